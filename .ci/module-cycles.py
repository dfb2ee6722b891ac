#!/usr/bin/env python3
"""Fails when the modules of a crate import each other in a circle.

For every crate under crates/ (and the facade), each file under src/ is a module
(`a/mod.rs` and `a.rs` are `a`; `a/b.rs` is `a::b`, counted as part of `a`), and an
edge a -> b is any `crate::b` path in a's code (use lines and inline paths; items that
lib.rs re-exports are followed to the module that defines them when lib.rs says
`pub use b::...`). A module's own children are part of it. Prints each cycle found.
"""
import os
import re
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def top_module(src, path):
    rel = os.path.relpath(path, src)[:-3].replace(os.sep, "/")
    head = rel.split("/")[0]
    return None if head in ("lib", "main") else head


def crate_graph(src):
    files = []
    for d, _, names in os.walk(src):
        files += [os.path.join(d, n) for n in names if n.endswith(".rs")]
    modules = {top_module(src, f) for f in files} - {None}
    # lib.rs re-exports: `pub use module::{A, B}` or `pub use module::A;`
    reexport = {}
    lib = os.path.join(src, "lib.rs")
    if os.path.exists(lib):
        text = open(lib, encoding="utf-8").read()
        for m, items in re.findall(r"pub use (\w+)::\{([^}]*)\}", text):
            for it in re.findall(r"\w+", items):
                reexport[it] = m
        for m, it in re.findall(r"pub use (\w+)::(\w+);", text):
            reexport[it] = m
    edges = {m: set() for m in modules}
    for f in files:
        a = top_module(src, f)
        if a is None:
            continue
        text = open(f, encoding="utf-8").read()
        text = re.sub(r"//[^\n]*", "", text)
        names = set(re.findall(r"crate::(\w+)", text))
        for group in re.findall(r"crate::\{([^}]*)\}", text):
            names |= set(re.findall(r"\b(\w+)\b", group))
        for n in names:
            b = n if n in modules else reexport.get(n)
            if b and b != a:
                edges[a].add(b)
    return edges


def cycles(edges):
    found, state, stack = [], {}, []

    def visit(n):
        state[n] = 1
        stack.append(n)
        for m in sorted(edges[n]):
            if state.get(m) == 1:
                found.append(stack[stack.index(m):] + [m])
            elif m not in state:
                visit(m)
        stack.pop()
        state[n] = 2

    for n in sorted(edges):
        if n not in state:
            visit(n)
    return found


# The check must be able to see an edge: cps-experiment's run module calls its kinds.
probe = crate_graph(os.path.join(ROOT, "crates", "cps-experiment", "src"))
if "kinds" not in probe.get("run", set()):
    print("FAIL: the module check cannot see cps-experiment's run -> kinds")
    sys.exit(1)

bad = 0
srcs = [os.path.join(ROOT, "src")] + [
    os.path.join(ROOT, "crates", c, "src") for c in sorted(os.listdir(os.path.join(ROOT, "crates")))
]
for src in srcs:
    if not os.path.isdir(src):
        continue
    for c in cycles(crate_graph(src)):
        bad += 1
        print(f"{os.path.relpath(src, ROOT)}: modules in a circle: {' -> '.join(c)}")
if bad:
    sys.exit(1)
print("no module circles")
