#!/usr/bin/env bash
# Every model's training step, candle against its PyTorch peer, at 1 and 2 threads, in one
# run (docs/benchmarks.md, "Training steps: every model against PyTorch", issue 51).
#
#   sh benches/peers/setup_torch.sh              # once: torch into benches/peers/.venv-torch
#   bash benches/training_steps.sh [ROUNDS] [THREADS...]   # default: 2 rounds, threads 1 2
#
# Per round, model and thread count: the candle bench of the network's step on a prepared
# batch (criterion, its median) and the peer's median step (30 steps after 5 of warm-up),
# alternated. Prints one markdown row per (model, threads, round) and the load average before
# each round; run it on an otherwise idle machine. The candle side is built once first.
set -euo pipefail
cd "$(dirname "$0")/.."
rounds=${1:-2}
shift || true
threads=("${@:-1 2}")
read -r -a threads <<<"${threads[*]}"
py=benches/peers/.venv-torch/bin/python
[ -x "$py" ] || { echo "no torch venv: sh benches/peers/setup_torch.sh" >&2; exit 1; }
cargo bench -q -p synthgen-train -p synthgen-detect --no-run >/dev/null 2>&1

# model | candle package | bench | criterion id | peer script
models=(
  "tnet|synthgen-train|tnet_step_mimalloc|tnet_step_32x500_w128|tnet_torch.py"
  "rnet|synthgen-train|rnet_step|rnet_net_step_32x500_c48_w128|rnet_torch.py"
  "full|synthgen-train|full_step|full_net_step_32x500_c48_w128|full_torch.py"
  "rgb|synthgen-train|rgb_step|rgb_net_step_32x64_w256|rgb_torch.py"
  "rgb-dense|synthgen-train|rgb_dense_step|rgb_dense_net_step_32x64_w128|rgb_dense_torch.py"
  "detector|synthgen-detect|detector_step|detector_step_16x160x120_c8|detector_torch.py"
)

median_ms() { # criterion id -> its median, ms
  python3 -c "import json,sys; print(round(json.load(open('target/criterion/$1/new/estimates.json'))['median']['point_estimate']/1e6, 2))"
}

echo "| round | model | threads | candle ms | PyTorch ms | candle / PyTorch | load |"
echo "|---:|---|---:|---:|---:|---:|---|"
for r in $(seq 1 "$rounds"); do
  for m in "${models[@]}"; do
    IFS='|' read -r name pkg bench id peer <<<"$m"
    for t in "${threads[@]}"; do
      load=$(cut -d' ' -f1-3 /proc/loadavg)
      RAYON_NUM_THREADS=$t cargo bench -q -p "$pkg" --bench "$bench" -- \
        --warm-up-time 2 --measurement-time 8 "^${id}\$" >/dev/null 2>&1
      c=$(median_ms "$id")
      p=$("$py" -W ignore "benches/peers/$peer" --threads "$t" --steps 30 --warmup 5 2>/dev/null |
        python3 -c "import json,sys; print(round(json.loads(sys.stdin.read().strip().splitlines()[-1])['median_ms'], 2))")
      ratio=$(python3 -c "print(round($c/$p, 2))")
      echo "| $r | $name | $t | $c | $p | $ratio | $load |"
    done
  done
done
