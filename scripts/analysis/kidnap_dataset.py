#!/usr/bin/python3
"""Make a "kidnapped" copy of an EuRoC ASL dataset (symlinks, no image copies) for
the relocalisation benchmark (scripts/bench/kidnap.sh):

  kidnap_dataset.py SRC DST remove START DUR        # frames in [START, START+DUR) s dropped
  kidnap_dataset.py SRC DST splice START DUR FROM   # those frames replaced by the frames
                                                    # from FROM s on (another part of the hall)

Times are seconds from the first camera frame. Ground truth, IMU and calibration
are linked unchanged; DST/kidnap.json records the window (ns) so that evaluation
can leave the spliced frames out (their ground truth is elsewhere)."""
import json, os, sys

def rows(csv):
    out = []
    for line in open(csv):
        if line.startswith('#') or not line.strip():
            continue
        t, name = line.strip().split(',')[:2]
        out.append((int(t), name))
    return out

def main():
    if len(sys.argv) < 6 or sys.argv[3] not in ('remove', 'splice') or (sys.argv[3] == 'splice' and len(sys.argv) < 7):
        sys.exit(__doc__)
    src, dst, mode = os.path.abspath(sys.argv[1]), sys.argv[2], sys.argv[3]
    start, dur = float(sys.argv[4]), float(sys.argv[5])
    src_m, dst_m = os.path.join(src, 'mav0'), os.path.join(dst, 'mav0')
    if os.path.exists(dst):
        sys.exit(f'{dst} exists; remove it first')
    os.makedirs(dst_m)
    for entry in os.listdir(src_m):
        if entry not in ('cam0', 'cam1'):
            os.symlink(os.path.join(src_m, entry), os.path.join(dst_m, entry))
    cam0 = rows(os.path.join(src_m, 'cam0', 'data.csv'))
    t0 = cam0[0][0]
    w0, w1 = t0 + int(start * 1e9), t0 + int((start + dur) * 1e9)
    for cam in ('cam0', 'cam1'):
        os.makedirs(os.path.join(dst_m, cam))
        for entry in ('data', 'sensor.yaml'):
            os.symlink(os.path.join(src_m, cam, entry), os.path.join(dst_m, cam, entry))
        frames = rows(os.path.join(src_m, cam, 'data.csv'))
        out = []
        if mode == 'remove':
            out = [(t, n) for t, n in frames if not (w0 <= t < w1)]
        else:
            f0 = t0 + int(float(sys.argv[6]) * 1e9)
            first_in = next(i for i, (t, _) in enumerate(frames) if t >= w0)
            first_from = next(i for i, (t, _) in enumerate(frames) if t >= f0)
            for i, (t, n) in enumerate(frames):
                if w0 <= t < w1:
                    n = frames[first_from + (i - first_in)][1]
                out.append((t, n))
        with open(os.path.join(dst_m, cam, 'data.csv'), 'w') as f:
            f.write('#timestamp [ns],filename\n')
            for t, n in out:
                f.write(f'{t},{n}\n')
    json.dump({'mode': mode, 'window_start_ns': w0, 'window_end_ns': w1}, open(os.path.join(dst, 'kidnap.json'), 'w'))

main()
