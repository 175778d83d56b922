"""`synthgen.Predictor` / `synthgen.predict`: the detector and a pose model on numpy images
with no GT give what `synthgen predict` writes for the same frames."""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Tuple

import numpy as np
import pytest
import synthgen

from .conftest import run_cli as _run
from .conftest import synthgen_exe


def test_predictor_matches_the_cli(
    tmp_path: Path, rendered: Path, models: Tuple[Path, Path]
) -> None:
    exe = synthgen_exe()
    dense, det = models
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
    # The refinement of `synthgen predict --refine`: the same detections, refined poses.
    refined = synthgen.Predictor(dense, det, objects_from=rendered, refine="edges").predict(
        frame.rgb, frame.cam_K
    )
    assert [o["obj_id"] for o in refined] == [o["obj_id"] for o in found]
    for o in refined:
        np.testing.assert_allclose(o["R"] @ o["R"].T, np.eye(3), atol=1e-6)
    with pytest.raises(synthgen.InputError, match="not a refinement"):
        synthgen.Predictor(dense, det, refine="sharpen")


HEADER = (
    "================================================================================\n"
    "MSG: std_msgs/Header\nbuiltin_interfaces/Time stamp\nstring frame_id\n"
    "================================================================================\n"
    "MSG: builtin_interfaces/Time\nint32 sec\nuint32 nanosec\n"
)
IMAGE = (
    "std_msgs/Header header\nuint32 height\nuint32 width\nstring encoding\n"
    "uint8 is_bigendian\nuint32 step\nuint8[] data\n" + HEADER
)
COMPRESSED = "std_msgs/Header header\nstring format\nuint8[] data\n" + HEADER
CAMERA_INFO = (
    "std_msgs/Header header\nuint32 height\nuint32 width\nstring distortion_model\n"
    "float64[] d\nfloat64[9] k\nfloat64[9] r\nfloat64[12] p\nuint32 binning_x\n"
    "uint32 binning_y\nsensor_msgs/RegionOfInterest roi\n"
    + HEADER
    + "================================================================================\n"
    "MSG: sensor_msgs/RegionOfInterest\nuint32 x_offset\nuint32 y_offset\n"
    "uint32 height\nuint32 width\nbool do_rectify\n"
)


def test_a_bag_written_by_mcap_ros2_reads_as_the_frames(
    tmp_path: Path, rendered: Path, models: Tuple[Path, Path]
) -> None:
    """A ROS 2 bag written by another implementation (mcap-ros2-support's CDR serializer,
    zstd chunks): bgr8 Images and PNG CompressedImages of the rendered frames give the poses
    `--data` gives for them."""
    try:
        import mcap_ros2.writer as writer_mod
        from PIL import Image as image_mod
    except ImportError:  # pragma: no cover - depends on the machine
        if os.environ.get("SYNTHGEN_REQUIRE_MCAP") == "1":
            raise
        pytest.skip(
            "mcap-ros2-support or pillow is not installed: the bag written by another "
            "implementation was not read (pip install mcap-ros2-support pillow; CI runs it "
            "with SYNTHGEN_REQUIRE_MCAP=1)"
        )
    import io

    exe = synthgen_exe()
    dense, det = models
    ds = synthgen.open_dataset(rendered)
    bag = tmp_path / "run.mcap"
    with open(bag, "wb") as f:
        w = writer_mod.Writer(f)
        s_img = w.register_msgdef("sensor_msgs/msg/Image", IMAGE)
        s_png = w.register_msgdef("sensor_msgs/msg/CompressedImage", COMPRESSED)
        s_info = w.register_msgdef("sensor_msgs/msg/CameraInfo", CAMERA_INFO)
        for i in range(len(ds)):
            frame = ds[i]
            h, wd = frame.rgb.shape[:2]
            header = {"stamp": {"sec": 7, "nanosec": i * 1000}, "frame_id": "cam"}
            t = 7_000_000_000 + i * 1000
            k = np.asarray(frame.cam_K, dtype=float)
            if i == 0:
                w.write_message(
                    "/cam/color/camera_info",
                    s_info,
                    {
                        "header": header,
                        "height": h,
                        "width": wd,
                        "distortion_model": "plumb_bob",
                        "d": [0.0] * 5,
                        "k": k.reshape(-1).tolist(),
                        "r": np.eye(3).reshape(-1).tolist(),
                        "p": np.hstack([k, np.zeros((3, 1))]).reshape(-1).tolist(),
                        "binning_x": 0,
                        "binning_y": 0,
                        "roi": {
                            "x_offset": 0,
                            "y_offset": 0,
                            "height": 0,
                            "width": 0,
                            "do_rectify": False,
                        },
                    },
                    log_time=t,
                    publish_time=t,
                )
            bgr = np.ascontiguousarray(frame.rgb[:, :, ::-1])
            w.write_message(
                "/cam/color/image_raw",
                s_img,
                {
                    "header": header,
                    "height": h,
                    "width": wd,
                    "encoding": "bgr8",
                    "is_bigendian": 0,
                    "step": wd * 3,
                    "data": bgr.tobytes(),
                },
                log_time=t,
                publish_time=t,
            )
            png = io.BytesIO()
            image_mod.fromarray(frame.rgb).save(png, format="PNG")
            w.write_message(
                "/cam/color/image_raw/compressed",
                s_png,
                {
                    "header": header,
                    "format": "png",
                    "data": png.getvalue(),
                },
                log_time=t,
                publish_time=t,
            )
        w.finish()

    ref = tmp_path / "ref"
    _run(
        exe, "predict", "-q", "--model", dense, "--detector", det, "--data", rendered, "--out", ref
    )
    want = (ref / "results.csv").read_text().splitlines()
    for topic, name in [
        ("/cam/color/image_raw", "raw"),
        ("/cam/color/image_raw/compressed", "png"),
    ]:
        out = tmp_path / name
        _run(
            exe,
            "predict",
            "-q",
            "--model",
            dense,
            "--detector",
            det,
            "--bag",
            bag,
            "--image-topic",
            topic,
            "--camera-info-topic",
            "/cam/color/camera_info",
            "--out",
            out,
        )
        got = (out / "results.csv").read_text().splitlines()

        # The same rows but the time column (each run's own).
        def strip(r: str) -> str:
            return r.rsplit(",", 1)[0]

        assert [strip(r) for r in got] == [strip(r) for r in want], name
        lines = [json.loads(x) for x in (out / "predictions.jsonl").read_text().splitlines()]
        assert len(lines) == len(ds)
        assert lines[2]["frame"] == "cam@7.000002000"
        assert abs(lines[2]["stamp"] - 7.000002) < 1e-9
