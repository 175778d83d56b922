"""render, mix and evaluate as the CLI's commands."""

from __future__ import annotations

import io
import json
import subprocess
from pathlib import Path

import numpy as np
import pytest
import synthgen

from .conftest import REPO, synthgen_exe


def results_csv(ds: synthgen.Dataset, path: Path, offset_m: float = 0.0) -> None:
    rows = ["scene_id,im_id,obj_id,score,R,t,time"]
    for f in ds:
        for k, o in enumerate(f.objects):
            t_mm = (o["t"] + [offset_m * (k % 2), 0, 0]) * 1000.0
            R = " ".join(f"{v:.9f}" for v in o["R"].ravel())
            t = " ".join(f"{v:.6f}" for v in t_mm)
            rows.append(
                f"{f.source['scene_id']},{f.source['im_id']},{o['obj_id']},1.0,{R},{t},-1"
            )
    path.write_text("\n".join(rows) + "\n")


def test_render_report_and_manifest(rendered: Path) -> None:
    manifest = json.loads((rendered / "synthgen.json").read_text())
    assert manifest["seed"] == 3
    assert any("synthgen.render(" in part for part in manifest["command_line"])
    assert (rendered / "train_pbr" / "000000" / "scene_gt.json").is_file()


def test_render_linemod_format(tmp_path: Path, driller: Path) -> None:
    report = synthgen.render(
        [driller],
        tmp_path / "lm",
        frames=3,
        format="linemod",
        camera="linemod",
        scene=REPO / "scenes" / "tabletop.toml",
        progress=False,
    )
    assert report["written"] == 3 and not report["failures"]
    assert synthgen.open_dataset(tmp_path / "lm").layout == "linemod"


def test_progress_events(tmp_path: Path, driller: Path) -> None:
    events = []
    synthgen.render(
        [driller],
        tmp_path / "p",
        frames=4,
        scene=REPO / "scenes" / "tabletop.toml",
        progress=lambda e, text, n: events.append((e, text, n)),
    )
    assert ("start", "rendering", 4) in events
    assert sum(n for e, _, n in events if e == "advance") == 4
    assert events[-1][0] == "finish"


def test_progress_bar_draws_only_on_a_terminal() -> None:
    quiet, loud = io.StringIO(), io.StringIO()
    for bar in (
        synthgen.ProgressBar(file=quiet),
        synthgen.ProgressBar(enabled=True, file=loud),
    ):
        bar("start", "rendering", 10)
        bar("advance", "", 10)
        bar("finish", "", 0)
    assert quiet.getvalue() == ""
    assert "10/10" in loud.getvalue() and "rendering 100%" in loud.getvalue()


def test_evaluate_gt_as_results_is_perfect(tmp_path: Path, rendered: Path) -> None:
    ds = synthgen.open_dataset(rendered)
    csv = tmp_path / "gt.csv"
    results_csv(ds, csv)
    r = synthgen.evaluate(rendered, csv, min_visib_fract=0.0)
    assert r["split"] == "train_pbr" and r["skipped_rows"] == []
    assert r["scores"]["all"]["add_s_acc"] == 1.0
    assert r["scores"]["all"]["acc_5cm5deg"] == 1.0
    assert r["scores"]["all"]["n_gt"] == sum(len(f.objects) for f in ds)
    assert "| all |" in r["markdown"]


def test_evaluate_rotations_as_stored_or_nearest(tmp_path: Path, rendered: Path) -> None:
    ds = synthgen.open_dataset(rendered)
    csv = tmp_path / "gt.csv"
    results_csv(ds, csv)
    stored = synthgen.evaluate(rendered, csv, min_visib_fract=0.0)
    nearest = synthgen.evaluate(rendered, csv, min_visib_fract=0.0, rotations="nearest")
    # synthgen's own rotations are proper: both ways agree.
    assert nearest["scores"]["all"]["acc_5cm5deg"] == stored["scores"]["all"]["acc_5cm5deg"] == 1.0
    with pytest.raises(synthgen.InputError, match="rotations must be"):
        synthgen.evaluate(rendered, csv, rotations="projected")


