#!/usr/bin/env python3
"""Independent numpy implementation of a whole sequence's metrics (formats.md section 5),
from the raw inputs: ground-truth part meshes (metres) and part poses per frame; the
predicted model's part meshes (canonical units) and each part's camera-from-part similarity
per frame; the joints; rendered depth pairs for the scale alignment.

It computes the monocular scale (median log depth ratio), Chamfer distances (mean distance
in cm, and the squared form in m^2 for the whole object, moving parts and static part) from
its own area-weighted samples, the articulation errors (axis angle, axis line distance,
state error) and the gauge-aligned rigid errors of the base part.

Reads JSON on stdin, prints JSON on stdout. Used by agentstar-bench's tests where Python and
numpy exist. Chamfer values are statistical (different samples): compare with a tolerance.
"""
import json
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from crosscheck_rigid import gauge_errors, rot  # noqa: E402


def sample(vertices, triangles, n, rng):
    v = np.asarray(vertices, dtype=float)
    t = np.asarray(triangles, dtype=int)
    a, b, c = v[t[:, 0]], v[t[:, 1]], v[t[:, 2]]
    area = 0.5 * np.linalg.norm(np.cross(b - a, c - a), axis=1)
    pick = rng.choice(len(t), size=n, p=area / area.sum())
    r1, r2 = rng.random(n), rng.random(n)
    flip = r1 + r2 > 1
    r1[flip], r2[flip] = 1 - r1[flip], 1 - r2[flip]
    return a[pick] + (b[pick] - a[pick]) * r1[:, None] + (c[pick] - a[pick]) * r2[:, None]


def nn(x, y):
    """Distance from each row of x to its nearest row of y (brute force, in chunks)."""
    out = np.empty(len(x))
    for i in range(0, len(x), 512):
        d = ((x[i:i + 512, None, :] - y[None, :, :]) ** 2).sum(-1)
        out[i:i + 512] = np.sqrt(d.min(1))
    return out


def posed_area_samples(meshes, poses, keep, n, rng):
    """Samples of the union of the kept parts, posed: area-weighted over every triangle."""
    verts, tris, off = [], [], 0
    for i, (m, (s, q, t)) in enumerate(zip(meshes, poses)):
        if not keep[i]:
            continue
        v = np.asarray(m["vertices"], dtype=float)
        verts.append(s * v @ rot(q).T + np.asarray(t))
        tris.append(np.asarray(m["triangles"], dtype=int) + off)
        off += len(v)
    if not verts:
        return None
    return sample(np.vstack(verts), np.vstack(tris), n, rng)


def main():
    d = json.load(sys.stdin)
    rng = np.random.default_rng(12345)
    n = d["samples"]
    pairs = np.asarray(d["depth_pairs"], dtype=float)
    s_hat = float(np.exp(np.median(np.log(pairs[:, 0]) - np.log(pairs[:, 1]))))
    gt_moving = [any(j["child"] == i for j in d["gt_joints"]) for i in range(len(d["gt_meshes"]))]
    pr_moving = d["pred_moving"]
    cd, cd_sq = {"w": [], "m": [], "s": []}, {"w": [], "m": [], "s": []}
    for f in range(len(d["gt_poses"])):
        gposes = [(1.0, p[:4], p[4:]) for p in d["gt_poses"][f]]
        pposes = [(s_hat * p[0], p[1:5], s_hat * np.asarray(p[5:])) for p in d["pred_poses"][f]]
        for key, gk, pk in [
            ("w", [True] * len(gposes), [True] * len(pposes)),
            ("m", gt_moving, pr_moving),
            ("s", [not m for m in gt_moving], [not m for m in pr_moving]),
        ]:
            a = posed_area_samples(d["gt_meshes"], gposes, gk, n, rng)
            b = posed_area_samples(d["pred_meshes"], pposes, pk, n, rng)
            if a is None or b is None:
                continue
            da, db = nn(a, b), nn(b, a)
            cd[key].append(0.5 * (da.mean() + db.mean()))
            cd_sq[key].append((da ** 2).mean() + (db ** 2).mean())
    joints = []
    for gj, pj in zip(d["gt_joints"], d["pred_joints"]):
        # Ground-truth axis and origin: parent part frame to the first camera.
        q, t = d["gt_poses"][0][gj["parent"]][:4], np.asarray(d["gt_poses"][0][gj["parent"]][4:])
        g_axis = rot(q) @ np.asarray(gj["axis"])
        g_origin = rot(q) @ np.asarray(gj["origin"]) + t
        s, pq, pt = pj["object_pose"][0], pj["object_pose"][1:5], np.asarray(pj["object_pose"][5:])
        p_axis = rot(pq) @ np.asarray(pj["axis"])
        p_origin = s_hat * (s * rot(pq) @ np.asarray(pj["origin"]) + pt)
        u, v = p_axis / np.linalg.norm(p_axis), g_axis / np.linalg.norm(g_axis)
        angle = float(np.arccos(min(1.0, abs(float(u @ v)))))
        w = g_origin - p_origin
        cr = np.cross(u, v)
        if np.linalg.norm(cr) < 1e-9:
            dist = float(np.linalg.norm(w - u * (w @ u)))
        else:
            dist = float(abs(w @ cr) / np.linalg.norm(cr))
        pred_states = np.asarray(pj["states"], dtype=float)
        if not gj["revolute"]:
            pred_states = pred_states * s * s_hat
        state = float(np.mean(np.abs(np.abs(pred_states) - np.abs(np.asarray(gj["states"])))))
        joints.append({"axis_rad": angle, "position_m": dist if gj["revolute"] else None,
                       "state": state})
    base = d["gt_base"]
    gt_rows = [d["gt_poses"][f][base] for f in range(len(d["gt_poses"]))]
    pred_rows = [p[1:] for p in d["pred_object_poses"]]
    rot_err, trans_err = gauge_errors(gt_rows, pred_rows, d["pred_scale"], s_hat)
    mean = lambda v: float(np.mean(v)) if v else None  # noqa: E731
    json.dump({
        "scale": s_hat,
        "chamfer_cm": 100 * mean(cd["w"]),
        "cd_moving_cm": 100 * mean(cd["m"]) if cd["m"] else None,
        "cd_static_cm": 100 * mean(cd["s"]) if cd["s"] else None,
        "cd_w_m2": mean(cd_sq["w"]), "cd_m_m2": mean(cd_sq["m"]), "cd_s_m2": mean(cd_sq["s"]),
        "joints": joints,
        "rotation_mean_deg": float(np.mean(rot_err)),
        "rotation_median_deg": float(np.median(rot_err)),
        "translation_mean_cm": float(np.mean(trans_err)),
        "translation_median_cm": float(np.median(trans_err)),
    }, sys.stdout)


if __name__ == "__main__":
    main()
