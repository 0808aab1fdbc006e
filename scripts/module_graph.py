#!/usr/bin/env python3
"""Print the workspace's crate graph by layer; exit 1 on a crate that depends on one of its own
layer or above (an upward edge: the layering below is the design, the compiler only forbids
cycles), on a crate no layer names, or on a module that re-exports a crate whole
(`pub use evoloop_x::*;`), which would build one namespace out of two crates again.

    python3 scripts/module_graph.py
"""
import os
import re
import sys

ROOT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..")

# The workspace's layers, bottom first: a crate may depend only on crates of lower layers (the
# root package `evoloop`, a facade above them all, on any). A new crate must be placed here.
LAYERS = [
    ["evoloop-msg", "evoloop-files", "evoloop-stats", "evoloop-rt", "evoloop-workspace-hack"],
    ["evoloop-linalg", "evoloop-ipc", "evoloop-report", "evoloop-optim"],
    ["evoloop-dynamics", "evoloop-rkgnn"],
    ["evoloop-control"],
    ["evoloop-scenario"],
    ["evoloop-schemes"],
    ["evoloop-identify", "evoloop-tune", "evoloop-net"],
    ["evoloop-run"],
    ["evoloop-cli"],
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


def glob_reexports():
    """Every `pub use evoloop_x::*;` in the workspace's code, as (file, line)."""
    found = []
    for top in [os.path.join(ROOT, "src"), os.path.join(ROOT, "crates")]:
        for root, _, files in os.walk(top):
            for f in files:
                if f.endswith(".rs"):
                    path = os.path.join(root, f)
                    for i, line in enumerate(open(path, encoding="utf-8"), 1):
                        if re.match(r"\s*pub use evoloop_\w+::\*;", line):
                            found.append((os.path.relpath(path, ROOT), i))
    return found


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
    globs = glob_reexports()
    for path, line in globs:
        print(f"glob re-export of a crate: {path}:{line}")
    return 1 if globs or up else 0


if __name__ == "__main__":
    sys.exit(main())
