#!/usr/bin/env bash
# Issue 7's ablation: which knob of the synthetic scene moves the all-synthetic row of
# `synthgen experiment mix` closest to the all-real row.
#
#   bash benches/mix_ablation.sh OUT [EPOCHS] [VARIANT...]   # VARIANT "none": only the table
#
# 1. OUT/main: the full 7-row table, proxy real set, synthetic side rendered from
#    scenes/robot_chest_d455.toml (the study's camera and viewpoints, D455 depth + RGB noise).
# 2. OUT/<variant>: only the 0/1500 row, the synthetic side rendered from a variant of that
#    preset, against the same proxy real set (OUT/main/sources/real_proxy, so the same
#    held-out test frames: the script checks the test-split hash).
# Prints one line per variant: test error (cm) and its gap to the all-real row. Each
# experiment keeps its own table.md/table.csv; re-running resumes (finished rows are kept).
set -euo pipefail
cd "$(dirname "$0")/.."
out=${1:?usage: bash benches/mix_ablation.sh OUT [EPOCHS] [VARIANT...]}
epochs=${2:-8}
shift $(( $# > 1 ? 2 : 1 ))
variants=("$@")
if [ ${#variants[@]} -eq 0 ]; then
  variants=(render_defaults no_sensor no_textures distractors physics)
fi
mkdir -p "$out/specs"
bin=target/release/synthgen
cargo build --release -q -p synthgen-cli
common=(--objects datasets/meshes/driller.ply --obj-ids 8 --total 1500 --epochs "$epochs" --seed 1)
base=scenes/robot_chest_d455.toml

/usr/bin/time -f "main: %e s wall, %P CPU, %M KB peak RSS" \
  "$bin" experiment mix --real-proxy --scene "$base" "${common[@]}" --out "$out/main"

# The variants: each changes one knob of the base preset.
spec_of() {
  local v=$1 f="$out/specs/$1.toml"
  case $v in
    render_defaults) echo "" ; return ;;  # no --scene: `synthgen render`'s defaults
    base) cp "$base" "$f" ;;
    no_sensor)  # clean depth and RGB: no D455 model
      sed -e 's/^depth = "d455"/depth = "none"/' -e '/^\[sensor.rgb\]/,$ s/^enabled = true/enabled = false/' \
        "$base" > "$f" ;;
    distractors)  # primitive clutter (boxes and spheres: the proxy's cylinders stay held out)
      { cat "$base"; printf '\n[distractors]\ncount = [0, 2]\nshapes = ["box", "sphere"]\nsize_m = [0.04, 0.1]\n'; } > "$f" ;;
    no_textures)  # plain procedural ground, no walls
      sed -e '/^texture_dir/d' -e '/^texture_scale_m/d' -e '/^\[walls\]/,/^$/d' "$base" > "$f" ;;
    physics)  # dropped and settled instead of placed upright
      sed 's/^orientation = "upright"/orientation = "upright"\nmode = "physics"/' "$base" > "$f" ;;
    *) [ -f "$v" ] || { echo "unknown variant $v (or not a file)" >&2; exit 1; }
       cp "$v" "$f"; v=$(basename "$v" .toml) ;;
  esac
  echo "$f"
}

row() {  # csv → "test_error_cm train_error_cm" of the row with REAL=$2
  awk -F, -v r="$2" 'NR > 1 && $1 == r { print $7, $5 }' "$1/table.csv"
}
hash_of() { grep -o '"test_split_hash": *"[0-9a-f]*"' "$1" | grep -o '[0-9a-f]\{16\}'; }

read -r real_test real_train < <(row "$out/main" 1500)
read -r synth_test synth_train < <(row "$out/main" 0)
main_hash=$(hash_of "$out/main/rows/r01500_s00000/row.json")
printf '%-18s %10s %10s %8s %s\n' variant test_cm train_cm vs_real test_split
printf '%-18s %10s %10s %8s %s\n' all-real "$real_test" "$real_train" "+0%" "$main_hash"
pct() { awk -v a="$1" -v b="$real_test" 'BEGIN { printf "%+.0f%%", 100 * (a / b - 1) }'; }
printf '%-18s %10s %10s %8s %s\n' base "$synth_test" "$synth_train" "$(pct "$synth_test")" "$main_hash"
for v in "${variants[@]}"; do
  [ "$v" = none ] && continue
  spec=$(spec_of "$v")
  name=$(basename "${spec:-$v}" .toml)
  scene=()
  [ -n "$spec" ] && scene=(--scene "$spec")
  "$bin" experiment mix --real "$out/main/sources/real_proxy" "${scene[@]}" "${common[@]}" \
    --ratios 0/1500 --test-count 300 --out "$out/$name" > "$out/$name.log" 2>&1 \
    || { echo "$name failed: see $out/$name.log" >&2; exit 1; }
  read -r t tr < <(row "$out/$name" 0)
  h=$(hash_of "$out/$name/rows/r00000_s01500/row.json")
  [ "$h" = "$main_hash" ] || { echo "$name: test split $h differs from main's $main_hash" >&2; exit 1; }
  printf '%-18s %10s %10s %8s %s\n' "$name" "$t" "$tr" "$(pct "$t")" "$h"
done
