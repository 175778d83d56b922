"""synthgen.experiment: the experiments as the CLI runs them, from Python."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
import synthgen


def test_mix_quick_writes_the_table_and_resumes(tmp_path: Path, driller: Path) -> None:
    out = tmp_path / "mix"
    events: list = []
    r = synthgen.experiment.mix(
        real_proxy=True,
        objects=[driller],
        quick=True,
        out=out,
        progress=lambda e, t, n: events.append(e),
    )
    assert r["out"] == str(out)
    assert "| real 42 + synth 0 |" in r["markdown"]
    # The study's seven compositions of the quick total, all real first.
    assert [(row["real"], row["synth"]) for row in r["table"]] == [
        ("42", "0"),
        ("35", "7"),
        ("28", "14"),
        ("21", "21"),
        ("14", "28"),
        ("7", "35"),
        ("0", "42"),
    ]
    for name in ("table.md", "table.csv", "table_objects.csv", "plot.png", "experiment.json"):
        assert (out / name).is_file(), name
    manifest = json.loads((out / "synthgen.json").read_text())
    assert any("synthgen.experiment.mix(" in part for part in manifest["command_line"])
    assert "start" in events and "info" in events
    # The same call again keeps every finished row: the same table, no row trained again.
    events.clear()
    again = synthgen.experiment.mix(
        real_proxy=True,
        objects=[driller],
        quick=True,
        out=out,
        progress=lambda e, t, n: events.append((e, t)),
    )
    assert again["table"] == r["table"]
    assert any(e == "info" and "7 rows already finished" in t for e, t in events)


def test_bad_options_are_input_errors(tmp_path: Path) -> None:
    with pytest.raises(synthgen.InputError, match="unknown variant `resnet`, expected"):
        synthgen.experiment.sim2real(test=tmp_path, model="resnet", out=tmp_path / "o")
    with pytest.raises(synthgen.InputError, match="unknown variant `snap`, expected"):
        synthgen.experiment.sim2real(test=tmp_path, refine="snap", out=tmp_path / "o")
    with pytest.raises(synthgen.InputError, match="unknown variant `yes`, expected"):
        synthgen.experiment.sim2real(test=tmp_path, visible_box="yes", out=tmp_path / "o")
    with pytest.raises(synthgen.InputError, match="--visible-box applies to the RGB models"):
        synthgen.experiment.sim2real(
            test=tmp_path, fit=tmp_path, visible_box="gt", out=tmp_path / "o"
        )
    with pytest.raises(synthgen.InputError, match="not found"):
        synthgen.experiment.sim2real(
            test=tmp_path / "missing", fit=tmp_path / "missing", out=tmp_path / "o"
        )
    with pytest.raises(synthgen.InputError, match="unknown experiment"):
        synthgen._native.run_experiment("table", "{}")


def test_sim2real_refuses_a_detector_folder_without_a_detector(
    tmp_path: Path, ycbv_real: Path
) -> None:
    # Issue 52: refused before anything is fitted or written.
    with pytest.raises(synthgen.InputError, match="no detector there"):
        synthgen.experiment.sim2real(
            test=ycbv_real,
            fit=ycbv_real,
            test_scenes=[2],
            detector=tmp_path / "nowhere",
            out=tmp_path / "o",
        )
    assert not (tmp_path / "o").exists()
