#!/usr/bin/env bash
# Cycles (the blender backend) against the raster backend on the same sampled frames, and the
# process RSS over a long run. Needs scripts/setup-blender.sh first.
#   bash benches/blender_vs_raster.sh [FRAMES_16] [FRAMES_64] [RSS_FRAMES]
# Scene: the DESIGN.md one (640x480, Linemod camera, lmo objects 1 5 6 8 9, default spec).
set -euo pipefail
cd "$(dirname "$0")/.."
f16="${1:-8}"; f64="${2:-4}"; rss="${3:-500}"
lmo="${SYNTHGEN_SHARED_DATA:-../shared/data}/lmo/models"
[ -d "$lmo" ] || lmo=/work/shared/data/lmo/models
meshes=("$lmo"/obj_0000{01,05,06,08,09}.ply)
cargo build -q -p synthgen-blender --features blender --example blender_bench
bench=target/debug/examples/blender_bench  # the dev profile is optimized (opt-level 2-3)
quiet() { grep -v -e "Freeing memory" -e "Saved:" -e "Not freed memory" || true; }
echo "== 640x480, 16 samples"
"$bench" --samples 16 --frames "$f16" --size 640x480 "${meshes[@]}" 2>&1 | quiet
echo "== 640x480, 64 samples"
"$bench" --samples 64 --frames "$f64" --size 640x480 "${meshes[@]}" 2>&1 | quiet
echo "== RSS over $rss frames, 160x120, 4 samples"
"$bench" --samples 4 --frames "$rss" --size 160x120 --rss-every 50 "${meshes[@]}" 2>&1 | quiet
