#!/usr/bin/env python3
"""Checks the project's #include graph: no include cycle between files, and no library that
includes a header of a library above it (docs/design.md, "Layout": the arrows point one way).

Usage: .ci/include_graph.py [repository root]   (exit 1 with one line per problem)
"""
import os
import re
import sys

ROOT = os.path.abspath(sys.argv[1] if len(sys.argv) > 1 else os.path.join(os.path.dirname(__file__), ".."))
FOLDERS = ["stream", "bucket", "receivers", "procedural", "bake", "tools", "python", "fuzz"]
INCLUDE = re.compile(r'^\s*#\s*include\s+"([^"]+)"', re.M)

# Which top-level parts each part may include (its own files always).
ALLOWED = {
    "stream/util": set(),
    "stream": {"stream/util"},
    "procedural": {"stream", "stream/util"},
    "bucket": {"stream", "stream/util"},
    "receivers": {"stream", "stream/util"},
    "bake/rule": {"stream", "stream/util"},
    "bake/light": {"bake/rule", "stream", "stream/util"},
    "bake/shading": {"bake/light", "bake/rule", "receivers", "stream", "stream/util"},
    "bake/cast": {"bake/light", "bake/rule", "receivers", "stream", "stream/util"},
    "bake/peers": {"bake/cast", "bake/light", "bake/rule", "receivers", "stream", "stream/util"},
    "bake/methods": {"bake/cast", "bake/light", "bake/rule", "receivers", "stream", "stream/util"},
    "bake/shard": {"bake/cast", "bake/light", "bake/rule", "receivers", "stream", "stream/util"},
    "bake/output": {"bake/cast", "bake/light", "bake/rule", "receivers", "stream", "stream/util"},
}


def part_of(path):
    """The layout part a repository path belongs to (its library)."""
    parts = path.split("/")
    if parts[0] == "stream" and len(parts) > 2 and parts[1] == "util":
        return "stream/util"
    if parts[0] == "bake" and len(parts) > 2:
        return "bake/kinds" if parts[1] == "kinds" else "bake/" + parts[1]
    return parts[0]


def files():
    for folder in FOLDERS:
        for dirpath, _, names in os.walk(os.path.join(ROOT, folder)):
            for name in names:
                if name.endswith((".h", ".cpp")):
                    yield os.path.relpath(os.path.join(dirpath, name), ROOT)


def resolve(src, target):
    """The repository path of `#include "target"` in src (project-rooted, or beside src)."""
    for candidate in (target, os.path.normpath(os.path.join(os.path.dirname(src), target))):
        if os.path.isfile(os.path.join(ROOT, candidate)):
            return candidate
    return None


def main():
    graph = {}
    problems = []
    for f in files():
        with open(os.path.join(ROOT, f), encoding="utf-8", errors="replace") as text:
            targets = [resolve(f, t) for t in INCLUDE.findall(text.read())]
        graph[f] = [t for t in targets if t]
        allowed = ALLOWED.get(part_of(f))
        if allowed is None:
            continue
        for t in graph[f]:
            if part_of(t) != part_of(f) and part_of(t) not in allowed:
                problems.append(f"{f}: includes {t}, against the layout's arrows ({part_of(f)} -> {part_of(t)})")
    # Depth-first search for cycles, reported once each.
    state, stack, seen_cycles = {}, [], set()

    def visit(node):
        state[node] = 1
        stack.append(node)
        for nxt in graph.get(node, []):
            if state.get(nxt) == 1:
                cycle = stack[stack.index(nxt):]
                key = frozenset(cycle)
                if key not in seen_cycles:
                    seen_cycles.add(key)
                    problems.append("include cycle: " + " -> ".join(cycle + [nxt]))
            elif state.get(nxt) is None:
                visit(nxt)
        stack.pop()
        state[node] = 2

    sys.setrecursionlimit(10000)
    for node in sorted(graph):
        if state.get(node) is None:
            visit(node)
    for p in problems:
        print(p)
    print(f"{len(graph)} files, {sum(len(v) for v in graph.values())} project includes, {len(problems)} problem(s)",
          file=sys.stderr)
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
