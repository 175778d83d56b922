#!/usr/bin/env bash
# Whole-command benchmark: `synthgen render` writing a complete BOP dataset (640x480, five
# Linemod models) against pyrender rendering and writing the same poses, in one run.
#
#   bash benches/render_vs_pyrender.sh [FRAMES] [REPEATS]
#
# Needs ../shared/data/lmo (or LMO=path/to/lmo) and, for the peer, benches/peers/setup_pyrender.sh.
# Prints one JSON line per measurement and a summary with medians and the ratio.
set -euo pipefail
cd "$(dirname "$0")/.."
frames=${1:-500}
repeats=${2:-5}
lmo=${LMO:-../shared/data/lmo}
models=()
for id in 1 5 6 8 9; do models+=("$lmo/models/obj_$(printf %06d $id).ply"); done
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT

cargo build --release -q -p synthgen-cli
bin=target/release/synthgen

times=()
for r in $(seq 1 "$repeats"); do
  rm -rf "$work/synth"
  t0=$(date +%s.%N)
  "$bin" render -q --objects "${models[@]}" --camera linemod --frames "$frames" --seed 1 --out "$work/synth"
  t1=$(date +%s.%N)
  dt=$(python3 -c "print($t1 - $t0)")
  times+=("$dt")
  echo "{\"tool\": \"synthgen\", \"repeat\": $r, \"frames\": $frames, \"seconds\": $dt, \"fps\": $(python3 -c "print(round($frames / $dt, 1))")}"
done
synth_fps=$(python3 -c "import statistics,sys; t=[float(x) for x in sys.argv[1:]]; print(round($frames / statistics.median(t), 1))" "${times[@]}")
du_mb=$(du -sm "$work/synth" | cut -f1)

peer_json=""
if [ -x benches/peers/.venv/bin/python ]; then
  peer_frames=$(( frames < 100 ? frames : 100 ))
  peer_json=$(PYOPENGL_PLATFORM=osmesa benches/peers/.venv/bin/python benches/peers/pyrender_bop.py \
    --bop "$work/synth" --frames "$peer_frames" --repeats 3 --out "$work/peer" | tail -n 1)
  echo "$peer_json"
else
  echo "pyrender peer skipped: run benches/peers/setup_pyrender.sh first" >&2
fi

python3 - "$synth_fps" "$du_mb" "$peer_json" <<'PY'
import json, sys
synth_fps, du_mb, peer = float(sys.argv[1]), sys.argv[2], sys.argv[3]
print(f"synthgen render to disk (median): {synth_fps} frames/s, dataset {du_mb} MB")
if peer:
    p = json.loads(peer)
    print(f"pyrender write_fps (median): {p['write_fps']} frames/s -> ratio {synth_fps / p['write_fps']:.1f}x")
    print(f"pyrender render_fps_with_alone (median): {p['render_fps_with_alone']} frames/s")
PY
