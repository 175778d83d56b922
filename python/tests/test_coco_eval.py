"""`synthgen detector eval` against pycocotools and bop_toolkit's rules, on the same files.

bop_toolkit's `eval_bop22_coco.py` scores BOP detections with pycocotools' COCOeval over the
COCO GT its `calc_gt_coco.py` builds from the masks. Here the GT synthgen scored against is
checked against the dataset's mask PNGs the way calc_gt_coco reads them, and synthgen's twelve
numbers and per-object AP against COCOeval's on seeded, imperfect detections (jittered boxes,
shifted masks, misses, false positives, tied scores, an object with no GT, masks left out).
"""

from __future__ import annotations

import json
import os
import subprocess
from pathlib import Path
from typing import Any, Dict, List, Tuple

import numpy as np
import pytest

from .conftest import SHARED, need, synthgen_exe

try:
    from PIL import Image
    from pycocotools import mask as mask_utils
    from pycocotools.coco import COCO
    from pycocotools.cocoeval import COCOeval
except ImportError:  # pragma: no cover - depends on the machine
    if os.environ.get("SYNTHGEN_REQUIRE_PYCOCOTOOLS") == "1":
        raise
    pytest.skip(
        "pycocotools is not installed: the COCO evaluation was not compared "
        "(pip install pycocotools; CI runs it with SYNTHGEN_REQUIRE_PYCOCOTOOLS=1)",
        allow_module_level=True,
    )


def synthgen_eval(
    data: Path, detections: Path, out: Path, gt_out: Path, *extra: str
) -> Dict[str, Any]:
    subprocess.run(
        [str(synthgen_exe()), "-q", "detector", "eval", "--data", str(data)]
        + ["--detections", str(detections), "--out", str(out), "--gt-out", str(gt_out)]
        + list(extra),
        check=True,
        capture_output=True,
    )
    scores: Dict[str, Any] = json.loads(out.read_text())
    return scores


def decode(segm: Dict[str, Any]) -> np.ndarray:
    rle = segm
    if isinstance(segm["counts"], list):
        h, w = segm["size"]
        rle = mask_utils.frPyObjects(segm, h, w)
    return np.asarray(mask_utils.decode(rle), dtype=bool)


def imperfect_detections(gt: Dict[str, Any], seed: int) -> List[Dict[str, Any]]:
    """Detections a real detector could give: most GT found with jittered boxes and shifted
    masks, some missed, false positives, scores with ties, entries without a mask, an object
    the GT does not have, and an image the GT does not have."""
    rng = np.random.default_rng(seed)
    images = {im["id"]: im for im in gt["images"]}
    out: List[Dict[str, Any]] = []

    def entry(im: Dict[str, Any], cat: int, box: List[float], mask: np.ndarray) -> None:
        score = float(np.round(rng.uniform(0.05, 1.0), 1))  # ties on purpose
        e: Dict[str, Any] = {
            "scene_id": im["scene_id"],
            "image_id": im["im_id"],
            "category_id": cat,
            "score": score,
            "bbox": [float(v) for v in box],
            "time": 0.1,
        }
        if rng.uniform() < 0.9:
            rle = mask_utils.encode(np.asfortranarray(mask.astype(np.uint8)))
            e["segmentation"] = {"size": rle["size"], "counts": rle["counts"].decode()}
        out.append(e)

    for ann in gt["annotations"]:
        if rng.uniform() < 0.15:
            continue  # missed
        im = images[ann["image_id"]]
        x, y, w, h = ann["bbox"]
        j = rng.normal(0.0, 0.08, 4)
        box = [x + j[0] * w, y + j[1] * h, max(1.0, w * (1 + j[2])), max(1.0, h * (1 + j[3]))]
        mask = np.roll(decode(ann["segmentation"]), tuple(rng.integers(-4, 5, 2)), axis=(0, 1))
        entry(im, ann["category_id"], box, mask)
        if rng.uniform() < 0.2:  # a duplicate, worse
            entry(im, ann["category_id"], [b + 6 for b in box], np.roll(mask, 8, axis=1))
    cats = sorted({a["category_id"] for a in gt["annotations"]})
    for im in gt["images"]:
        for _ in range(int(rng.integers(0, 3))):
            w, h = im["width"], im["height"]
            x0, y0 = rng.uniform(0, w - 40), rng.uniform(0, h - 40)
            bw, bh = rng.uniform(10, 120), rng.uniform(10, 120)
            mask = np.zeros((h, w), dtype=bool)
            mask[int(y0) : int(min(h, y0 + bh)), int(x0) : int(min(w, x0 + bw))] = True
            entry(im, int(rng.choice(cats + [999])), [x0, y0, bw, bh], mask)
    first = gt["images"][0]
    out.append(dict(out[0], image_id=first["im_id"] + 100000))  # not a scored image
    return out


def coco_stats(
    gt: Dict[str, Any], dets: List[Dict[str, Any]], ann_type: str
) -> Tuple[List[float], Dict[int, float]]:
    """What eval_bop22_coco.py computes: results of the GT's images, COCOeval, summarize."""
    coco = COCO()
    coco.dataset = json.loads(json.dumps(gt))
    coco.createIndex()
    ids = {(im["scene_id"], im["im_id"]): im["id"] for im in gt["images"]}
    res = []
    for d in dets:
        key = (d["scene_id"], d["image_id"])
        if key not in ids or (ann_type == "segm" and "segmentation" not in d):
            continue
        r = dict(d, image_id=ids[key])
        del r["scene_id"]
        res.append(r)
    ev = COCOeval(coco, coco.loadRes(res), ann_type)
    ev.params.imgIds = sorted(coco.getImgIds())
    ev.evaluate()
    ev.accumulate()
    ev.summarize()
    per_object = {}
    for k, cat in enumerate(ev.params.catIds):
        p = ev.eval["precision"][:, :, k, 0, 2]
        per_object[int(cat)] = float(np.mean(p[p > -1])) if (p > -1).any() else -1.0
    return [float(s) for s in ev.stats], per_object


