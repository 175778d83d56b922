"""`import synthgen` stays light: no torch."""

from __future__ import annotations

import subprocess
import sys


def test_import_does_not_import_torch() -> None:
    code = "import sys, synthgen, synthgen.metrics; print('torch' in sys.modules)"
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True
    )
    assert out.stdout.strip() == "False"


def test_public_names() -> None:
    import synthgen

    for name in synthgen.__all__:
        assert hasattr(synthgen, name), name
