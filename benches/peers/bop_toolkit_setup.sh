#!/usr/bin/env bash
# Set up the bop_toolkit peer: a Python venv that runs thodan/bop_toolkit's evaluation
# (scripts/eval_bop19_pose.py) with its default VSD renderer, vispy, headless through
# EGL on Mesa (llvmpipe software GL: no display, no GPU).
#
# bop_toolkit is not on PyPI; point BOP_TOOLKIT at a checkout of it. The checkout is put
# on the venv's sys.path with a .pth file (nothing is built or written into it).
# Idempotent: re-running skips whatever is already installed.
#
#   BOP_TOOLKIT=/path/to/bop_toolkit bash benches/peers/bop_toolkit_setup.sh
#
# Environment:
#   BOP_TOOLKIT  bop_toolkit checkout (required)
#   BOPTK_VENV   venv to create or update (default: ~/.cache/synthgen/bop_toolkit-venv)
#   PYTHON       interpreter for the venv (default: the first of python3.12, 3.11, 3.10,
#                python3 that is >= 3.8 and < 3.13, bop_toolkit's supported range)
set -euo pipefail

log() { echo "[bop_toolkit_setup] $*" >&2; }

if [ -z "${BOP_TOOLKIT:-}" ]; then
    log "BOP_TOOLKIT is not set. Get a checkout and point BOP_TOOLKIT at it:"
    log "  git clone https://github.com/thodan/bop_toolkit"
    log "  BOP_TOOLKIT=\$PWD/bop_toolkit bash $0"
    exit 2
fi
BOP_TOOLKIT="$(cd "$BOP_TOOLKIT" && pwd)"
if [ ! -f "$BOP_TOOLKIT/bop_toolkit_lib/config.py" ] ||
   [ ! -f "$BOP_TOOLKIT/scripts/eval_bop19_pose.py" ]; then
    log "$BOP_TOOLKIT does not look like a bop_toolkit checkout"
    exit 2
fi
VENV="${BOPTK_VENV:-$HOME/.cache/synthgen/bop_toolkit-venv}"

# --- 1. venv ------------------------------------------------------------------------
py_ok() {  # usable interpreter: bop_toolkit declares requires-python >=3.8,<3.13
    "$1" -c 'import sys; sys.exit(0 if (3, 8) <= sys.version_info[:2] < (3, 13) else 1)' \
        2>/dev/null
}
pick_python() {
    if [ -n "${PYTHON:-}" ]; then echo "$PYTHON"; return; fi
    for c in python3.12 python3.11 python3.10 python3; do
        if command -v "$c" >/dev/null 2>&1 && py_ok "$c"; then echo "$c"; return; fi
    done
    log "no Python >= 3.8 and < 3.13 found (set PYTHON=/path/to/python3.11)"
    exit 1
}
if [ -x "$VENV/bin/python" ] && py_ok "$VENV/bin/python"; then
    log "venv exists: $VENV"
else
    PY="$(pick_python)"
    log "creating venv with $PY at $VENV"
    rm -rf "$VENV"
    mkdir -p "$(dirname "$VENV")"
    "$PY" -m venv "$VENV"
fi
VPY="$VENV/bin/python"

# --- 2. Python packages -------------------------------------------------------------
# Only what the pose evaluation imports (bop_toolkit_lib's inout, misc, pose_error,
# renderer_vispy, pose_matching, score). The rest of its declared dependencies
# (opencv, matplotlib, scikit-image, webdataset) serve visualisation and other scripts.
# numpy<2 as bop_toolkit requires. Tested with numpy 1.26.4, scipy 1.17.1, vispy 0.17.0,
# PyOpenGL 3.1.10, pypng 0.20220715.0, imageio 2.38.2, pillow 13.0.0 on Python 3.11.
PKGS=("numpy>=1.21,<2" "scipy>=1.10" "vispy>=0.14.2" "PyOpenGL>=3.1" "pypng>=0.20220715.0"
      "imageio>=2.35" "pillow>=8.2" "pytz" "tqdm")
if "$VPY" -c 'import numpy, scipy, vispy, OpenGL, png, imageio, PIL, pytz, tqdm, sys
sys.exit(int(numpy.__version__.split(".")[0]) >= 2)' 2>/dev/null; then
    log "python packages already installed"
else
    log "installing python packages"
    "$VPY" -m pip install --disable-pip-version-check --no-cache-dir -q "${PKGS[@]}"
fi

# --- 3. bop_toolkit itself: the checkout on sys.path ----------------------------------
SITE="$("$VPY" -c 'import sysconfig; print(sysconfig.get_paths()["purelib"])')"
echo "$BOP_TOOLKIT" > "$SITE/bop_toolkit_checkout.pth"
log "bop_toolkit_lib from $BOP_TOOLKIT"

# --- 4. smoke test: one headless vispy/EGL depth render of a cube ---------------------
# EGL_PLATFORM=surfaceless: without a display Mesa's default EGL platform fails and vispy
# reports 'Could not import backend "EGL"'. (renderer_vispy sets PYOPENGL_PLATFORM=egl.)
tmp="$(mktemp -d)"
trap 'rm -rf "$tmp"' EXIT
if ! EGL_PLATFORM=surfaceless PYOPENGL_PLATFORM=egl "$VPY" - "$tmp/cube.ply" <<'EOF'
import sys
import numpy as np

path = sys.argv[1]
# 100 mm cube centred on the origin, as an ASCII PLY (vertices and triangles only).
v = np.array([[x, y, z] for x in (-50, 50) for y in (-50, 50) for z in (-50, 50)], float)
quads = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
tris = [t for a, b, c, d in quads for t in ((a, b, c), (a, c, d))]
with open(path, "w") as f:
    f.write("ply\nformat ascii 1.0\nelement vertex 8\nproperty float x\nproperty float y\n"
            "property float z\nelement face 12\nproperty list uchar int vertex_indices\n"
            "end_header\n")
    f.writelines("%g %g %g\n" % tuple(p) for p in v)
    f.writelines("3 %d %d %d\n" % t for t in tris)

from bop_toolkit_lib.rendering import renderer

r = renderer.create_renderer(64, 48, renderer_type="vispy", mode="depth")
r.add_object(1, path)
depth = r.render_object(1, np.eye(3), np.array([[0.0], [0.0], [500.0]]),
                        60.0, 60.0, 32.0, 24.0)["depth"]
centre = float(depth[24, 32])
assert abs(centre - 450.0) < 1.0, f"centre depth {centre} mm, expected 450"
import OpenGL.GL as gl
print("[bop_toolkit_setup] ok: vispy renders depth headless via EGL on "
      f"{gl.glGetString(gl.GL_RENDERER).decode()} (centre depth {centre:.1f} mm)",
      file=sys.stderr)
EOF
then
    log "headless render failed. vispy's EGL backend needs the Mesa EGL/GL drivers;"
    log "on Debian/Ubuntu: apt-get install libegl1 libegl-mesa0 libgl1 libgl1-mesa-dri"
    exit 1
fi
log "venv ready: $VENV"
