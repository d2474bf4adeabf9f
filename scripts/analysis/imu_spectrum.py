#!/usr/bin/python3
"""What a real EuRoC IMU measures besides the motion: the numbers behind the
simulator's realistic IMU (core/sim/imu_vibration.cc, imu_synthesizer.cc).

For a real IMU recording (`t_ns wx wy wz ax ay az`, plain or gzip):
- the vibration's amplitude spectral density in flight, per axis, averaged over
  5-Hz bands from 5 to 100 Hz (Welch, 1024 samples a segment, linear detrend):
  the table euroc_flight_vibration() holds, and its RMS;
- the white noise density while parked (the bands above 30 Hz), against the
  settings' 1.6968e-4 rad/s/sqrt(Hz) and 2.0e-3 m/s^2/sqrt(Hz);
- the RMS above 15 Hz in windows of 1 s every 5 s, which shows when the motors
  start.

  /usr/bin/python3 scripts/analysis/imu_spectrum.py [IMU] [--flight A B] [--parked A B]

IMU defaults to data/euroc/imu/MH_05_imu0.txt.gz (flight 40-100 s, parked
1-9 s from its first sample); for data/euroc/imu/MH_01_imu0_lossy.txt.gz use
--flight 60 170 --parked 20 30. Needs numpy and scipy (Debian: python3-numpy,
python3-scipy).
"""
import argparse
import gzip
import os

import numpy as np
from scipy import signal

RATE_HZ = 200.0


def load(path):
    opener = gzip.open if path.endswith(".gz") else open
    with opener(path, "rt") as f:
        data = np.loadtxt(f)
    t = (data[:, 0] - data[0, 0]) * 1e-9
    return t, data[:, 1:7]


def main():
    here = os.path.dirname(os.path.abspath(__file__))
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("imu", nargs="?", default=os.path.join(here, "..", "..", "data", "euroc", "imu",
                                                               "MH_05_imu0.txt.gz"))
    parser.add_argument("--flight", nargs=2, type=float, default=[40.0, 100.0])
    parser.add_argument("--parked", nargs=2, type=float, default=[1.0, 9.0])
    args = parser.parse_args()
    t, x = load(args.imu)

    m = (t >= args.flight[0]) & (t < args.flight[1])
    freq, psd = signal.welch(x[m], fs=RATE_HZ, nperseg=1024, axis=0, detrend="linear")
    print(f"flight {args.flight[0]:g}-{args.flight[1]:g} s: amplitude spectral density per 5-Hz band")
    print("band Hz      gyro rad/s/sqrt(Hz)           accel m/s^2/sqrt(Hz)")
    power = np.zeros(6)
    for lo in range(5, 100, 5):
        band = (freq >= lo) & (freq < lo + 5)
        mean = psd[band].mean(axis=0)
        power += mean * 5.0
        g = ", ".join(f"{v:.5f}" for v in np.sqrt(mean[:3]))
        a = ", ".join(f"{v:.4f}" for v in np.sqrt(mean[3:]))
        print(f"{lo:3d}-{lo + 5:3d}   {{{g}}}, {{{a}}}")
    rms = np.sqrt(power)
    print("RMS 5-100 Hz: gyro " + " ".join(f"{v:.3f}" for v in rms[:3]) + " rad/s, accel " +
          " ".join(f"{v:.2f}" for v in rms[3:]) + " m/s^2")

    m = (t >= args.parked[0]) & (t < args.parked[1])
    freq, psd = signal.welch(x[m], fs=RATE_HZ, nperseg=256, axis=0, detrend="linear")
    density = np.sqrt(psd[freq >= 30.0].mean(axis=0))
    print(f"parked {args.parked[0]:g}-{args.parked[1]:g} s, white noise density above 30 Hz: gyro " +
          " ".join(f"{v:.2e}" for v in density[:3]) + " rad/s/sqrt(Hz), accel " +
          " ".join(f"{v:.2e}" for v in density[3:]) + " m/s^2/sqrt(Hz)")

    b, a = signal.butter(4, 15.0 / (RATE_HZ / 2), "high")
    high = signal.filtfilt(b, a, x, axis=0)
    print("RMS above 15 Hz in 1-s windows (motors idle, then flying):")
    for start in range(0, int(t[-1]), 5):
        w = (t >= start) & (t < start + 1)
        r = np.sqrt((high[w] ** 2).mean(axis=0))
        print(f"  {start:4d} s  gyro {r[0]:.4f} {r[1]:.4f} {r[2]:.4f}  accel {r[3]:.3f} {r[4]:.3f} {r[5]:.3f}")


if __name__ == "__main__":
    main()
