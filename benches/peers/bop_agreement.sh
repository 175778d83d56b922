#!/usr/bin/env bash
# Compares `synthgen eval --bop` with bop_toolkit's eval_bop19_pose.py (vispy renderer) on the
# cases of bop_cases.py, and refreshes the expected scores the CLI tests check against
# (crates/synthgen-cli/tests/data/bop_toolkit/CASE/bop_toolkit.json). Not run in CI: it
# needs a bop_toolkit checkout and its venv (benches/peers/bop_toolkit_setup.sh).
#
#   BOP_TOOLKIT=/path/to/bop_toolkit bash benches/peers/bop_agreement.sh
#
# Environment: SYNTHGEN (default target/release/synthgen), SHARED (default ../shared/data),
# WORK (default /tmp/synthgen-bop-agreement), BOPTK_VENV (see run_bop_toolkit.sh).
set -euo pipefail
cd "$(dirname "$0")/../.."
: "${BOP_TOOLKIT:?set BOP_TOOLKIT to a bop_toolkit checkout (see bop_toolkit_setup.sh)}"
synthgen="$(realpath "${SYNTHGEN:-target/release/synthgen}")"
shared="$(realpath "${SHARED:-../shared/data}")"
work="${WORK:-/tmp/synthgen-bop-agreement}"
fixtures="crates/synthgen-cli/tests/data/bop_toolkit"
lmo="$shared/lmo"
ids="01 05 06 08 09 10 11 12"

rm -rf "$work" && mkdir -p "$work"
# The base scene: the command the CLI test runs too (tests/cli/bop_eval.rs).
objects=""
for i in $ids; do objects="$objects $lmo/models/obj_0000$i.ply"; done
# shellcheck disable=SC2086
"$synthgen" render --objects $objects --camera linemod --frames 10 --seed 1 --split test \
    --out "$work/base" 2>/dev/null
python3 benches/peers/bop_cases.py "$work/base/test/000000" "$lmo/models_eval/models_info.json" "$fixtures"

for case_dir in "$fixtures"/*/; do
    case="$(basename "$case_dir")"
    root="$work/$case/lmo"
    scene="$root/test/000002"
    mkdir -p "$scene" "$root/models_eval"
    cp "$work/base/camera.json" "$root/"
    ln -s "$work/base/models" "$root/models"
    for f in "$lmo"/models_eval/*.ply; do ln -s "$f" "$root/models_eval/"; done
    cp "$case_dir/models_info.json" "$root/models_eval/"
    cp "$case_dir/test_targets_bop19.json" "$root/"
    for d in rgb depth; do ln -s "$work/base/test/000000/$d" "$scene/$d"; done
    cp "$work/base/test/000000/scene_camera.json" "$scene/"
    cp "$case_dir/scene_gt.json" "$case_dir/scene_gt_info.json" "$scene/"

    out="$(bash benches/peers/run_bop_toolkit.sh "$work/$case" lmo "$case_dir/results.csv" "$work/$case/eval")"
    echo "$case: bop_toolkit $(echo "$out" | grep wall_s)"
    python3 - "$work/$case/eval/synthgen_lmo-test" "$case_dir/bop_toolkit.json" <<'PY'
import glob, json, os, re, sys
ev, out = sys.argv[1:3]
def curve(pattern):
    rec, obj = [], {}
    for f in glob.glob(os.path.join(ev, pattern, "scores_th=*.json")):
        th = float(re.search(r"th=([0-9.]+)_", os.path.basename(f)).group(1))
        s = json.load(open(f))
        rec.append((th, s["recall"]))
        for o, r in s["obj_recalls"].items():
            obj.setdefault(o, []).append(r)
    rec.sort()
    return [t for t, _ in rec], [r for _, r in rec], obj
res = {}
for err in ("mssd", "mspd"):
    th, rec, obj = curve(f"error={err}_ntop=-1")
    res[err] = {"thresholds": th, "recall_per_threshold": rec,
                "per_object_mean_recall": {o: sum(v) / len(v) for o, v in obj.items()}}
taus = sorted(glob.glob(os.path.join(ev, "error=vsd_ntop=-1_delta=15.000_tau=*")))
rows, obj_all = [], {}
for d in taus:
    th, rec, obj = curve(os.path.basename(d))
    rows.append(rec)
    for o, v in obj.items():
        obj_all.setdefault(o, []).extend(v)
res["vsd"] = {"thresholds": th, "recall_per_tau_threshold": rows,
              "per_object_mean_recall": {o: sum(v) / len(v) for o, v in obj_all.items()}}
final = json.load(open(os.path.join(ev, "scores_bop19.json")))
res["ar"] = final["bop19_average_recall"]
for e in ("vsd", "mssd", "mspd"):
    res[e]["mean_recall"] = final[f"bop19_average_recall_{e}"]
json.dump(res, open(out, "w"), indent=1, sort_keys=True)
PY
    t0=$(date +%s.%N)
    "$synthgen" eval --results "$case_dir/results.csv" --data "$root" --bop \
        --json "$work/$case/synthgen.json" >/dev/null 2>&1 || true
    t1=$(date +%s.%N)
    echo "$case: synthgen wall_s: $(awk -v a="$t0" -v b="$t1" 'BEGIN { printf "%.2f", b - a }')"
    python3 - "$case_dir/bop_toolkit.json" "$work/$case/synthgen.json" <<'PY'
import json, sys
want, got = json.load(open(sys.argv[1])), json.load(open(sys.argv[2]))["bop"]
diffs = [abs(want["ar"] - got["ar"])]
for e in ("vsd", "mssd", "mspd"):
    diffs.append(abs(want[e]["mean_recall"] - got[e]["mean_recall"]))
    w = want[e].get("recall_per_tau_threshold") or [want[e]["recall_per_threshold"]]
    g = got[e].get("recall_per_tau_threshold") or [got[e]["recall_per_threshold"]]
    diffs += [abs(a - b) for rw, rg in zip(w, g) for a, b in zip(rw, rg)]
    for o, v in got[e]["per_object_mean_recall"].items():
        diffs.append(abs(want[e]["per_object_mean_recall"][o] - v))
m = max(diffs)
print(f"  AR bop_toolkit {want['ar']!r} synthgen {got['ar']!r}; {len(diffs)} numbers, max |diff| {m:.3g}",
      "OK" if m <= 1e-6 else "DIFFERENT")
PY
done
