#!/usr/bin/env bash
# The Python package's CI checks, in two parts so that .ci/run can install while cargo builds:
#   scripts/python-ci.sh setup   the venvs: maturin's, and the test venv (pytest, mypy, torch)
#   scripts/python-ci.sh test    build the wheel (maturin, dev profile: reuses the workspace
#                                build), install it into the test venv, run pytest (the torch and
#                                shared-data tests must run, not skip), mypy.stubtest and mypy
# With no argument, both. PYTHON, SYNTHGEN_CI_PY_TOOLS and SYNTHGEN_CI_PY_VENV override the
# interpreter and the venvs.
set -euo pipefail
cd "$(dirname "$0")/.."
started=$(date +%s)
python=${PYTHON:-python3.11}
tools=$(realpath -m "${SYNTHGEN_CI_PY_TOOLS:-target/ci-python-tools}")
venv=$(realpath -m "${SYNTHGEN_CI_PY_VENV:-target/ci-python-venv}")
wheels=$(realpath -m target/ci-wheels)
pip_quiet=(--quiet --disable-pip-version-check)
# torch 2.0.1 is the oldest torch the package supports (pyproject's `torch>=2.0`) and PyPI's
# smallest for CPython 3.11 on Linux: 2.3 GB with its CUDA libraries, against 3.0 GB for 2.15
# (download.pytorch.org's CPU wheels are not reachable from CI). It was built against numpy 1.
test_requirements=(pytest mypy "torch==2.0.1" "numpy<2" "pycocotools==2.0.7" "mcap==1.6.0" "mcap-ros2-support==0.6.0" "pillow" "cyclonedds==11.0.1" "rosbags==0.11.9")

setup() {
  if [ ! -x "$tools/bin/maturin" ]; then
    "$python" -m venv "$tools"
    "$tools/bin/pip" install "${pip_quiet[@]}" "maturin>=1.9,<2"
  fi
  local stamp="$venv/.synthgen-requirements"
  if [ "$(cat "$stamp" 2>/dev/null)" != "${test_requirements[*]}" ]; then
    rm -rf "$venv"
    "$python" -m venv "$venv"
    "$venv/bin/pip" install "${pip_quiet[@]}" "${test_requirements[@]}"
    echo "${test_requirements[*]}" >"$stamp"
  fi
  echo "python venvs ready: $(($(date +%s) - started)) s"
}

run_tests() {
  # The dev profile and the workspace's feature set (synthgen-workspace-hack): only pyo3,
  # numpy and the binding crate are compiled again (~40 s).
  rm -rf "$wheels"
  (cd python && "$tools/bin/maturin" build --profile dev --locked -o "$wheels")
  "$venv/bin/pip" install "${pip_quiet[@]}" --no-deps --force-reinstall "$wheels"/synthgen-*.whl
  echo "wheel built and installed: $(($(date +%s) - started)) s"
  SYNTHGEN_REQUIRE_TORCH=1 SYNTHGEN_REQUIRE_SHARED=1 SYNTHGEN_REQUIRE_PYCOCOTOOLS=1 SYNTHGEN_REQUIRE_MCAP=1 SYNTHGEN_REQUIRE_DDS=1 SYNTHGEN_BIN=target/debug/synthgen \
    "$venv/bin/python" -m pytest -q -p no:cacheprovider python/tests
  # The stubs are checked against the built module, not trusted; the package type-checks.
  "$venv/bin/python" -m mypy.stubtest synthgen._native --allowlist python/stubtest-allowlist.txt
  "$venv/bin/python" -m mypy -p synthgen
  echo "python package checks: $(($(date +%s) - started)) s"
}

case "${1:-all}" in
  setup) setup ;;
  test) run_tests ;;
  all) setup && run_tests ;;
  *) echo "usage: scripts/python-ci.sh [setup|test]" >&2; exit 2 ;;
esac
