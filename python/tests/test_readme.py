"""The README's Python example, run as written (from the repository root)."""

from __future__ import annotations

import os
import re
import subprocess
import sys

import pytest

from .conftest import REPO, need

MARKER = "<!-- readme-python-example -->"


def readme_example() -> str:
    text = (REPO / "README.md").read_text(encoding="utf-8")
    after = text.split(MARKER, 1)
    assert len(after) == 2, f"README.md has no {MARKER} block"
    m = re.match(r"\s*```python\n(.*?)```", after[1], re.S)
    assert m, "the marker is not followed by a python code block"
    return m.group(1)


def test_readme_example_runs_as_written() -> None:
    try:
        import torch  # noqa: F401
    except ImportError:
        if os.environ.get("SYNTHGEN_REQUIRE_TORCH") == "1":
            raise
        pytest.skip("torch is not installed: the README's training loop did not run")
    need(REPO / "datasets" / "meshes" / "driller.ply")
    out = subprocess.run(
        [sys.executable, "-c", readme_example()],
        cwd=REPO,
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert out.returncode == 0, out.stderr
    lines = out.stdout.strip().splitlines()
    assert [ln.split(":")[0] for ln in lines] == ["epoch 0", "epoch 1", "epoch 2"], out.stdout
    for ln in lines:
        loss = float(ln.split("L1 ")[1].split(" m")[0])
        # An L1 error on the object's position in metres: finite and below the camera's range.
        assert 0.0 <= loss < 2.0, ln
