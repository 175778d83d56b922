#!/usr/bin/env bash
# Creates the venv that `synthgen render --backend blender` loads bpy from, and checks it.
#   scripts/setup-blender.sh [VENV_DIR]
# VENV_DIR defaults to $SYNTHGEN_BLENDER_VENV, else ${XDG_CACHE_HOME:-~/.cache}/synthgen/blender-venv
# (where synthgen looks by default). Needs CPython 3.11 (bpy 5.0.1 is built for it only) with
# its shared library (libpython3.11.so), which the `blender` cargo feature links against.
# The bpy wheel is ~374 MB; the venv ~1 GB.
set -euo pipefail

venv="${1:-${SYNTHGEN_BLENDER_VENV:-${XDG_CACHE_HOME:-$HOME/.cache}/synthgen/blender-venv}}"
python="${PYTHON:-}"
if [ -z "$python" ]; then
  for p in python3.11 python3; do
    if command -v "$p" >/dev/null 2>&1 && "$p" -c 'import sys; sys.exit(sys.version_info[:2] != (3, 11))'; then
      python="$p"; break
    fi
  done
fi
if [ -z "$python" ]; then
  echo "error: no CPython 3.11 found (bpy 5.0.1 needs exactly 3.11); set PYTHON=/path/to/python3.11" >&2
  exit 1
fi
libdir="$("$python" -c 'import sysconfig; print(sysconfig.get_config_var("LIBDIR"))')"
if ! ls "$libdir"/libpython3.11.so* >/dev/null 2>&1; then
  echo "warning: no libpython3.11.so in $libdir; building with --features blender needs it (Debian: apt-get install libpython3.11-dev)" >&2
fi

if [ ! -x "$venv/bin/python" ]; then
  echo "creating $venv with $("$python" --version)"
  mkdir -p "$(dirname "$venv")"
  "$python" -m venv "$venv"
fi
if ! "$venv/bin/python" -c 'import bpy, numpy' >/dev/null 2>&1; then
  echo "installing bpy 5.0.1 and numpy<2 into $venv (a ~374 MB download)"
  "$venv/bin/python" -m pip install --quiet --disable-pip-version-check 'bpy==5.0.1' 'numpy<2'
fi
version="$("$venv/bin/python" -c 'import bpy; print(bpy.app.version_string)' 2>/dev/null | tail -n 1)"
echo "ok: bpy $version in $venv"
if [ "$venv" != "${XDG_CACHE_HOME:-$HOME/.cache}/synthgen/blender-venv" ]; then
  echo "hint: pass --blender-venv $venv or export SYNTHGEN_BLENDER_VENV=$venv"
fi
