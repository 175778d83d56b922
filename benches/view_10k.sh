#!/usr/bin/env bash
# Load times of `synthgen view` on a 10k-frame BOP dataset: start-up (indexing the
# annotations), the first grid page (its HTML, script, API call and 60 thumbnails, cold), and
# frame pages (HTML, API call, RGB, masks, contours, colour depth and raw depth, cold), each
# fetched over HTTP with 6 requests in flight as a browser does. Not run in CI.
#
#   bash benches/view_10k.sh            # SCENES=100 x FRAMES_PER_SCENE=100 frames
#
# The 10k frames are 100 scenes that share one rendered scene's images (symlinked folders) and
# carry their own copies of its annotations: what the viewer indexes and pages through is 10k
# frames, what it decodes per request is one real 640x480 frame. Environment: SYNTHGEN
# (default target/release/synthgen), SHARED (default ../shared/data), WORK.
set -euo pipefail
cd "$(dirname "$0")/.."
synthgen="$(realpath "${SYNTHGEN:-target/release/synthgen}")"
shared="$(realpath "${SHARED:-../shared/data}")"
work="${WORK:-/tmp/synthgen-view-10k}"
scenes="${SCENES:-100}"
per="${FRAMES_PER_SCENE:-100}"

rm -rf "$work" && mkdir -p "$work"
objects=""
for i in 01 05 06 08 09; do objects="$objects $shared/lmo/models/obj_0000$i.ply"; done
# shellcheck disable=SC2086
"$synthgen" render --objects $objects --camera linemod --frames "$per" --seed 3 --split test \
    --out "$work/base" 2>/dev/null
python3 - "$work" "$scenes" <<'PY'
import os, shutil, sys
work, scenes = sys.argv[1], int(sys.argv[2])
base, ds = os.path.join(work, "base"), os.path.join(work, "ds")
os.makedirs(os.path.join(ds, "test"))
shutil.copy(os.path.join(base, "camera.json"), ds)
os.symlink(os.path.join(base, "models"), os.path.join(ds, "models"))
src = os.path.join(base, "test", "000000")
for s in range(scenes):
    d = os.path.join(ds, "test", f"{s:06d}")
    os.makedirs(d)
    for name in os.listdir(src):
        p = os.path.join(src, name)
        if os.path.isdir(p):
            os.symlink(p, os.path.join(d, name))
        else:
            shutil.copy(p, d)
PY
t0=$(date +%s.%N)
"$synthgen" view "$work/ds" --port 0 >"$work/url.txt" 2>"$work/view.log" &
pid=$!
trap 'kill $pid 2>/dev/null' EXIT
while [ ! -s "$work/url.txt" ]; do sleep 0.05; done
t1=$(date +%s.%N)
url="$(head -n1 "$work/url.txt")"
echo "start-up (index $((scenes * per)) frames, serve): $(awk -v a="$t0" -v b="$t1" 'BEGIN { printf "%.2f", b - a }') s"
python3 - "$url" <<'PY'
import json, statistics, sys, time, urllib.request
from concurrent.futures import ThreadPoolExecutor
url = sys.argv[1].rstrip("/")
get = lambda p: urllib.request.urlopen(url + p).read()
pool = ThreadPoolExecutor(6)
def page(paths, first=()):
    t = time.perf_counter()
    out = [get(p) for p in first]
    list(pool.map(get, paths))
    return time.perf_counter() - t, out
frames = json.loads(get("/api/frames?ds=0&page=0"))
total = frames["total"]
grid = []
for pg in (0, 50, 100, 150, 160):
    t, (_, _, _, body) = page([], ["/", "/app.js", "/style.css", f"/api/frames?ds=0&page={pg}"])
    ids = [f["idx"] for f in json.loads(body)["frames"]]
    t2, _ = page([f"/img/0/{i}/thumb" for i in ids])
    grid.append(t + t2)
fp = []
for idx in (7, 1234, 5678, 9001, 9999):
    kinds = ["rgb", "masks", "contours", "depth", "depth.raw"]
    t, _ = page([f"/img/0/{idx}/{k}" for k in kinds], ["/frame", f"/api/frame/0/{idx}"])
    fp.append(t)
print(f"frames: {total}")
print("grid page, cold (60 thumbnails): median %.0f ms (each: %s)" % (1000 * statistics.median(grid), ", ".join("%.0f" % (1000 * g) for g in grid)))
print("frame page, cold (all layers): median %.0f ms (each: %s)" % (1000 * statistics.median(fp), ", ".join("%.0f" % (1000 * f) for f in fp)))
PY
