#!/usr/bin/python3
"""How far a recording's IMU agrees with its ground-truth motion (issue 19).

From the ground-truth state (position, velocity, orientation) every second,
integrates 0.5 s of the recording's imu0 (midpoint rule, gravity 9.81 m/s^2
along -z, the biases of the ground truth or of --biases) and prints how far the
integrated position and velocity end from the ground truth's: the level at which
the IMU and the images (rendered from that ground truth) disagree.

  /usr/bin/python3 scripts/analysis/imu_consistency.py DATASET [--biases ASL_GT_CSV]

DATASET holds mav0/imu0/data.csv and mav0/state_groundtruth_estimate0/data.csv
(an EuRoC ASL folder, e.g. one `orbatlas sim` wrote). --biases: an ASL
ground-truth csv whose bias columns to use instead (a real IMU's, as the real
MH_05 ground truth in ../shared/data/euroc/groundtruth/MH_05_difficult.csv).
Needs numpy (Debian: python3-numpy).
"""
import argparse

import numpy as np

WINDOW_SAMPLES = 100  # 0.5 s at 200 Hz
STEP_SAMPLES = 200    # one window a second
GRAVITY = np.array([0.0, 0.0, -9.81])


def rotation(q_wxyz):
    w, x, y, z = q_wxyz
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                     [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                     [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])


def exp_so3(w):
    angle = np.linalg.norm(w)
    if angle < 1e-12:
        return np.eye(3)
    k = w / angle
    K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + np.sin(angle) * K + (1 - np.cos(angle)) * K @ K


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("dataset")
    parser.add_argument("--biases")
    args = parser.parse_args()
    imu = np.loadtxt(f"{args.dataset}/mav0/imu0/data.csv", delimiter=",", comments="#")
    gt = np.loadtxt(f"{args.dataset}/mav0/state_groundtruth_estimate0/data.csv", delimiter=",", comments="#")
    biases = np.loadtxt(args.biases, delimiter=",", comments="#") if args.biases else gt
    position_errors, velocity_errors = [], []
    for s in range(STEP_SAMPLES, len(imu) - 2 * WINDOW_SAMPLES, STEP_SAMPLES):
        i = np.searchsorted(gt[:, 0], imu[s, 0])
        end = np.searchsorted(gt[:, 0], imu[s + WINDOW_SAMPLES, 0])
        if end >= len(gt) or abs(gt[i, 0] - imu[s, 0]) > 1e6:
            continue
        j = min(np.searchsorted(biases[:, 0], imu[s, 0]), len(biases) - 1)
        gyro_bias, accel_bias = biases[j, 11:14], biases[j, 14:17]
        R, p, v = rotation(gt[i, 4:8]), gt[i, 1:4].copy(), gt[i, 8:11].copy()
        for k in range(s, s + WINDOW_SAMPLES):
            dt = (imu[k + 1, 0] - imu[k, 0]) * 1e-9
            w = 0.5 * (imu[k, 1:4] + imu[k + 1, 1:4]) - gyro_bias
            a = R @ (0.5 * (imu[k, 4:7] + imu[k + 1, 4:7]) - accel_bias) + GRAVITY
            p, v, R = p + v * dt + 0.5 * a * dt * dt, v + a * dt, R @ exp_so3(w * dt)
        position_errors.append(np.linalg.norm(p - gt[end, 1:4]))
        velocity_errors.append(np.linalg.norm(v - gt[end, 8:11]))
    pe, ve = np.array(position_errors), np.array(velocity_errors)
    print(f"{args.dataset}: {len(pe)} windows of 0.5 s; position off by median {np.median(pe):.4f} m, "
          f"p90 {np.percentile(pe, 90):.4f} m; velocity off by median {np.median(ve):.4f} m/s, "
          f"p90 {np.percentile(ve, 90):.4f} m/s")


if __name__ == "__main__":
    main()