NAMES = ["AP", "AP50", "AP75", "AP_small", "AP_medium", "AP_large"]
NAMES += ["AR1", "AR10", "AR100", "AR_small", "AR_medium", "AR_large"]


def compare(tmp: Path, data: Path, seed: int, *extra: str) -> Dict[str, Any]:
    empty = tmp / "empty.json"
    empty.write_text("[]")
    gt_path = tmp / "gt.json"
    synthgen_eval(data, empty, tmp / "s0.json", gt_path, *extra)
    gt = json.loads(gt_path.read_text())
    assert gt["annotations"], "no GT instances to score"
    dets = imperfect_detections(gt, seed)
    det_path = tmp / "dets.json"
    det_path.write_text(json.dumps(dets))
    ours = synthgen_eval(data, det_path, tmp / "s.json", tmp / "gt2.json", *extra)
    assert ours["other_images"] == 1 and ours["entries"] == len(dets)
    for ann_type in ("bbox", "segm"):
        stats, per_object = coco_stats(gt, dets, ann_type)
        mine = ours[ann_type]
        got = [mine["stats"][n] for n in NAMES]
        assert np.allclose(got, stats, atol=1e-9, rtol=0), (ann_type, got, stats)
        for obj, ap in per_object.items():
            if str(obj) in mine["objects"]:
                assert abs(mine["objects"][str(obj)]["AP"] - ap) < 1e-9, (ann_type, obj)
            else:
                assert ap == -1.0, (ann_type, obj, ap)
        # Not a degenerate case: something found, something missed.
        assert 0.2 < stats[1] < 1.0 and 0.0 < stats[0] < stats[1], stats
    return gt


def test_rendered_dataset_gt_is_calc_gt_cocos_and_scores_are_cocoevals(
    tmp_path: Path, rendered: Path
) -> None:
    gt = compare(tmp_path, rendered, seed=1)
    # The GT is calc_gt_coco.py's: the visible mask's RLE and pixel count, the full
    # mask's bounds (amodal), every instance with a visible pixel.
    scene_gt = json.loads((rendered / "train_pbr" / "000000" / "scene_gt.json").read_text())
    images = {im["id"]: im for im in gt["images"]}
    checked = 0
    for im_id, insts in scene_gt.items():
        for gt_id, inst in enumerate(insts):
            stem = f"{int(im_id):06d}_{gt_id:06d}.png"
            folder = rendered / "train_pbr" / "000000"
            visib = np.asarray(Image.open(folder / "mask_visib" / stem)) > 0
            full = np.asarray(Image.open(folder / "mask" / stem)) > 0
            if visib.sum() < 1:
                continue
            matches = [
                a
                for a in gt["annotations"]
                if images[a["image_id"]]["im_id"] == int(im_id)
                and a["category_id"] == inst["obj_id"]
                and np.array_equal(decode(a["segmentation"]), visib)
            ]
            assert len(matches) == 1, (im_id, gt_id)
            a = matches[0]
            assert a["area"] == int(visib.sum())
            rows, cols = np.where(full.any(axis=1))[0], np.where(full.any(axis=0))[0]
            box = [cols[0], rows[0], cols[-1] - cols[0] + 1, rows[-1] - rows[0] + 1]
            assert a["bbox"] == [float(v) for v in box], (a["bbox"], box)
            checked += 1
    assert checked == len(gt["annotations"]) and checked >= 6


def test_modal_boxes_score_as_cocoeval(tmp_path: Path, rendered: Path) -> None:
    compare(tmp_path, rendered, 2, "--bbox-type", "modal")


def test_lmo_photographs_with_rendered_masks_score_as_cocoeval(tmp_path: Path) -> None:
    lmo = need(SHARED / "data" / "lmo")
    gt = compare(tmp_path, lmo, seed=3)
    # The images are test_targets_bop19.json's, as bop_toolkit reads them.
    targets = json.loads((lmo / "test_targets_bop19.json").read_text())
    assert {(im["scene_id"], im["im_id"]) for im in gt["images"]} == {
        (t["scene_id"], t["im_id"]) for t in targets
    }


def test_evaluate_detections_equals_the_cli(tmp_path: Path, rendered: Path) -> None:
    import synthgen

    gt = compare(tmp_path, rendered, 4)
    assert gt["annotations"]
    ours = synthgen.evaluate_detections(rendered, tmp_path / "dets.json")
    cli = json.loads((tmp_path / "s.json").read_text())
    for key in ("bbox", "segm", "n_gt", "n_images", "entries", "other_images"):
        assert ours[key] == cli[key], key
    with pytest.raises(synthgen.InputError, match="bbox_type"):
        synthgen.evaluate_detections(rendered, tmp_path / "dets.json", bbox_type="tight")
    bad = tmp_path / "bad.json"
    entry = {"scene_id": 0, "image_id": 0, "category_id": 8, "score": 1, "bbox": [1, 2, 0, 4]}
    bad.write_text(json.dumps([entry]))
    with pytest.raises(synthgen.InputError, match="entry 0"):
        synthgen.evaluate_detections(rendered, bad)
