#!/usr/bin/env python3
"""Print the crate's top-level module graph (which module names which through `crate::`) and its
cycles; exit 1 if there is one. A step towards the workspace of issue 43, whose crates the
compiler keeps acyclic: a module cycle here is a crate split that would not compile yet.

    python3 scripts/module_graph.py          # the cycles only
    python3 scripts/module_graph.py --edges  # and every edge
"""
import collections
import os
import re
import sys

SRC = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "src")


def strip(text):
    """The code without comments, string literals and the unit tests (they may reach anywhere)."""
    text = text.split("#[cfg(test)]\nmod tests")[0]
    text = re.sub(r"//[^\n]*", "", text)
    return re.sub(r'"(?:\\.|[^"\\])*"', '""', text)


def graph():
    g = collections.defaultdict(set)
    for root, _, files in os.walk(SRC):
        for f in files:
            if not f.endswith(".rs"):
                continue
            path = os.path.join(root, f)
            rel = os.path.relpath(path, SRC).split(os.sep)
            module = rel[0][:-3] if len(rel) == 1 else rel[0]
            if module in ("lib", "main"):
                continue
            code = strip(open(path, encoding="utf-8").read())
            names = set(re.findall(r"crate::(\w+)", code))
            for group in re.findall(r"crate::\{([^}]*)\}", code, re.S):
                names |= set(re.findall(r"(?:^|,)\s*(\w+)", group))
            g[module] |= names - {module}
            g[module]  # a module naming nothing is still a node
    return g


def cycles(g):
    """Strongly connected components of more than one module (Tarjan)."""
    index, low, stack, on, out = {}, {}, [], set(), []
    counter = [0]

    def visit(v):
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on.add(v)
        for w in sorted(g.get(v, ())):
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
                out.append(sorted(comp))

    sys.setrecursionlimit(10000)
    for v in sorted(g):
        if v not in index:
            visit(v)
    return out


def main():
    g = graph()
    if "--edges" in sys.argv:
        for m in sorted(g):
            print(f"{m} -> {', '.join(sorted(g[m])) or '(nothing)'}")
    found = cycles(g)
    for c in found:
        print("cycle: " + " <-> ".join(c))
    print(f"{len(g)} modules, {sum(len(v) for v in g.values())} edges, {len(found)} cycles")
    return 1 if found else 0


if __name__ == "__main__":
    sys.exit(main())
