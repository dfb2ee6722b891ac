#!/usr/bin/env python3
"""Fails when ARCHITECTURE.md's crate table or code map no longer matches the tree.

Every crate under crates/ has a row in the crate table (| `cps-x` | ...) and a row in the
code map (| `crates/cps-x` | ...); every module file of a crate (src/*.rs besides lib.rs
and main.rs, and every folder src/*/) is named in its code-map row, as `name.rs` or
`name/`; and neither table names a crate that is not there. A new crate or module thus
comes with its line in ARCHITECTURE.md, where a newcomer looks for it.
"""
import os
import re
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
text = open(os.path.join(ROOT, "ARCHITECTURE.md"), encoding="utf-8").read()
crates = sorted(d for d in os.listdir(os.path.join(ROOT, "crates"))
                if os.path.isfile(os.path.join(ROOT, "crates", d, "Cargo.toml")))

table = set(re.findall(r"^\|[^|\n]*\| `(cps-[a-z0-9-]+)` \|", text, re.M))
rows = {m.group(1): m.group(2) for m in re.finditer(r"^\| `crates/(cps-[a-z0-9-]+)`[^|\n]*\|(.*)$", text, re.M)}

problems = []
for c in crates:
    if c not in table:
        problems.append(f"crate {c} has no row in ARCHITECTURE.md's crate table")
    if c not in rows:
        problems.append(f"crate {c} has no row in ARCHITECTURE.md's code map (| `crates/{c}` | ...)")
        continue
    src = os.path.join(ROOT, "crates", c, "src")
    if not os.path.isdir(src):
        continue
    row = rows[c]
    for entry in sorted(os.listdir(src)):
        path = os.path.join(src, entry)
        if os.path.isdir(path):
            name = entry + "/"
        elif entry.endswith(".rs") and entry not in ("lib.rs", "main.rs"):
            name = entry
        else:
            continue
        if f"`{name}" not in row:
            problems.append(f"crates/{c}/src/{name} is not named in the code map's row for {c}")
for c in sorted(table | set(rows)):
    if c not in crates:
        problems.append(f"ARCHITECTURE.md names crate {c}, which is not under crates/")

if problems:
    print("FAIL: ARCHITECTURE.md and the tree disagree:")
    for p in problems:
        print("  " + p)
    sys.exit(1)
modules = sum(1 for c in crates if os.path.isdir(os.path.join(ROOT, "crates", c, "src"))
              for e in os.listdir(os.path.join(ROOT, "crates", c, "src")) if e not in ("lib.rs", "main.rs"))
print(f"ok: ARCHITECTURE.md's crate table and code map name all {len(crates)} crates and their {modules} modules")
