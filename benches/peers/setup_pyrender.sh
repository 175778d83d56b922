#!/usr/bin/env bash
# Set up the pyrender peer benchmark: a Python 3.11 venv at benches/peers/.venv with
# pyrender 0.1.45 rendering through OSMesa (software GL, no display, no GPU).
#
# Idempotent: re-running skips whatever is already installed.
#
#   bash benches/peers/setup_pyrender.sh
#
# Environment:
#   PYTHON   interpreter used to create the venv (default: python3.11, else python3 if it is 3.11)
set -euo pipefail

HERE="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
VENV="$HERE/.venv"

log() { echo "[setup_pyrender] $*" >&2; }

# --- 1. system library: OSMesa (software off-screen GL) ---------------------------
osmesa_present() {
    ldconfig -p 2>/dev/null | grep -q 'libOSMesa\.so'
}
if osmesa_present; then
    log "libOSMesa already present"
else
    SUDO=""
    if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi
    export DEBIAN_FRONTEND=noninteractive
    if ! $SUDO apt-get install -y --no-install-recommends libosmesa6; then
        log "libosmesa6 not found in the package lists; running apt-get update"
        $SUDO apt-get update
        $SUDO apt-get install -y --no-install-recommends libosmesa6
    fi
    osmesa_present || { log "libOSMesa still missing after install"; exit 1; }
fi

# --- 2. Python 3.11 venv ----------------------------------------------------------
pick_python() {
    if [ -n "${PYTHON:-}" ]; then echo "$PYTHON"; return; fi
    for c in python3.11 python3; do
        if command -v "$c" >/dev/null 2>&1 &&
           "$c" -c 'import sys; sys.exit(0 if sys.version_info[:2] == (3, 11) else 1)' 2>/dev/null; then
            echo "$c"; return
        fi
    done
    log "no Python 3.11 found (set PYTHON=/path/to/python3.11)"; exit 1
}
if [ -x "$VENV/bin/python" ] &&
   "$VENV/bin/python" -c 'import sys; sys.exit(0 if sys.version_info[:2] == (3, 11) else 1)'; then
    log "venv exists: $VENV"
else
    PY="$(pick_python)"
    log "creating venv with $PY at $VENV"
    rm -rf "$VENV"
    "$PY" -m venv "$VENV"
fi
VPY="$VENV/bin/python"
PIP=("$VPY" -m pip install --disable-pip-version-check -q)

# --- 3. Python packages -----------------------------------------------------------
# Already installed with the exact versions? Then nothing to do.
if "$VPY" - <<'EOF' 2>/dev/null
import importlib.metadata as md, sys
want = {"pyrender": "0.1.45", "PyOpenGL": "3.1.10", "networkx": "3.4.2"}
for name, ver in want.items():
    if md.version(name) != ver:
        sys.exit(1)
import numpy, trimesh, PIL, imageio, scipy  # noqa: F401
if int(numpy.__version__.split(".")[0]) >= 2:
    sys.exit(1)
EOF
then
    log "python packages already installed"
else
    log "installing python packages"
    # numpy<2: pyrender 0.1.45 uses np.infty (removed in numpy 2.0).
    "${PIP[@]}" "numpy<2"
    # pyrender with its dependencies. It pins PyOpenGL==3.1.0, whose OpenGL.osmesa lacks
    # OSMesaCreateContextAttribs (pyrender's OSMesa platform fails to import), so PyOpenGL
    # is overridden just below; networkx is pinned to a known-good version at the same time.
    "${PIP[@]}" "pyrender==0.1.45" "numpy<2"
    "${PIP[@]}" --no-deps "PyOpenGL==3.1.10" "networkx==3.4.2"
    "${PIP[@]}" trimesh Pillow imageio "numpy<2"
fi

# --- 4. smoke test: one off-screen OSMesa render ----------------------------------
PYOPENGL_PLATFORM=osmesa "$VPY" - <<'EOF'
import numpy as np, pyrender, trimesh
m = pyrender.Mesh.from_trimesh(trimesh.creation.box(extents=(0.1, 0.1, 0.1)))
s = pyrender.Scene()
s.add(m, pose=np.eye(4))
cam = np.eye(4); cam[2, 3] = 0.5
s.add(pyrender.IntrinsicsCamera(500, 500, 32, 24, znear=0.05, zfar=5.0), pose=cam)
r = pyrender.OffscreenRenderer(64, 48)
c, d = r.render(s)
r.delete()
assert d[24, 32] > 0.4, d[24, 32]
print(f"[setup_pyrender] ok: pyrender {pyrender.__version__} renders via OSMesa "
      f"(centre depth {d[24, 32]:.3f} m)")
EOF
