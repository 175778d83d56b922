#!/usr/bin/env bash
# `synthgen render` to disk for every preset in scenes/, five Linemod models, 640x480 BOP
# (rgb PNG, depth PNG, masks, JSON). The peers in the same run are tabletop with
# placement.mode = "sample" (no physics), so the cost of physics reads as a ratio, and
# tabletop without its image textures and walls (procedural ground, as before issue 6's
# backgrounds), so the cost of those reads as a ratio too.
#
#   bash benches/presets.sh [FRAMES] [REPEATS] [JOBS]
#
# Needs ../shared/data/lmo (or LMO=path/to/lmo). Prints one line per preset with the
# per-repeat frames/s and the median.
set -euo pipefail
cd "$(dirname "$0")/.."
frames=${1:-300}
repeats=${2:-3}
jobs=${3:-2}
lmo=${LMO:-../shared/data/lmo}
models=()
for id in 1 5 6 8 9; do models+=("$lmo/models/obj_$(printf %06d $id).ply"); done
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT

cargo build --release -q -p synthgen-cli
bin=target/release/synthgen
# Texture folders are relative to the spec file: the copies point at the repo's absolutely.
sed 's/^mode = "physics".*/mode = "sample"/; s|^texture_dir = "\.\./|texture_dir = "'"$PWD"'/|' \
  scenes/tabletop.toml > "$work/tabletop_no_physics.toml"
sed '/^texture_dir/d; s/^count = \[2, 4\]/count = [0, 0]/' scenes/tabletop.toml \
  > "$work/tabletop_plain_surfaces.toml"

specs=(scenes/tabletop.toml "$work/tabletop_no_physics.toml" "$work/tabletop_plain_surfaces.toml" \
  scenes/robot_chest_d455.toml \
  scenes/linemod_like.toml scenes/bin_picking.toml scenes/random_pose.toml)
for spec in "${specs[@]}"; do
  fps=()
  for r in $(seq 1 "$repeats"); do
    rm -rf "$work/out"
    t0=$(date +%s.%N)
    "$bin" render -q --scene "$spec" --objects "${models[@]}" --frames "$frames" --seed 1 \
      --jobs "$jobs" --out "$work/out"
    t1=$(date +%s.%N)
    fps+=("$(python3 -c "print(round($frames / ($t1 - $t0), 1))")")
  done
  med=$(python3 -c "import statistics,sys; print(statistics.median(float(x) for x in sys.argv[1:]))" "${fps[@]}")
  echo "$(basename "$spec" .toml): ${fps[*]} -> median $med frames/s ($frames frames, --jobs $jobs)"
done
