#!/usr/bin/python3
"""Where along a trajectory its ATE comes from.

    scripts/ate_over_time.py GROUND_TRUTH.csv EST.tum [EST2.tum ...] [--step 10]

GROUND_TRUTH.csv is an ASL ground truth (mav0/state_groundtruth_estimate0/data.csv
of a dataset `orbatlas sim` rendered); EST a TUM trajectory (`orbatlas stream
--out-trajectory`, `orbatlas trajectory`). Each estimate is aligned to the truth
once, as a whole (SE3, positions), as `orbatlas eval` does, over the poses with a
ground-truth sample within 3 ms (no interpolation: it may use fewer poses than
`orbatlas eval`, whose ATE it matches to about 0.1 mm); then the RMSE of the position error is printed for the whole and for each
--step seconds from its first pose. A trajectory whose error sits in one stretch
(a bad start, the newest keyframes) shows it there; one that is worse all along
shows it everywhere.
"""
import argparse

import numpy as np


def ground_truth(path):
    a = np.loadtxt(path, delimiter=",", comments="#")
    return a[:, 0] * 1e-9, a[:, 1:4]


def tum(path):
    rows = [line.split() for line in open(path) if line.strip() and not line.startswith("#")]
    a = np.array([[float(x) for x in r[:4]] for r in rows])
    return a[:, 0], a[:, 1:4]


def align(est, truth):
    """R, t minimising |R est + t - truth| (Umeyama without scale)."""
    me, mt = est.mean(0), truth.mean(0)
    u, _, vt = np.linalg.svd((est - me).T @ (truth - mt))
    d = np.eye(3)
    d[2, 2] = np.sign(np.linalg.det(vt.T @ u.T))
    r = vt.T @ d @ u.T
    return r, mt - r @ me


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("ground_truth")
    parser.add_argument("estimates", nargs="+")
    parser.add_argument("--step", type=float, default=10.0, help="seconds per stretch")
    args = parser.parse_args()
    gt_t, gt_p = ground_truth(args.ground_truth)
    for path in args.estimates:
        t, p = tum(path)
        i = np.clip(np.searchsorted(gt_t, t), 0, len(gt_t) - 1)
        near = np.abs(gt_t[i] - t) < 0.003
        t, p, g = t[near], p[near], gt_p[i[near]]
        if len(t) < 3:
            print(f"{path}: fewer than 3 poses match the ground truth")
            continue
        r, shift = align(p, g)
        err = np.linalg.norm(p @ r.T + shift - g, axis=1)
        since = t - t[0]
        stretches = []
        for start in np.arange(0.0, since[-1] + 1e-9, args.step):
            inside = (since >= start) & (since < start + args.step)
            if inside.any():
                stretches.append(f"{1000 * np.sqrt(np.mean(err[inside] ** 2)):.1f}")
        print(f"{path}: ATE {1000 * np.sqrt(np.mean(err ** 2)):.2f} mm over {len(t)} poses; "
              f"per {args.step:g} s [mm]: {' '.join(stretches)}")


if __name__ == "__main__":
    main()
