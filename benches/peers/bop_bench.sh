#!/usr/bin/env bash
# End-to-end timing of BOP 2019 scoring (VSD, MSSD, MSPD, AR): `synthgen eval --bop` against
# bop_toolkit's eval_bop19_pose.py with its default renderer (vispy; Mesa llvmpipe when there
# is no GPU), on the same results CSV and dataset, on this machine, in one run. Not run in CI.
#
#   BOP_TOOLKIT=/path/to/bop_toolkit bash benches/peers/bop_bench.sh [FRAMES] [REPEATS]
#
# FRAMES (default 100) frames of the eight Linemod-Occluded objects are rendered by synthgen
# into a BOP dataset named lmo; every GT pose, perturbed, is an estimate (bop_cases.py's
# "perturbed" case). Each tool scores it REPEATS times (default 3); medians are printed.
# Environment: SYNTHGEN (default target/release/synthgen), SHARED (default ../shared/data),
# WORK (default /tmp/synthgen-bop-bench), BOPTK_VENV, BOP_NUM_WORKERS (see run_bop_toolkit.sh).
set -euo pipefail
cd "$(dirname "$0")/../.."
: "${BOP_TOOLKIT:?set BOP_TOOLKIT to a bop_toolkit checkout (see bop_toolkit_setup.sh)}"
frames="${1:-100}"
repeats="${2:-3}"
synthgen="$(realpath "${SYNTHGEN:-target/release/synthgen}")"
shared="$(realpath "${SHARED:-../shared/data}")"
work="${WORK:-/tmp/synthgen-bop-bench}"
lmo="$shared/lmo"

rm -rf "$work" && mkdir -p "$work"
objects=""
for i in 01 05 06 08 09 10 11 12; do objects="$objects $lmo/models/obj_0000$i.ply"; done
# shellcheck disable=SC2086
"$synthgen" render --objects $objects --camera linemod --frames "$frames" --seed 7 \
    --split test --out "$work/base" 2>/dev/null
python3 benches/peers/bop_cases.py "$work/base/test/000000" "$lmo/models_eval/models_info.json" \
    "$work/cases" >/dev/null
case_dir="$work/cases/perturbed"
root="$work/data/lmo"
scene="$root/test/000002"
mkdir -p "$root/models_eval" "$root/test"
mv "$work/base/test/000000" "$scene"
ln -s "$work/base/models" "$root/models"
cp "$work/base/camera.json" "$root/"
for f in "$lmo"/models_eval/*; do ln -s "$f" "$root/models_eval/"; done
cp "$case_dir/test_targets_bop19.json" "$root/"
estimates=$(($(wc -l <"$case_dir/results.csv") - 1))

median() { sort -g | awk '{ v[NR] = $1 } END { print (NR % 2) ? v[(NR + 1) / 2] : (v[NR / 2] + v[NR / 2 + 1]) / 2 }'; }
ours=() theirs=()
for r in $(seq "$repeats"); do
    t0=$(date +%s.%N)
    "$synthgen" eval --results "$case_dir/results.csv" --data "$root" --bop \
        --json "$work/synthgen.json" >/dev/null 2>&1
    t1=$(date +%s.%N)
    ours+=("$(awk -v a="$t0" -v b="$t1" 'BEGIN { printf "%.3f", b - a }')")
    out="$(bash benches/peers/run_bop_toolkit.sh "$work/data" lmo "$case_dir/results.csv" "$work/eval")"
    theirs+=("$(echo "$out" | sed -n 's/^wall_s: //p')")
    echo "run $r: synthgen ${ours[-1]} s, bop_toolkit ${theirs[-1]} s" >&2
done
m_ours=$(printf '%s\n' "${ours[@]}" | median)
m_theirs=$(printf '%s\n' "${theirs[@]}" | median)
python3 - "$work/synthgen.json" "$work/eval/synthgen_lmo-test/scores_bop19.json" <<PY
import json, sys
ours = json.load(open(sys.argv[1]))["bop"]
theirs = json.load(open(sys.argv[2]))
print(f"frames: $frames, estimates: $estimates, cores: $(nproc)")
print(f"synthgen eval --bop   median {float('$m_ours'):8.2f} s  AR {ours['ar']:.6f}")
print(f"bop_toolkit (vispy)   median {float('$m_theirs'):8.2f} s  AR {theirs['bop19_average_recall']:.6f}")
print(f"speed-up: {float('$m_theirs') / float('$m_ours'):.1f}x")
PY
