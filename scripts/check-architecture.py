#!/usr/bin/env python3
"""The layout rules of docs/ARCHITECTURE.md, checked (issue 30):

1. No import circle between sibling modules of a crate: in every folder of `src/`, the
   modules side by side (a file, or a folder with everything in it) import each other, through
   `crate::`, `super::` or `self::` paths, without a circle. A module and its own submodules
   are one room (children may use what their parent defines, the parent what they export),
   and a file's `#[cfg(test)]` test module is left out (unit tests may use any module of their
   crate).
2. No crate above 10,000 lines of Rust under its `src/` (tests in the files included).

Usage: scripts/check-architecture.py [CRATES_DIR]   (default: crates/ beside this script)
Exit 0 when both hold; 1 with every circle and oversized crate listed."""

from __future__ import annotations

import os
import re
import sys
from collections import defaultdict
from typing import Dict, List, Optional, Set, Tuple

MAX_LINES = 10_000
Module = Tuple[str, ...]


def module_of(src: str, path: str) -> Module:
    parts = os.path.relpath(path, src)[:-3].split(os.sep)
    if parts[-1] in ("mod", "lib", "main"):
        parts = parts[:-1]
    return tuple(parts)


def code_of(path: str) -> str:
    text = open(path, encoding="utf-8").read()
    # The file's unit-test module (by convention the last item, `#[cfg(test)] mod tests`).
    m = re.search(r"^#\[cfg\(test\)\]\n(?:#\[[^\n]*\]\n)*mod \w+ \{", text, re.M)
    if m:
        text = text[: m.start()]
    return "\n".join(line for line in text.split("\n") if not line.lstrip().startswith("//"))


def imports(code: str, me: Module, resolve) -> Set[Module]:
    out: Set[Module] = set()
    for m in re.finditer(r"\b(crate|super|self)((?:::\w+)+|::\{[^}]*\})", code):
        kind, rest = m.group(1), m.group(2)
        if rest.startswith("::{"):
            paths = [p.strip().split("::") for p in rest[3:-1].split(",") if p.strip()]
        else:
            paths = [rest[2:].split("::")]
        base = () if kind == "crate" else (me[:-1] if kind == "super" else me)
        for p in paths:
            target = resolve(list(base) + [x for x in p if x != "self"])
            if target is not None and target != me:
                out.add(target)
    return out


def circles(graph: Dict[Module, Set[Module]], nodes: List[Module]) -> List[List[Module]]:
    """Strongly connected components with more than one module (Tarjan)."""
    index: Dict[Module, int] = {}
    low: Dict[Module, int] = {}
    stack: List[Module] = []
    on: Set[Module] = set()
    found: List[List[Module]] = []
    counter = [0]
    sys.setrecursionlimit(100_000)

    def visit(v: Module) -> None:
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on.add(v)
        for w in sorted(graph[v]):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                found.append(sorted(comp))

    for v in nodes:
        if v not in index:
            visit(v)
    return found


def main() -> int:
    here = os.path.dirname(os.path.abspath(__file__))
    root = sys.argv[1] if len(sys.argv) > 1 else os.path.join(here, "..", "crates")
    problems = 0
    for crate in sorted(os.listdir(root)):
        src = os.path.join(root, crate, "src")
        if not os.path.isdir(src):
            continue
        files = sorted(
            os.path.join(d, f) for d, _, fs in os.walk(src) for f in fs if f.endswith(".rs")
        )
        lines = sum(sum(1 for _ in open(f, encoding="utf-8")) for f in files)
        if lines > MAX_LINES:
            print(f"{crate}: {lines} lines of Rust in src/ (at most {MAX_LINES})")
            problems += 1
        mods = {module_of(src, f): f for f in files}

        def resolve(path: List[str]) -> Optional[Module]:
            for n in range(len(path), 0, -1):
                if tuple(path[:n]) in mods:
                    return tuple(path[:n])
            return None

        # Per folder, the graph of its sibling modules: an edge a -> b between files becomes an
        # edge between the siblings that hold them below their common folder (none when one is
        # the other's ancestor).
        graph: Dict[Module, Set[Module]] = defaultdict(set)
        nodes: Set[Module] = set()
        for a, f in mods.items():
            nodes.add(a)
            for b in imports(code_of(f), a, resolve):
                n = 0
                while n < min(len(a), len(b)) and a[n] == b[n]:
                    n += 1
                if n == len(a) or n == len(b):
                    continue
                ua, ub = a[: n + 1], b[: n + 1]
                graph[ua].add(ub)
                nodes.update((ua, ub))
        for comp in circles(graph, sorted(nodes)):
            names = ["::".join(m) or "<crate root>" for m in comp]
            edges = [
                f"{'::'.join(a) or '<root>'} -> {'::'.join(b) or '<root>'}"
                for a in comp
                for b in sorted(graph[a])
                if b in comp
            ]
            print(f"{crate}: import circle between {', '.join(names)}: {'; '.join(edges)}")
            problems += 1
    if problems:
        print(f"{problems} problem(s); see docs/ARCHITECTURE.md")
        return 1
    print("architecture: no import circle, every crate under 10000 lines")
    return 0


if __name__ == "__main__":
    sys.exit(main())
