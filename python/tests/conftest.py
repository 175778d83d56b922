"""Shared fixtures: the repository's meshes and scenes, ../shared/data, small generators."""

from __future__ import annotations

import os
import subprocess
from pathlib import Path
from typing import Tuple

import pytest
import synthgen

REPO = Path(os.environ.get("SYNTHGEN_REPO", Path(__file__).resolve().parents[2]))
SHARED = Path(os.environ.get("SYNTHGEN_SHARED", REPO.parent / "shared"))
DRILLER = REPO / "datasets" / "meshes" / "driller.ply"
LMO_MODELS = SHARED / "data" / "lmo" / "models"
YCBV_REAL = SHARED / "data" / "ycbv_real"


def synthgen_exe() -> Path:
    """The CLI binary (SYNTHGEN_BIN, else cargo's debug build), or a skip saying how to get it."""
    exe = Path(os.environ.get("SYNTHGEN_BIN", REPO / "target" / "debug" / "synthgen"))
    if not exe.is_file():
        pytest.skip(
            f"no synthgen binary at {exe} (cargo build -p synthgen-cli, or set SYNTHGEN_BIN)"
        )
    return exe


def need(path: Path) -> Path:
    """`path`, or a skip with the reason (a failure under SYNTHGEN_REQUIRE_SHARED=1, as in CI)."""
    if not path.exists():
        msg = f"{path} is missing (the shared data lives beside the repository)"
        if os.environ.get("SYNTHGEN_REQUIRE_SHARED") == "1":
            pytest.fail(msg)
        pytest.skip(msg)
    return path


@pytest.fixture(scope="session")
def driller() -> Path:
    return need(DRILLER)


@pytest.fixture(scope="session")
def lmo_models() -> Path:
    return need(LMO_MODELS)


@pytest.fixture(scope="session")
def ycbv_real() -> Path:
    return need(YCBV_REAL)


@pytest.fixture(scope="session")
def gen(driller: Path) -> synthgen.Generator:
    """Two drillers on the tabletop with the Linemod camera, 6 frames."""
    return synthgen.Generator(
        objects=[driller, driller],
        scene=REPO / "scenes" / "tabletop.toml",
        camera="linemod",
        seed=3,
        frames=6,
    )


@pytest.fixture(scope="session")
def rendered(tmp_path_factory: pytest.TempPathFactory, gen: synthgen.Generator) -> Path:
    """`gen`'s frames written as a BOP dataset by `synthgen.render`."""
    out = tmp_path_factory.mktemp("render") / "bop"
    k = gen.kwargs
    report = synthgen.render(
        k["objects"],
        out,
        frames=len(gen),
        scene=k["scene"],
        camera=k["camera"],
        seed=k["seed"],
        progress=False,
    )
    assert report["written"] == len(gen)
    return out


def run_cli(*args: object) -> None:
    """Runs the CLI with `args`, failing on a non-zero exit."""
    subprocess.run([str(a) for a in args], check=True, capture_output=True)


@pytest.fixture(scope="session")
def models(tmp_path_factory: pytest.TempPathFactory, rendered: Path) -> Tuple[Path, Path]:
    """A one-epoch detector and rgb-dense model of `rendered` (CLI-trained)."""
    exe = synthgen_exe()
    tmp = tmp_path_factory.mktemp("models")
    det = tmp / "det"
    run_cli(
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
    dense = tmp / "dense"
    run_cli(
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
    return dense, det
