#!/usr/bin/env python3
"""Independent numpy implementation of the gauge-aligned rigid pose errors (HOT3D protocol).

Reads JSON on stdin: {"gt": [[qw,qx,qy,qz,tx,ty,tz], ...], "pred": [...], "pred_scale": s,
"depth_scale": s_hat} and prints {"rotation_deg": [...], "translation_cm": [...]}.
Used by agentstar-eval's tests where Python and numpy exist.
"""
import json
import sys

import numpy as np


def rot(q):
    w, x, y, z = np.asarray(q, dtype=float) / np.linalg.norm(q)
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
        [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
        [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
    ])


def gauge_errors(gt_rows, pred_rows, pred_scale, depth_scale):
    """Per-frame rotation (degrees) and translation (cm) errors after one gauge."""
    gt = [(rot(p[:4]), np.array(p[4:])) for p in gt_rows]
    pr = [(rot(p[:4]), np.array(p[4:])) for p in pred_rows]
    s, k = pred_scale, depth_scale * pred_scale
    m = sum(rp.T @ rg for (rg, _), (rp, _) in zip(gt, pr))
    u, _, vt = np.linalg.svd(m)
    g = u @ np.diag([1, 1, np.sign(np.linalg.det(u @ vt))]) @ vt
    # Least squares for the offset c: stack k R_i c = t_gt_i - s_hat t_i.
    a = np.vstack([k * rp for (_, _), (rp, _) in zip(gt, pr)])
    b = np.concatenate([tg - depth_scale * tp for (_, tg), (_, tp) in zip(gt, pr)])
    c, *_ = np.linalg.lstsq(a, b, rcond=None)
    rot_err, trans_err = [], []
    for (rg, tg), (rp, tp) in zip(gt, pr):
        rel = rg.T @ (rp @ g)
        rot_err.append(float(np.degrees(np.arccos(np.clip((np.trace(rel) - 1) / 2, -1, 1)))))
        trans_err.append(float(np.linalg.norm(tg - (k * rp @ c + depth_scale * tp)) * 100))
    return rot_err, trans_err


def main():
    d = json.load(sys.stdin)
    rot_err, trans_err = gauge_errors(d["gt"], d["pred"], d["pred_scale"], d["depth_scale"])
    json.dump({"rotation_deg": rot_err, "translation_cm": trans_err}, sys.stdout)


if __name__ == "__main__":
    main()
