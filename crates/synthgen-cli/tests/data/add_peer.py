"""ADD(-S) per object as bop_toolkit computes it, the peer of `synthgen eval`'s table.

bop_toolkit (pose_error.py): add = mean over model points of |(R_e p + t_e) - (R_g p + t_g)|;
adi = mean over the GT-posed points of the distance to the nearest estimate-posed point
(scipy's cKDTree); a symmetric object (symmetries in models_info) uses adi. Every vertex of
the model file the metrics read (BOP's models_eval/), the rotations as stored in the files.
Per (image, object) with k GT instances, the k best-scoring estimates, each taking the free GT
instance it fits best; a GT instance without one is wrong. Correct: error < 0.1 diameter.

usage: python3 add_peer.py DATASET SCENE_ID RESULTS_CSV  ->  JSON on stdout
"""

import csv
import json
import os
import sys

import numpy as np
from scipy import spatial


def ply_vertices(path):
    with open(path, "rb") as f:
        fmt, count, props, in_vertex = None, 0, [], False
        while True:
            line = f.readline().decode("ascii").strip()
            if line.startswith("format"):
                fmt = line.split()[1]
            elif line.startswith("element"):
                in_vertex = line.split()[1] == "vertex"
                if in_vertex:
                    count = int(line.split()[2])
            elif line.startswith("property") and in_vertex:
                _, t, name = line.split()
                props.append((name, t))
            elif line == "end_header":
                break
        types = {"float": "f4", "double": "f8", "uchar": "u1", "int": "i4", "uint": "u4",
                 "short": "i2", "ushort": "u2", "char": "i1", "float32": "f4", "uint8": "u1"}
        if fmt == "ascii":
            rows = [f.readline().split() for _ in range(count)]
            idx = [i for i, (n, _) in enumerate(props) if n in ("x", "y", "z")]
            return np.array([[float(r[i]) for i in idx] for r in rows])
        dtype = np.dtype([(n, "<" + types[t]) for n, t in props])
        v = np.frombuffer(f.read(dtype.itemsize * count), dtype=dtype, count=count)
        return np.stack([v["x"], v["y"], v["z"]], axis=1).astype(np.float64)


def main():
    root, scene, csv_path = sys.argv[1], int(sys.argv[2]), sys.argv[3]
    models = os.path.join(root, "models_eval")
    if not os.path.isdir(models):
        models = os.path.join(root, "models")
    info = json.load(open(os.path.join(models, "models_info.json")))
    gt = json.load(open(os.path.join(root, "test", f"{scene:06d}", "scene_gt.json")))
    ests = {}
    with open(csv_path) as f:
        for row in csv.DictReader(f):
            key = (int(row["im_id"]), int(row["obj_id"]))
            R = np.array([float(x) for x in row["R"].split()]).reshape(3, 3)
            t = np.array([float(x) for x in row["t"].split()]).reshape(3, 1)
            ests.setdefault(key, []).append((float(row["score"]), R, t))
    pts = {}
    per_obj = {}
    for im, insts in gt.items():
        im = int(im)
        by_obj = {}
        for g in insts:
            R = np.array(g["cam_R_m2c"]).reshape(3, 3)
            t = np.array(g["cam_t_m2c"]).reshape(3, 1)
            by_obj.setdefault(g["obj_id"], []).append((R, t))
        for obj, gts in by_obj.items():
            if obj not in pts:
                pts[obj] = ply_vertices(os.path.join(models, f"obj_{obj:06d}.ply"))
            p = pts[obj]
            sym = bool(info[str(obj)].get("symmetries_discrete")) or bool(
                info[str(obj)].get("symmetries_continuous"))
            d = info[str(obj)]["diameter"]
            acc = per_obj.setdefault(obj, {"n_gt": 0, "ok": 0, "errors": []})
            acc["n_gt"] += len(gts)
            cand = sorted(ests.get((im, obj), []), key=lambda e: -e[0])[: len(gts)]
            free = list(range(len(gts)))
            for _, Re, te in cand:
                pe = (Re @ p.T + te).T
                errs = []
                for gi in free:
                    Rg, tg = gts[gi]
                    pg = (Rg @ p.T + tg).T
                    if sym:
                        e = spatial.cKDTree(pe).query(pg, k=1)[0].mean()
                    else:
                        e = np.linalg.norm(pe - pg, axis=1).mean()
                    errs.append((e, gi))
                if not errs:
                    break
                e, gi = min(errs)
                free.remove(gi)
                acc["errors"].append(e)
                acc["ok"] += int(e < 0.1 * d)
    out = {
        str(o): {
            "n_gt": a["n_gt"],
            "add_s_acc": a["ok"] / a["n_gt"],
            "mean_add_mm": (sum(a["errors"]) / len(a["errors"])) if a["errors"] else None,
        }
        for o, a in per_obj.items()
    }
    json.dump(out, sys.stdout)


if __name__ == "__main__":
    main()
