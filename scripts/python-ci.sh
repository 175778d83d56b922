#!/usr/bin/env bash
# The Python package's CI checks (.ci/run calls this after the workspace build and the blender
# step, which installs python3.11 with venv): build the wheel, install it into a fresh venv,
# run pytest (the torch and shared-data tests must run, not skip), mypy.stubtest and mypy.
# PYTHON, SYNTHGEN_CI_PY_TOOLS and SYNTHGEN_CI_PY_VENV override the interpreter and the venvs
# (the test venv holds torch with its CUDA libraries: ~5.4 GB).
set -euo pipefail
cd "$(dirname "$0")/.."
started=$(date +%s)
python=${PYTHON:-python3.11}
tools=${SYNTHGEN_CI_PY_TOOLS:-target/ci-python-tools}
venv=${SYNTHGEN_CI_PY_VENV:-target/ci-python-venv}
tools=$(realpath -m "$tools") venv=$(realpath -m "$venv") wheels=$(realpath -m target/ci-wheels)
pip_quiet=(--quiet --disable-pip-version-check)

[ -x "$tools/bin/maturin" ] || { "$python" -m venv "$tools" && "$tools/bin/pip" install "${pip_quiet[@]}" "maturin>=1.9,<2"; }
# The dev profile reuses the workspace build (only pyo3, numpy and the binding crate are
# compiled again: ~40 s); the benchmark uses a release wheel (docs/python.md).
rm -rf "$wheels"
(cd python && "$tools/bin/maturin" build --profile dev --locked -o "$wheels")
echo "wheel built: $(( $(date +%s) - started )) s"

# A fresh venv each run: the wheel and what it declares (numpy), pytest, mypy, and torch for
# synthgen.torch. PyPI's Linux torch pulls its CUDA libraries (~3 GB download, ~5.4 GB on
# disk, ~2.5 min here); download.pytorch.org's CPU index is not reachable from CI. pip keeps
# the wheels in its cache, so reruns install faster.
rm -rf "$venv"
"$python" -m venv "$venv"
"$venv/bin/pip" install "${pip_quiet[@]}" "$wheels"/synthgen-*.whl pytest mypy torch
echo "venv installed: $(( $(date +%s) - started )) s"

SYNTHGEN_REQUIRE_TORCH=1 SYNTHGEN_REQUIRE_SHARED=1 SYNTHGEN_BIN=target/debug/synthgen \
  "$venv/bin/python" -m pytest -q -p no:cacheprovider python/tests
# The stubs are checked against the built module, not trusted; the package type-checks.
"$venv/bin/python" -m mypy.stubtest synthgen._native --allowlist python/stubtest-allowlist.txt
"$venv/bin/python" -m mypy -p synthgen
echo "python package checks: $(( $(date +%s) - started )) s"
