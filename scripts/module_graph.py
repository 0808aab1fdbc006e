#!/usr/bin/env python3
"""Print the workspace's crate graph by layer and the root package's top-level module graph
(which module names which through `crate::`); exit 1 on a crate that depends on one of its own
layer or above (an upward edge: the layering below is the design, the compiler only forbids
cycles) or on a module cycle in the root (a further crate split that would not compile yet).

A name the root re-exports from a crate (`pub use evoloop_dynamics as dynamics;`) is no module
of the root: no edge. A module that re-exports a crate whole and adds its own (`report`, `optim`:
`pub use evoloop_report::*;` plus `pub mod build;`) is an edge only where its own parts are
named (`crate::report::build`), not the crate's (`crate::report::Table`).

    python3 scripts/module_graph.py          # the crate graph, then the module cycles
    python3 scripts/module_graph.py --edges  # and every module edge
"""
import collections
import os
import re
import sys

ROOT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..")
SRC = os.path.join(ROOT, "src")

# The workspace's layers, bottom first: a crate may depend only on crates of lower layers (the
# root package `evoloop`, above them all, on any). A new crate must be placed here.
LAYERS = [
    ["evoloop-msg", "evoloop-files", "evoloop-stats", "evoloop-rt", "evoloop-workspace-hack"],
    ["evoloop-linalg", "evoloop-ipc", "evoloop-report", "evoloop-optim"],
    ["evoloop-dynamics", "evoloop-rkgnn"],
    ["evoloop-control"],
]


def crate_graph():
    """Each crate of crates/ and the evoloop crates its [dependencies] name."""
    g = {}
    crates = os.path.join(ROOT, "crates")
    for name in sorted(os.listdir(crates)):
        manifest = os.path.join(crates, name, "Cargo.toml")
        if not os.path.isfile(manifest):
            continue
        g[name] = sorted(set(evoloop_deps(manifest)))
    return g


def evoloop_deps(manifest):
    """The evoloop crates a manifest's normal dependencies name (every target's, renamed ones by
    their package), read as TOML where Python has it (3.11+)."""
    try:
        import tomllib
    except ImportError:  # older Python: the plain `[dependencies]` table only
        text = open(manifest, encoding="utf-8").read()
        deps = re.search(r"^\[dependencies\]\s*\n(.*?)(?=^\[|\Z)", text, re.S | re.M)
        return re.findall(r"^\s*(evoloop-[a-z0-9-]+)", deps.group(1), re.M) if deps else []
    with open(manifest, "rb") as f:
        m = tomllib.load(f)
    tables = [m.get("dependencies", {})]
    tables += [t.get("dependencies", {}) for t in m.get("target", {}).values()]
    names = []
    for table in tables:
        for key, spec in table.items():
            package = spec.get("package", key) if isinstance(spec, dict) else key
            if package.startswith("evoloop-"):
                names.append(package)
    return names


def upward_edges(g):
    """(crate, dependency, why) for every edge that does not go down a layer."""
    layer = {c: i for i, names in enumerate(LAYERS) for c in names}
    bad = [(c, "", "not placed in LAYERS") for c in g if c not in layer]
    bad += [(c, "", "in LAYERS but no crate of crates/") for c in layer if c not in g]
    for c, deps in g.items():
        for d in deps:
            if c in layer and d in layer and layer[d] >= layer[c]:
                bad.append((c, d, f"layer {layer[c]} -> layer {layer[d]}"))
    return bad


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
    crates = crate_graph()
    for i, names in enumerate(LAYERS):
        for c in names:
            if c in crates:
                print(f"layer {i}  {c} -> {', '.join(crates[c]) or '(no evoloop crate)'}")
    up = upward_edges(crates)
    for c, d, why in up:
        print(f"upward: {c} -> {d or '?'} ({why})")
    print(f"{len(crates)} crates, {sum(len(v) for v in crates.values())} edges, {len(up)} upward")
    g = graph()
    if "--edges" in sys.argv:
        for m in sorted(g):
            print(f"{m} -> {', '.join(sorted(g[m])) or '(nothing)'}")
    found = cycles(g)
    for c in found:
        print("cycle: " + " <-> ".join(c))
    print(f"{len(g)} modules, {sum(len(v) for v in g.values())} edges, {len(found)} cycles")
    return 1 if found or up else 0


if __name__ == "__main__":
    sys.exit(main())