def test_evaluate_equals_the_cli(tmp_path: Path, rendered: Path) -> None:
    exe = synthgen_exe()
    ds = synthgen.open_dataset(rendered)
    csv = tmp_path / "off.csv"
    results_csv(ds, csv, offset_m=0.03)
    ours = synthgen.evaluate(rendered, csv)
    out = tmp_path / "cli.json"
    subprocess.run(
        [
            str(exe),
            "eval",
            "--data",
            str(rendered),
            "--results",
            str(csv),
            "--json",
            str(out),
        ],
        check=True,
        capture_output=True,
    )
    assert ours["scores"] == json.loads(out.read_text())


def test_evaluate_bop_gt_is_perfect_and_equals_the_cli(
    tmp_path: Path, rendered: Path
) -> None:
    ds = synthgen.open_dataset(rendered)
    csv = tmp_path / "gt.csv"
    results_csv(ds, csv)
    r = synthgen.evaluate(rendered, csv, bop=True)
    bop = r["bop"]
    assert bop["ar"] == 1.0, bop
    for err in ("vsd", "mssd", "mspd"):
        assert bop[err]["recall_per_threshold"] == [1.0] * 10
    assert synthgen.evaluate(rendered, csv)["bop"] is None
    exe = synthgen_exe()
    off = tmp_path / "off.csv"
    results_csv(ds, off, offset_m=0.01)
    ours = synthgen.evaluate(rendered, off, bop=True)["bop"]
    out = tmp_path / "cli.json"
    subprocess.run(
        [str(exe), "eval", "--bop", "--data", str(rendered), "--results", str(off)]
        + ["--json", str(out)],
        check=True,
        capture_output=True,
    )
    assert ours == json.loads(out.read_text())["bop"]


def test_metrics_equal_evaluate(tmp_path: Path, rendered: Path) -> None:
    ds = synthgen.open_dataset(rendered)
    points, diameter, symmetric = ds.eval_model(1)
    f = ds[0]
    o = f.objects[0]
    e = synthgen.metrics.pose_errors(
        points, diameter, symmetric, o["R"], o["t"], o["R"], o["t"] + [0.03, 0, 0]
    )
    assert e["add"] == pytest.approx(0.03) and e["te"] == pytest.approx(0.03)


def test_mix_of_two_renders(tmp_path: Path, rendered: Path, driller: Path) -> None:
    synth = tmp_path / "synth"
    synthgen.render(
        [driller],
        synth,
        frames=6,
        seed=9,
        scene=REPO / "scenes" / "tabletop.toml",
        camera="linemod",
        progress=False,
    )
    out = tmp_path / "mix"
    r = synthgen.mix(
        rendered,
        synth,
        out,
        real_count=3,
        synth_count=2,
        test_count=2,
        seed=1,
        progress=False,
    )
    assert (r["train_real"], r["train_synth"], r["test"]) == (3, 2, 2)
    mixed = synthgen.open_dataset(out)
    assert sorted(mixed.splits) == ["test", "train"]
    assert len(mixed) == 7
    again = synthgen.mix(
        rendered,
        synth,
        tmp_path / "mix2",
        real_count=3,
        synth_count=2,
        test_count=2,
        seed=1,
        progress=False,
    )
    assert again["train_real"] == 3
    a = (out / "provenance.json").read_text().replace(str(out), "")
    b = (
        (tmp_path / "mix2" / "provenance.json")
        .read_text()
        .replace(str(tmp_path / "mix2"), "")
    )
    assert a == b
    with pytest.raises(synthgen.InputError):
        synthgen.mix(
            rendered,
            synth,
            rendered / "inside",
            real_count=1,
            synth_count=1,
            progress=False,
        )
    assert np.array_equal(mixed[0].rgb.shape, (480, 640, 3))
