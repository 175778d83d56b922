"""open_dataset on what `render` wrote (equal to the generator's frames) and on real YCB-Video."""

from __future__ import annotations

import pickle
from pathlib import Path

import numpy as np
import pytest
import synthgen


def test_rendered_dataset_reads_back_as_the_generators_frames(
    rendered: Path, gen: synthgen.Generator
) -> None:
    ds = synthgen.open_dataset(rendered)
    assert ds.layout == "bop" and ds.splits == ["train_pbr"] and len(ds) == len(gen)
    for i in range(len(ds)):
        f, g = ds[i], gen[i]
        assert f.source is not None and f.source["im_id"] == i and f.index == i
        assert np.array_equal(f.rgb, g.rgb)  # PNG is lossless
        # Depth PNGs store 0.1 mm steps.
        np.testing.assert_allclose(f.depth, g.depth, atol=0.06e-3)
        assert np.array_equal(f.masks, g.masks)
        assert np.array_equal(f.masks_visib, g.masks_visib)
        assert np.array_equal(f.instance_ids, g.instance_ids)
        np.testing.assert_allclose(f.cam_K, g.cam_K)
        assert f.obj_ids == g.obj_ids
        for a, b in zip(f.objects, g.objects):
            np.testing.assert_allclose(a["R"], b["R"], atol=1e-6)
            np.testing.assert_allclose(a["t"], b["t"], atol=1e-6)
            for key in ("bbox_obj", "bbox_visib", "px_count_all", "px_count_visib"):
                assert a[key] == b[key], key
            assert a["visib_fract"] == pytest.approx(b["visib_fract"], abs=1e-6)


def test_images_load_lazily_and_frames_pickle(rendered: Path) -> None:
    ds = synthgen.open_dataset(rendered)
    f = ds[0]
    assert f._arrays == {}  # annotations only
    assert f.rgb.shape == (480, 640, 3)
    assert set(f._arrays) == {"rgb"}
    back = pickle.loads(pickle.dumps(f))
    assert np.array_equal(back.masks, f.masks) and back.source == f.source
    ds2 = pickle.loads(pickle.dumps(ds))
    assert len(ds2) == len(ds) and np.array_equal(ds2[1].rgb, ds[1].rgb)


def test_filtering_by_object_and_visibility(rendered: Path) -> None:
    ds = synthgen.open_dataset(rendered)
    assert ds.obj_ids == [1]
    assert len(ds.filter(obj_ids=[2])) == 0
    visible = ds.filter(min_visib_fract=0.5)
    for f in visible:
        assert f.objects and all(o["visib_fract"] >= 0.5 for o in f.objects)
        assert f.masks.shape[0] == len(f.objects)
        assert sorted(set(np.unique(f.instance_ids)) - {0}) <= list(
            range(1, len(f.objects) + 1)
        )
    total = sum(len(f.objects) for f in ds)
    kept = sum(len(f.objects) for f in visible)
    assert kept <= total
    assert len(synthgen.open_dataset(rendered, obj_ids=1)) == len(ds)
    assert len(synthgen.open_dataset(rendered, split="train_pbr")) == len(ds)


def test_real_ycbv_frames(ycbv_real: Path) -> None:
    ds = synthgen.open_dataset(ycbv_real)
    assert ds.layout == "ycbv"
    assert len(ds) == 60
    f = ds[0]
    assert f.rgb.dtype == np.uint8 and f.rgb.shape == (480, 640, 3)
    assert (
        f.depth is not None
        and f.depth.dtype == np.float32
        and f.depth.shape == (480, 640)
    )
    valid = f.depth[f.depth > 0]
    assert 0.2 < float(np.median(valid)) < 3.0  # metres
    assert f.masks is None  # YCB-Video has visible masks (labels) only
    assert f.masks_visib.shape == (len(f.objects), 480, 640) and f.masks_visib.any()
    assert f.cam_K[0, 0] > 500 and f.cam_K[2, 2] == 1.0
    for o in f.objects:
        np.testing.assert_allclose(o["R"] @ o["R"].T, np.eye(3), atol=1e-6)
        assert 0.2 < o["t"][2] < 3.0
        assert o["visib_fract"] is None and o["bbox_obj"] is None
    # Per-object filtering keeps that object's instances only.
    some = f.objects[0]["obj_id"]
    only = ds.filter(obj_ids=some)
    assert 0 < len(only) <= len(ds)
    assert all(o["obj_id"] == some for fr in only for o in fr.objects)
    assert only[0].masks_visib.shape[0] == len(only[0].objects)


def _ply_vertex_count(path: Path) -> int:
    with path.open("rb") as f:
        for line in f:
            if line.startswith(b"element vertex"):
                return int(line.split()[2])
            if line.strip() == b"end_header":
                break
    raise AssertionError(f"{path}: no vertex count in the PLY header")


def test_eval_model(rendered: Path) -> None:
    points, diameter, symmetric = synthgen.open_dataset(rendered).eval_model(1)
    # Every vertex of the model, as bop_toolkit scores ADD(-S) (no subsample).
    assert points.shape == (_ply_vertex_count(rendered / "models" / "obj_000001.ply"), 3)
    assert 0.1 < diameter < 0.5 and symmetric is False
