#!/usr/bin/env bash
# Leave-one-scene-out check of `synthgen sensor fit` on real frames (docs/sensors.md):
# for each scene of REAL, fit the structured-light model on the other scenes, replay the
# held-out scene through the fitted model, through no sensor model and through the D455
# model, and compare each replay with the real frames of that scene. Prints one table per
# held-out scene (scaled aspects; lower = closer to the real camera) and writes the JSON
# reports to OUT.
#
#   bash scripts/sensor_loso.sh [REAL] [OUT]
#   (defaults: ../shared/data/ycbv_real, /tmp/sensor_loso)
set -euo pipefail
REAL=${1:-../shared/data/ycbv_real}
OUT=${2:-/tmp/sensor_loso}
SG=${SYNTHGEN:-target/release/synthgen}
[ -x "$SG" ] || SG=target/debug/synthgen
rm -rf "$OUT"
mkdir -p "$OUT"
SCENES=$(ls "$REAL/data" | sed 's/^0*//; s/^$/0/' | sort -n | tr '\n' ' ')
for held in $SCENES; do
  train=$(echo $SCENES | tr ' ' '\n' | grep -vx "$held" | paste -sd, -)
  d="$OUT/held_$held"
  mkdir -p "$d"
  "$SG" -q sensor fit --data "$REAL" --scenes "$train" --out "$d/fitted.toml" --json \
    > "$d/fit.json" 2>/dev/null
  for s in fitted none d455; do
    sensor=$s
    [ "$s" = fitted ] && sensor="$d/fitted.toml"
    "$SG" -q render --replay "$REAL" --scenes "$held" --sensor "$sensor" --seed 1 \
      --out "$d/replay_$s" 2>/dev/null
    "$SG" -q sensor compare --real "$REAL" --synth "$d/replay_$s" --scenes "$held" --json \
      > "$d/compare_$s.json" 2>/dev/null
  done
done
python3 - "$OUT" $SCENES <<'PY'
import json, sys
out, scenes = sys.argv[1], sys.argv[2:]
models = ["fitted", "none", "d455"]
for held in scenes:
    rows = {m: json.load(open(f"{out}/held_{held}/compare_{m}.json")) for m in models}
    names = [a["name"] for a in rows["fitted"]["aspects"]]
    print(f"held-out scene {held} (fit on the others)")
    print(f"  {'aspect':<22}" + "".join(f"{m:>10}" for m in models) + "   fitted closest")
    for n in names:
        vals = {}
        for m in models:
            a = next(a for a in rows[m]["aspects"] if a["name"] == n)
            vals[m] = (a["value"] / a["scale"], a["scored"])
        scored = vals["fitted"][1]
        best = all(vals["fitted"][0] < vals[m][0] for m in models if m != "fitted")
        mark = ("yes" if best else "NO") if scored else "(not scored)"
        print(f"  {n:<22}" + "".join(f"{vals[m][0]:>10.3f}" for m in models) + f"   {mark}")
    print(f"  {'score':<22}" + "".join(f"{rows[m]['score']:>10.3f}" for m in models))
PY
