#!/bin/bash
# Renders, converts, mixes, fits, replays, trains, evaluates and runs the quick experiments with
# two synthgen binaries into the same paths, and compares every file they wrote (timing fields
# aside): what a change that should not change outputs (issue 30's rearrangement) must pass.
#
#   scripts/same-outputs.sh BEFORE_BIN AFTER_BIN [WORK_DIR]
#
# ../shared/data must lie beside the repository. Exit 0 when every file is the same.
set -u
before=$(realpath "$1"); after=$(realpath "$2"); work=$(realpath -m "${3:-/tmp/synthgen-same-outputs}")
cd "$(dirname "$0")/.."
S=$(realpath ../shared/data); R=$S/ycbv_real; M=$S/lmo/models
run_set() { # BIN OUT
  local B=$1 O=$2
  rm -rf "$O"; mkdir -p "$O"
  run() { echo "== ${*#$B}" >> "$O/log.txt"; "$@" >> "$O/log.txt" 2>&1; echo "rc=$?" >> "$O/log.txt"; }
  run $B render --objects $M/obj_000001.ply $M/obj_000005.ply --frames 6 --seed 3 -q --out $O/r_bop
  run $B render --objects $M/obj_000001.ply $M/obj_000005.ply --frames 6 --seed 3 -q --format linemod --out $O/r_lm
  run $B render --objects $M/obj_000001.ply $M/obj_000005.ply --frames 6 --seed 3 -q --format ycbv --out $O/r_ycbv
  run $B render --scene scenes/ycbv_like.toml --objects $M/obj_000008.ply --frames 4 --seed 1 -q --out $O/r_scene
  run $B convert --to bop -q $R $O/c_bop
  run $B convert --to ycbv -q $O/c_bop $O/c_ycbv
  run $B convert --to linemod -q $O/r_bop $O/c_lm
  run $B mix --real $O/c_bop --synth $O/r_bop --real-count 20 --synth-count 4 --seed 2 -q --out $O/mix
  run $B sensor fit --data $R --out $O/sensor.toml
  run $B scene fit --data $R --scenes 0,1 --out $O/scene.toml
  run $B render --replay $R -q --out $O/rp_bop
  run $B render --replay $R --sensor d455 --format ycbv -q --out $O/rp_ycbv
  run $B render --replay $S/lmo --replay-lit --format linemod -q --out $O/rp_lm
  run $B annotate --compare $R --report $O/annotate.json --overlay $O/overlays --overlay-count 3
  cp -r $O/r_bop $O/ann_bop && rm -rf $O/ann_bop/train_pbr/*/mask* $O/ann_bop/train_pbr/*/scene_gt_info.json
  run $B annotate $O/ann_bop
  run $B model align --scans $S/ycb_textured --to-dataset $R --json --out $O/aligned
  run $B model align --scan $S/ycb_textured/011_banana/textured.obj --to $R/models/011_banana/textured_simple.obj --out $O/aligned_one
  run $B model align --scan $S/ycb_textured/011_banana/textured.obj --to $R/models/006_mustard_bottle/textured_simple.obj --json --out $O/aligned_bad
  run $B train --data $O/r_bop --model tnet --epochs 2 --batch 4 --points 64 --width 16 --seed 1 -q --out $O/t_tnet
  run $B train --data $O/r_bop --model tnet --epochs 3 --batch 4 --points 64 --width 16 --seed 1 -q --resume --out $O/t_tnet
  run $B train --data $O/r_bop --model rgb-dense --epochs 1 --batch 4 --width 16 --seed 2 -q --out $O/t_dense
  run $B eval --data $O/r_bop --checkpoint $O/t_tnet/model.safetensors --json $O/e_tnet.json
  run $B eval --data $O/r_bop --checkpoint $O/t_dense/model.safetensors --save-results $O/res.csv
  run $B eval --data $O/r_bop --results $O/res.csv --bop --json $O/e_res.json
  run $B experiment mix --real-proxy --objects $M/obj_000008.ply --quick --out $O/xmix
  run $B experiment mix --real $R --test-scenes 0 --total 20 --quick --out $O/xmixr
  run $B experiment sim2real --fit $R --test $R --test-scenes 2 --quick --out $O/xs2r
  run $B experiment sim2real --model rgb-dense --scene scenes/linemod_rgb.toml --test $S/lmo --quick --rows synth_plain,naive_box --out $O/xrgb
}
# Both binaries run from the same path: the manifests record the command line.
mkdir -p "$work/bin"
cp "$before" "$work/bin/synthgen" && run_set "$work/bin/synthgen" "$work/out" && mv "$work/out" "$work/before.tmp"
cp "$after" "$work/bin/synthgen" && run_set "$work/bin/synthgen" "$work/out" && mv "$work/out" "$work/after.tmp"
rm -rf "$work/before" "$work/after"; mv "$work/before.tmp" "$work/before"; mv "$work/after.tmp" "$work/after"
python3 scripts/compare-outputs.py "$work/before" "$work/after"
