#!/usr/bin/env python3
"""compare-outputs.py A B: compares two output trees file by file (what scripts/same-outputs.sh
wrote). JSON and JSON-lines files are compared with their timing fields left out, the
experiments' tables with their time column left out; every other file byte for byte. Logs are
not compared (their order and timings change). Exit 1 when a file differs or is missing."""

import json
import os
import re
import sys

TIMING = re.compile(
    r"(seconds|elapsed|wall|_s$|time|duration|frames_per_s|created|date|"
    r"^mix$|^load$|^train$|^eval$|^total$|^render$|^fit$)"
)


def scrub(v):
    if isinstance(v, dict):
        return {k: scrub(x) for k, x in v.items() if not TIMING.search(k)}
    if isinstance(v, list):
        return [scrub(x) for x in v]
    return v


def norm(path: str):
    data = open(path, "rb").read()
    name = os.path.basename(path)
    if path.endswith(".json"):
        try:
            return scrub(json.loads(data))
        except ValueError:
            return data
    if path.endswith(".jsonl"):
        try:
            return [scrub(json.loads(line)) for line in data.splitlines() if line.strip()]
        except ValueError:
            return data
    text = data.decode("utf-8", "replace")
    if name in ("table.csv",):  # experiment mix: the minutes column
        return [",".join(r.split(",")[:12] + r.split(",")[13:]) for r in text.splitlines()]
    if name in ("table.md", "report.md"):  # time columns and the wall-time line
        return [
            re.sub(r"\| [0-9.]+ \|$", "|", line)
            for line in text.splitlines()
            if not line.startswith("Wall time")
        ]
    return data


def files(root: str) -> set:
    return {
        os.path.relpath(os.path.join(d, f), root)
        for d, _, fs in os.walk(root)
        for f in fs
        if f != "log.txt"
    }


def main() -> int:
    a, b = sys.argv[1:3]
    fa, fb = files(a), files(b)
    bad = 0
    for f in sorted(fa ^ fb):
        print("only in one:", f)
        bad += 1
    for f in sorted(fa & fb):
        if norm(os.path.join(a, f)) != norm(os.path.join(b, f)):
            print("differs:", f)
            bad += 1
    print(f"{len(fa & fb)} files compared, {bad} differ")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
