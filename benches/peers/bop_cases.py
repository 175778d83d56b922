#!/usr/bin/env python3
"""Builds the cases on which `synthgen eval --bop` is compared with bop_toolkit.

    python3 benches/peers/bop_cases.py BASE_SCENE MODELS_INFO OUT

BASE_SCENE is a scene folder of a BOP dataset rendered by synthgen (scene_gt.json,
scene_gt_info.json, scene_camera.json, rgb/, depth/) with the Linemod-Occluded objects
1, 5, 6, 8, 9, 10, 11, 12 (see bop_agreement.sh for the render command); MODELS_INFO is
their models_eval/models_info.json. For each case OUT/CASE/ gets the files that differ from the base: scene_gt.json, scene_gt_info.json,
models_info.json (models_eval), test_targets_bop19.json and results.csv. Standard library only,
seeded: the same input gives the same files.

Cases:
  perturbed  every GT pose perturbed by 1-30 deg and 2-60 mm, growing with the instance
  symmetric  a continuous symmetry (obj 1), a continuous + a discrete one with an offset (obj 5),
             the discrete symmetries of obj 10 and 11: estimates at symmetric poses
  truncated  GT instances moved across the image border (and one out of the image entirely)
  extras     duplicate and tied estimates, estimates for an object not in the image, for an
             unknown image and an unknown object, two instances of one object (inst_count 2)
             and three of another with inst_count 1 (the most visible counts)
"""

import copy
import json
import math
import os
import random
import sys

OBJ_IDS = [1, 5, 6, 8, 9, 10, 11, 12]


def mat_mul(a, b):
    return [[sum(a[i][k] * b[k][j] for k in range(3)) for j in range(3)] for i in range(3)]


def mat_vec(a, v):
    return [sum(a[i][k] * v[k] for k in range(3)) for i in range(3)]


def rot(axis, angle):
    n = math.sqrt(sum(x * x for x in axis))
    x, y, z = (v / n for v in axis)
    c, s = math.cos(angle), math.sin(angle)
    return [
        [c + x * x * (1 - c), x * y * (1 - c) - z * s, x * z * (1 - c) + y * s],
        [y * x * (1 - c) + z * s, c + y * y * (1 - c), y * z * (1 - c) - x * s],
        [z * x * (1 - c) - y * s, z * y * (1 - c) + x * s, c + z * z * (1 - c)],
    ]


def rand_axis(rng):
    while True:
        v = [rng.gauss(0, 1) for _ in range(3)]
        if sum(x * x for x in v) > 1e-6:
            return v


def perturb(rng, R, t, deg, mm):
    """R' = dR R about a random axis by `deg`; t' = t + a random direction * `mm`."""
    R2 = mat_mul(rot(rand_axis(rng), math.radians(deg)), R)
    d = rand_axis(rng)
    n = math.sqrt(sum(x * x for x in d))
    return R2, [t[i] + mm * d[i] / n for i in range(3)]


def unflat(r):
    return [r[0:3], r[3:6], r[6:9]]


def flat(R):
    return [v for row in R for v in row]


def row(scene_id, im_id, obj_id, score, R, t):
    r = " ".join(repr(float(v)) for v in flat(R))
    tt = " ".join(repr(float(v)) for v in t)
    return f"{scene_id},{im_id},{obj_id},{score},{r},{tt},0.5"


def targets_of(gt, info, scene_id, visib_min=0.1, counts_override=None):
    out = []
    for im in sorted(gt, key=int):
        counts = {}
        for g, gi in zip(gt[im], info[im]):
            if gi["visib_fract"] >= visib_min:
                counts[g["obj_id"]] = counts.get(g["obj_id"], 0) + 1
        for (i, o), n in (counts_override or {}).items():
            if int(im) == i:
                counts[o] = n
        for obj_id, n in sorted(counts.items()):
            out.append({"im_id": int(im), "inst_count": n, "obj_id": obj_id, "scene_id": scene_id})
    return out


