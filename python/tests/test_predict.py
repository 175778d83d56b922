"""`synthgen.Predictor` / `synthgen.predict`: the detector and a pose model on numpy images
with no GT give what `synthgen predict` writes for the same frames."""

from __future__ import annotations

import json
import subprocess
from pathlib import Path

import numpy as np
import pytest
import synthgen

from .conftest import synthgen_exe


def _run(*args: object) -> None:
    subprocess.run([str(a) for a in args], check=True, capture_output=True)


def test_predictor_matches_the_cli(tmp_path: Path, rendered: Path) -> None:
    exe = synthgen_exe()
    det = tmp_path / "det"
    _run(
        exe,
        "detector",
        "train",
        "-q",
        "--data",
        rendered,
        "--input",
        "64x48",
        "--batch",
        "2",
        "--epochs",
        "1",
        "--out",
        det,
    )
    dense = tmp_path / "dense"
    _run(
        exe,
        "train",
        "-q",
        "--model",
        "rgb-dense",
        "--data",
        rendered,
        "--crop-size",
        "16",
        "--epochs",
        "1",
        "--batch",
        "4",
        "--width",
        "16",
        "--out",
        dense,
    )
    out = tmp_path / "pred"
    _run(
        exe, "predict", "-q", "--model", dense, "--detector", det, "--data", rendered, "--out", out
    )
    lines = [json.loads(line) for line in (out / "predictions.jsonl").read_text().splitlines()]

    ds = synthgen.open_dataset(rendered)
    p = synthgen.Predictor(dense, det, objects_from=rendered)
    assert p.model_kind == "rgb-dense" and not p.needs_depth
    frame = ds[0]
    found = p.predict(frame.rgb, frame.cam_K)
    want = lines[0]["objects"]
    assert [o["obj_id"] for o in found] == [o["obj_id"] for o in want]
    for got, exp in zip(found, want):
        assert got["R"].shape == (3, 3) and got["t"].shape == (3,)
        np.testing.assert_allclose(got["R"].reshape(-1), exp["R"], atol=1e-9)
        np.testing.assert_allclose(got["t"], exp["t"], atol=1e-12)
        np.testing.assert_allclose(got["bbox"], exp["bbox"])
        assert got["mask"] is None or got["mask"].shape == frame.rgb.shape[:2]
        # A rotation.
        np.testing.assert_allclose(got["R"] @ got["R"].T, np.eye(3), atol=1e-6)
    # The one-call form and K as nine numbers give the same.
    again = synthgen.predict(
        dense, det, frame.rgb, np.asarray(frame.cam_K).reshape(-1), objects_from=rendered
    )
    assert [o["obj_id"] for o in again] == [o["obj_id"] for o in found]

    with pytest.raises(synthgen.InputError, match="uint8"):
        p.predict(frame.rgb[:, :, :2], frame.cam_K)
    with pytest.raises(synthgen.InputError, match="camera matrix"):
        p.predict(frame.rgb, np.zeros((3, 3)))
    with pytest.raises(synthgen.InputError, match="min-score"):
        synthgen.Predictor(dense, det, min_score=2.0)
