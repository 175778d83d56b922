#!/usr/bin/env bash
# Score a BOP results CSV with bop_toolkit's scripts/eval_bop19_pose.py (VSD, MSSD, MSPD and
# their average recall) using its default renderer, vispy, headless on EGL/Mesa.
# Set the venv up first with benches/peers/bop_toolkit_setup.sh.
#
#   BOP_TOOLKIT=/path/to/bop_toolkit bash benches/peers/run_bop_toolkit.sh \
#       DATASETS_ROOT DATASET RESULTS_CSV EVAL_DIR
#
#   DATASETS_ROOT  folder holding DATASET/ (camera.json, models_eval/ with models_info.json,
#                  SPLIT/SCENE/..., and the targets file); DATASET must be a name that
#                  bop_toolkit's dataset_params.py knows (lm, lmo, tless, ycbv, ...)
#   RESULTS_CSV    BOP results CSV (scene_id,im_id,obj_id,score,R,t,time), any file name
#   EVAL_DIR       where the errors, matches and scores go
#
# Environment:
#   BOP_TOOLKIT      bop_toolkit checkout (required)
#   BOPTK_VENV       venv (default: ~/.cache/synthgen/bop_toolkit-venv)
#   BOP_SPLIT        dataset split (default: test)
#   BOP_METHOD       method name in the result file name (default: synthgen)
#   BOP_TARGETS      targets file inside DATASETS_ROOT/DATASET (default: test_targets_bop19.json)
#   BOP_NUM_WORKERS  parallel workers (default: the number of CPUs)
#
# Prints (stdout) the path of scores_bop19.json and the wall time in seconds; the toolkit's
# own log goes to EVAL_DIR/bop_toolkit.log.
set -euo pipefail

if [ $# -ne 4 ]; then
    sed -n '6,7p' "$0" >&2
    exit 2
fi
: "${BOP_TOOLKIT:?set BOP_TOOLKIT to a bop_toolkit checkout (see bop_toolkit_setup.sh)}"
datasets="$(cd "$1" && pwd)"
dataset="$2"
csv="$(cd "$(dirname "$3")" && pwd)/$(basename "$3")"
mkdir -p "$4"
eval_dir="$(cd "$4" && pwd)"
venv="${BOPTK_VENV:-$HOME/.cache/synthgen/bop_toolkit-venv}"
split="${BOP_SPLIT:-test}"
method="${BOP_METHOD:-synthgen}"

# bop_toolkit reads method, dataset and split from the result file name,
# METHOD_DATASET-SPLIT.csv (METHOD without '_', '-' or '.'), so link the CSV under one.
name="${method}_${dataset}-${split}"
mkdir -p "$eval_dir/results"
ln -sf "$csv" "$eval_dir/results/$name.csv"
rm -rf "${eval_dir:?}/$name"   # no stale error/score files from an earlier run

# The eval script spawns its sub-steps as a bare `python`, so the venv must come first on
# PATH. Dataset location comes only from BOP_PATH (there is no command-line flag for it).
# EGL_PLATFORM=surfaceless lets Mesa's EGL start without a display.
export PATH="$venv/bin:$PATH" BOP_PATH="$datasets" EGL_PLATFORM=surfaceless \
    PYOPENGL_PLATFORM=egl
workers="${BOP_NUM_WORKERS:-$(nproc)}"

t0=$(date +%s.%N)
python "$BOP_TOOLKIT/scripts/eval_bop19_pose.py" \
    --renderer_type=vispy \
    --result_filenames="$name.csv" \
    --results_path="$eval_dir/results" \
    --eval_path="$eval_dir" \
    --targets_filename="${BOP_TARGETS:-test_targets_bop19.json}" \
    --num_workers="$workers" \
    >"$eval_dir/bop_toolkit.log" 2>&1 ||
    { tail -n 20 "$eval_dir/bop_toolkit.log" >&2; exit 1; }
t1=$(date +%s.%N)

scores="$eval_dir/$name/scores_bop19.json"
# With several workers a failed scoring step is only logged; the missing file tells.
[ -f "$scores" ] || { echo "no $scores; see $eval_dir/bop_toolkit.log" >&2; exit 1; }
echo "scores: $scores"
echo "wall_s: $(awk -v a="$t0" -v b="$t1" 'BEGIN { printf "%.2f", b - a }')"