def perturbed_rows(rng, gt, scene_id, max_deg=30.0, max_mm=60.0):
    rows = []
    for im in sorted(gt, key=int):
        for k, g in enumerate(gt[im]):
            s = rng.random()
            R, t = perturb(rng, unflat(g["cam_R_m2c"]), g["cam_t_m2c"], 1 + max_deg * s, 2 + max_mm * s)
            rows.append(row(scene_id, int(im), g["obj_id"], round(1.0 - 0.01 * k, 3), R, t))
    return rows


def case_perturbed(base, rng, scene_id):
    gt, info, models = base
    return gt, info, models, targets_of(gt, info, scene_id), perturbed_rows(rng, gt, scene_id)


def case_symmetric(base, rng, scene_id):
    gt, info, models = base
    models = copy.deepcopy(models)
    models["1"]["symmetries_continuous"] = [{"axis": [0, 0, 1], "offset": [0, 0, 0]}]
    models["5"]["symmetries_continuous"] = [{"axis": [0, 1, 0], "offset": [0, 0, 10.0]}]
    models["5"]["symmetries_discrete"] = [
        [1, 0, 0, 0, 0, -1, 0, 0, 0, 0, -1, 20.0, 0, 0, 0, 1]
    ]
    rows = []
    for im in sorted(gt, key=int):
        for k, g in enumerate(gt[im]):
            R, t = unflat(g["cam_R_m2c"]), g["cam_t_m2c"]
            o = str(g["obj_id"])
            syms = []
            for c in models[o].get("symmetries_continuous", []):
                a = rng.uniform(0, 2 * math.pi)
                Rs = rot(c["axis"], a)
                off = c["offset"]
                ts = [off[i] - mat_vec(Rs, off)[i] for i in range(3)]
                syms.append((Rs, ts))
            disc = models[o].get("symmetries_discrete", [])
            if disc and rng.random() < 0.7:
                m = disc[rng.randrange(len(disc))]
                syms.append(([m[0:3], m[4:7], m[8:11]], [m[3], m[7], m[11]]))
            # The GT moved by the symmetries: GT * S (model frame), then a small perturbation.
            for Rs, ts in syms:
                t = [t[i] + mat_vec(R, ts)[i] for i in range(3)]
                R = mat_mul(R, Rs)
            s = rng.random()
            R, t = perturb(rng, R, t, 0.5 + 15 * s, 1 + 30 * s)
            rows.append(row(scene_id, int(im), g["obj_id"], round(0.9 - 0.01 * k, 3), R, t))
    return gt, info, models, targets_of(gt, info, scene_id), rows


def case_truncated(base, rng, scene_id, cam):
    gt, info, models = base
    gt = copy.deepcopy(gt)
    fx, cx, fy, cy = cam[0], cam[2], cam[4], cam[5]
    moved = []
    for n, im in enumerate(sorted(gt, key=int)):
        for k in (0, 3):
            if k >= len(gt[im]):
                continue
            g = gt[im][k]
            z = g["cam_t_m2c"][2]
            # Centre on (or past) an image border: left, right, top, bottom in turn.
            u, v = [(2.0, cy), (637.0, cy), (cx, 4.0), (cx, 470.0)][(n + k) % 4]
            if n == 3 and k == 3:
                u = -400.0  # entirely out of the image
            g["cam_t_m2c"] = [(u - cx) * z / fx, (v - cy) * z / fy, z]
            moved.append((int(im), k))
    rows = perturbed_rows(rng, gt, scene_id, max_deg=20.0, max_mm=40.0)
    return gt, info, models, targets_of(gt, info, scene_id, visib_min=0.0), rows


