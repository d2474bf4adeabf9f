#!/usr/bin/env python3
# Usage: /usr/bin/python3 scripts/analysis/evo_ape_check.py GT_DATA_CSV ESTIMATE_CSV (both EuRoC csv)
# evo_ape's default APE (translation part, SE3 Umeyama alignment with -a, timestamps
# associated to the nearest ground-truth pose within 10 ms), written out with numpy
# to cross-check `orbatlas eval` where evo itself cannot be installed.
import sys
import numpy as np
gt = np.loadtxt(sys.argv[1], delimiter=",", comments="#")[:, :8]
est = np.loadtxt(sys.argv[2], delimiter=",", comments="#")[:, :8]
gt_t, est_t = gt[:, 0] / 1e9, est[:, 0] / 1e9
idx = np.searchsorted(gt_t, est_t)
pairs = []
for i, (t, k) in enumerate(zip(est_t, idx)):
    best = min((j for j in (k - 1, k) if 0 <= j < len(gt_t)), key=lambda j: abs(gt_t[j] - t))
    if abs(gt_t[best] - t) <= 0.01:
        pairs.append((i, best))
e = np.array([est[i, 1:4] for i, _ in pairs]); g = np.array([gt[j, 1:4] for _, j in pairs])
mu_e, mu_g = e.mean(0), g.mean(0)
C = (g - mu_g).T @ (e - mu_e) / len(e)
U, D, Vt = np.linalg.svd(C)
S = np.eye(3)
if np.linalg.det(U) * np.linalg.det(Vt) < 0: S[2, 2] = -1
R = U @ S @ Vt
t = mu_g - R @ mu_e
err = np.linalg.norm(g - (e @ R.T + t), axis=1)
print(f"pairs {len(pairs)} of {len(est)}; APE translation rmse {np.sqrt((err**2).mean()):.6f} m, mean {err.mean():.6f}, median {np.median(err):.6f}, max {err.max():.6f}")
