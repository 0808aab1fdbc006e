#!/usr/bin/env python3
"""Print the root package's top-level module graph (which module names which through `crate::`)
and its cycles; exit 1 if there is one. The workspace's crates (crates/) are acyclic by the
compiler; a module cycle here is a further crate split that would not compile yet.

A name the root re-exports from a crate (`pub use evoloop_dynamics as dynamics;`) is no module
of the root: no edge. A module that re-exports a crate whole and adds its own (`report`, `optim`:
`pub use evoloop_report::*;` plus `pub mod build;`) is an edge only where its own parts are
named (`crate::report::build`), not the crate's (`crate::report::Table`).

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


def own_parts(module):
    """The names a module adds to a crate it re-exports whole, or None if it re-exports none:
    every item its mod.rs declares or re-exports from elsewhere (counted generously: a name
    counted as the module's own keeps an edge, never hides one)."""
    mod_rs = os.path.join(SRC, module, "mod.rs")
    if not os.path.exists(mod_rs):
        return None
    text = strip(open(mod_rs, encoding="utf-8").read())
    if not re.search(r"^pub use evoloop_\w+::\*;", text, re.M):
        return None
    item = r"^\s*pub(?:\([^)]*\))?\s+(?:mod|fn|struct|enum|const|static|type|trait|macro)\s+(\w+)"
    names = set(re.findall(item, text, re.M))
    for used in re.findall(r"^\s*pub(?:\([^)]*\))?\s+use\s+(?!evoloop_)([^;]*);", text, re.M):
        names |= set(re.findall(r"\w+", used))
    return names


def keeps_edge(code, module, parts):
    """Whether `code` names `module` (one that extends a crate) for its own parts. Only a path
    `crate::module::name` whose name is the crate's is no edge; anything this cannot read (the
    module named bare, through a glob or a `{...}` group, or as `super::super::module`) counts."""
    named = re.findall(rf"\bcrate::{module}\b(?:::(\w+))?", code)
    in_group = any(
        re.search(rf"(?:^|[,{{\s]){module}\b", g) for g in re.findall(r"crate::\{([^}]*)\}", code, re.S)
    )
    unread = in_group or "" in named or re.search(rf"\bsuper::super::{module}\b", code)
    return bool(unread) or any(n in parts for n in named)


def graph():
    g = collections.defaultdict(set)
    lib = open(os.path.join(SRC, "lib.rs"), encoding="utf-8").read()
    # `pub use evoloop_x as name;` and `pub use evoloop_x::{A, B};`: names from crates.
    crates = set(re.findall(r"^pub use evoloop_\w+ as (\w+);", lib, re.M))
    for group in re.findall(r"^pub use evoloop_\w+::\{([^}]*)\}", lib, re.M):
        crates |= {name.strip() for name in group.split(",")}
    extended = {m: p for m in os.listdir(SRC) if (p := own_parts(m)) is not None}
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
            names |= set(re.findall(r"\bsuper::super::(\w+)", code)) if len(rel) == 2 else set()
            for m, parts in extended.items():
                if m in names and not keeps_edge(code, m, parts):
                    names.discard(m)
            g[module] |= names - {module} - crates
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
