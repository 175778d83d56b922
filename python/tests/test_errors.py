"""Rust errors arrive as synthgen.Error subclasses with the library's messages."""

from __future__ import annotations

from pathlib import Path

import pytest
import synthgen


def test_bad_mesh_path_names_the_file(tmp_path: Path) -> None:
    missing = tmp_path / "no_such_mesh.ply"
    with pytest.raises(synthgen.InputError) as e:
        synthgen.Generator(objects=[missing])
    assert str(missing) in str(e.value)
    assert str(e.value).startswith("cannot load object ")
    assert isinstance(e.value, synthgen.Error)


def test_broken_mesh_is_an_error_not_a_crash(tmp_path: Path) -> None:
    bad = tmp_path / "broken.ply"
    bad.write_text("ply\nformat ascii 1.0\nelement vertex 3\nend_header\n1 2\n")
    with pytest.raises(synthgen.Error) as e:
        synthgen.Generator(objects=[bad])
    assert str(bad) in str(e.value)


def test_bad_scene_file(tmp_path: Path, driller: Path) -> None:
    spec = tmp_path / "scene.toml"
    spec.write_text("[camera]\npreset = 'no_such_camera'\n")
    with pytest.raises(synthgen.InputError) as e:
        synthgen.Generator(objects=[driller], scene=spec)
    assert "no_such_camera" in str(e.value)
    with pytest.raises(synthgen.InputError) as e:
        synthgen.Generator(objects=[driller], scene=tmp_path / "missing.toml")
    assert "missing.toml" in str(e.value)


def test_no_objects_has_a_hint() -> None:
    with pytest.raises(synthgen.InputError) as e:
        synthgen.Generator(objects=[])
    assert str(e.value) == "no objects to render"
    assert "objects" in e.value.hint  # type: ignore[attr-defined]


def test_bad_arguments(driller: Path) -> None:
    with pytest.raises(synthgen.InputError, match="unknown units"):
        synthgen.Generator(objects=[driller], units="inches")
    with pytest.raises(synthgen.InputError, match="obj_ids has 2 ids"):
        synthgen.Generator(objects=[driller], obj_ids=[1, 2])


def test_missing_dataset(tmp_path: Path) -> None:
    with pytest.raises(synthgen.InputError, match="dataset folder not found"):
        synthgen.open_dataset(tmp_path / "nothing")
    (tmp_path / "empty").mkdir()
    with pytest.raises(synthgen.InputError) as e:
        synthgen.open_dataset(tmp_path / "empty")
    assert "empty" in str(e.value)


def test_render_refuses_a_non_empty_folder(tmp_path: Path, driller: Path) -> None:
    (tmp_path / "keep.txt").write_text("mine")
    with pytest.raises(synthgen.InputError, match="output folder is not empty"):
        synthgen.render([driller], tmp_path, frames=1, progress=False)
    assert (tmp_path / "keep.txt").read_text() == "mine"
