#!/usr/bin/env bash
# Runs N shard processes in parallel on this machine the way a Slurm job array or a
# Kubernetes Indexed Job would (one process per index, each with its own --out), merges
# them, renders the same frames in one process and checks the two datasets are identical.
#
#   scripts/run_shards_local.sh [N] [FRAMES] [WORKDIR]
#
# SYNTHGEN (default: target/debug/synthgen, built if missing) and MESH
# (default: datasets/meshes/driller.ply) can be overridden.
set -euo pipefail
N=${1:-4}
FRAMES=${2:-200}
WORK=${3:-$(mktemp -d)}
cd "$(dirname "$0")/.."
SYNTHGEN=${SYNTHGEN:-target/debug/synthgen}
MESH=${MESH:-datasets/meshes/driller.ply}
[ -x "$SYNTHGEN" ] || cargo build -q -p synthgen-cli
COMMON=(render -q --objects "$MESH" --frames "$FRAMES" --seed 7 --chunk-size 64
        --image-size 128,96 --jobs 1)

start=$(date +%s.%N)
pids=()
for ((i = 0; i < N; i++)); do
  # What the scheduler does: the same command, a different index.
  "$SYNTHGEN" "${COMMON[@]}" --shard "$i/$N" --out "$WORK/shard_$i" &
  pids+=($!)
done
for p in "${pids[@]}"; do wait "$p"; done
mid=$(date +%s.%N)
shards=()
for ((i = 0; i < N; i++)); do shards+=("$WORK/shard_$i"); done
"$SYNTHGEN" merge -q "${shards[@]}" --out "$WORK/merged"
end=$(date +%s.%N)

"$SYNTHGEN" "${COMMON[@]}" --out "$WORK/single"
single_end=$(date +%s.%N)

# Every file but the manifest byte-identical; the manifest equal but for the command line
# and the list of shards it was merged from.
diff -r -q -x synthgen.json "$WORK/single" "$WORK/merged"
python3 - "$WORK" <<'PY'
import json, sys
w = sys.argv[1]
a = json.load(open(f"{w}/single/synthgen.json"))
b = json.load(open(f"{w}/merged/synthgen.json"))
for m in (a, b):
    m.pop("command_line")
b["extra"].pop("merged_from")
assert a == b, "manifests differ"
PY
files=$(find "$WORK/merged" -type f | wc -l)
printf '%d shards x %d frames: shards %.2f s, merge %.2f s, single process %.2f s; %d files identical\n' \
  "$N" "$FRAMES" "$(echo "$mid - $start" | bc)" "$(echo "$end - $mid" | bc)" \
  "$(echo "$single_end - $end" | bc)" "$files"
echo "OK: merged shards == single run ($WORK)"