def case_extras(base, rng, scene_id):
    gt, info, models = base
    gt, info = copy.deepcopy(gt), copy.deepcopy(info)
    ims = sorted(gt, key=int)
    # Object 12 leaves images 0 and 1 (estimates for it there are for an absent object).
    for im in ims[:2]:
        keep = [i for i, g in enumerate(gt[im]) if g["obj_id"] != 12]
        gt[im] = [gt[im][i] for i in keep]
        info[im] = [info[im][i] for i in keep]
    # A second instance of object 6 in image 2, 60 mm to the side; two of object 8 more in
    # image 3 with the targets asking for one.
    def add_copy(im, obj, dx, visib):
        src = next(i for i, g in enumerate(gt[im]) if g["obj_id"] == obj)
        g = copy.deepcopy(gt[im][src])
        g["cam_t_m2c"][0] += dx
        gi = copy.deepcopy(info[im][src])
        gi["visib_fract"] = visib
        gt[im].append(g)
        info[im].append(gi)
    add_copy(ims[2], 6, 60.0, 0.5)
    add_copy(ims[3], 8, -50.0, 0.95)
    add_copy(ims[3], 8, 45.0, 0.3)
    targets = targets_of(gt, info, scene_id, visib_min=0.0, counts_override={(int(ims[3]), 8): 1})
    rows = perturbed_rows(rng, gt, scene_id, max_deg=20.0, max_mm=40.0)
    for n, im in enumerate(ims):
        g0 = gt[im][0]
        R, t = unflat(g0["cam_R_m2c"]), g0["cam_t_m2c"]
        # Duplicates: the same pose twice with the same score, and a far-off one scoring higher.
        Rp, tp = perturb(rng, R, t, 3.0, 5.0)
        rows.append(row(scene_id, int(im), g0["obj_id"], 0.99, Rp, tp))
        rows.append(row(scene_id, int(im), g0["obj_id"], 0.99, Rp, tp))
        if n % 2 == 0:
            Rf, tf = perturb(rng, R, t, 90.0, 150.0)
            rows.append(row(scene_id, int(im), g0["obj_id"], 1.5, Rf, tf))
        # Ties across objects and an estimate for an object the image lacks.
        if n < 2:
            rows.append(row(scene_id, int(im), 12, 2.0, R, [t[0], t[1], t[2] + 30]))
    # Unknown image and unknown object: ignored by bop_toolkit (not targets).
    rows.append(row(scene_id, 999, 1, 1.0, [[1, 0, 0], [0, 1, 0], [0, 0, 1]], [0, 0, 800]))
    rows.append(row(scene_id, int(ims[0]), 2, 1.0, [[1, 0, 0], [0, 1, 0], [0, 0, 1]], [0, 0, 800]))
    return gt, info, models, targets, rows


def dump(path, value):
    with open(path, "w") as f:
        json.dump(value, f, indent=1, sort_keys=True)
        f.write("\n")


def main():
    if len(sys.argv) != 4:
        print(__doc__.split("\n\n")[1], file=sys.stderr)
        sys.exit(2)
    scene_dir, models_info, out = sys.argv[1:4]
    scene_id = 2
    load = lambda name: json.load(open(os.path.join(scene_dir, name)))
    gt, info, cams = load("scene_gt.json"), load("scene_gt_info.json"), load("scene_camera.json")
    models = json.load(open(models_info))
    cam = next(iter(cams.values()))["cam_K"]
    base = (gt, info, models)
    cases = {
        "perturbed": lambda rng: case_perturbed(base, rng, scene_id),
        "symmetric": lambda rng: case_symmetric(base, rng, scene_id),
        "truncated": lambda rng: case_truncated(base, rng, scene_id, cam),
        "extras": lambda rng: case_extras(base, rng, scene_id),
    }
    for seed, (name, make) in enumerate(cases.items()):
        g, i, m, targets, rows = make(random.Random(seed))
        d = os.path.join(out, name)
        os.makedirs(d, exist_ok=True)
        dump(os.path.join(d, "scene_gt.json"), g)
        dump(os.path.join(d, "scene_gt_info.json"), i)
        dump(os.path.join(d, "models_info.json"), m)
        dump(os.path.join(d, "test_targets_bop19.json"), targets)
        with open(os.path.join(d, "results.csv"), "w") as f:
            f.write("scene_id,im_id,obj_id,score,R,t,time\n" + "\n".join(rows) + "\n")
        print(f"{name}: {len(targets)} targets, {len(rows)} estimates")


if __name__ == "__main__":
    main()
