#!/usr/bin/env bash
# Records the losses of short trainings of every model (tnet, rnet, full, rgb, rgb-dense and
# the detector) into before.json, for tests/cli/training_threads.rs: the losses a training
# reached before the multi-threaded training (issue 51), which it must reproduce within
# floating-point reordering. Run with the synthgen binary of the commit before that change:
#
#   SYNTHGEN=/path/to/old/synthgen bash crates/synthgen-cli/tests/data/training/record.sh
#
# The commands are those of the test (its `COMMANDS`); keep the two in step.
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
repo=$(cd "$here/../../../../.." && pwd)
synthgen=${SYNTHGEN:?set SYNTHGEN to the synthgen binary to record}
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
cd "$work"
mesh="$repo/datasets/meshes/driller.ply"
"$synthgen" render -q --objects "$mesh" "$mesh" --obj-ids 8,9 --frames 12 --seed 3 \
    --image-size 320,240 --out set
common="-q --data set --epochs 2 --batch 4 --seed 1 --val-fraction 0.25 --jobs 1"
"$synthgen" train $common --model tnet --points 64 --width 16 --out tnet
"$synthgen" train $common --model rnet --points 64 --width 16 --crop-size 16 --out rnet
"$synthgen" train $common --model full --points 64 --width 16 --crop-size 16 --loss-points 20 --out full
# RNet's and Full's colour CNN sums its gradients in another order since issue 51 (candle's
# NCHW conv2d → the fused NHWC convolution); the test compares where these trainings end.
"$synthgen" train ${common/--epochs 2/--epochs 8} --model rnet --points 64 --width 16 --crop-size 16 --out rnet_8
"$synthgen" train ${common/--epochs 2/--epochs 8} --model full --points 64 --width 16 --crop-size 16 --loss-points 20 --out full_8
"$synthgen" train $common --model rgb --width 16 --crop-size 16 --out rgb
"$synthgen" train $common --model rgb-dense --width 16 --crop-size 16 --out rgb-dense
"$synthgen" detector train -q --data set --epochs 2 --batch 4 --seed 5 --val-fraction 0.25 \
    --input 64x48 --jobs 1 --out detector
python3 - "$here/before.json" <<'PY'
import json, sys
out = {}
for run in ["tnet", "rnet", "full", "rgb", "rgb-dense", "detector", "rnet_8", "full_8"]:
    lines = [json.loads(l) for l in open(f"{run}/metrics.jsonl") if l.strip()]
    out[run] = [[l["train_loss"], l["val_loss"]] for l in lines]
json.dump(out, open(sys.argv[1], "w"), indent=1)
PY
echo "wrote $here/before.json"
