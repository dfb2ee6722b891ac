#!/usr/bin/env python3
"""ARCHITECTURE.md's crate table against the Cargo.toml files.

The table ("Crates and layers") lists the crates lowest first, each with the cps crates it
depends on. This check holds it to the manifests:
- every crate's cps dependencies (`[dependencies]`, not dev or build ones; the
  workspace-hack left out) are the ones its row names — or, where the row ends in "…" or
  says "all of the above" / "all libraries", at least the ones it names;
- a crate depends only on crates of rows above its own (the house's layering), never on
  itself or a crate listed after it.
A row names crates without their `cps-` prefix (`kinematics`, `ros2-msg`); `cps` is the
facade. Run from the repository's root; exits 1 with one line per difference.
"""

import re
import sys
import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
IGNORED = {"cps-workspace-hack"}


def table_rows():
    """(layer, crate, named deps, open) per row, in order."""
    text = (ROOT / "ARCHITECTURE.md").read_text()
    section = text.split("## Crates and layers", 1)[1].split("\n## ", 1)[0]
    rows = []
    layer = None
    for line in section.splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if len(cells) != 4 or not cells[1].startswith("`"):
            continue
        layer = cells[0] or layer
        crate = cells[1].strip("`").split("`")[0]
        deps_cell = cells[3]
        open_list = "…" in deps_cell or "all " in deps_cell
        # The names before any parenthesis or semicolon in each comma-separated item.
        named = set()
        for item in re.split(r"[,;]", deps_cell):
            word = re.sub(r"\(.*?\)", "", item).strip().strip("`")
            if not word or word in ("—", "…") or " " in word:
                continue
            named.add("cps" if word == "cps" else f"cps-{word}")
        rows.append((layer, crate, named, open_list))
    return rows


def manifest_deps(crate):
    path = ROOT / "Cargo.toml" if crate == "cps" else ROOT / "crates" / crate / "Cargo.toml"
    data = tomllib.loads(path.read_text())
    deps = data.get("dependencies", {})
    return {d for d in deps if (d == "cps" or d.startswith("cps-")) and d not in IGNORED}


def main():
    rows = table_rows()
    order = {crate: i for i, (_, crate, _, _) in enumerate(rows)}
    layer_of = {crate: layer for layer, crate, _, _ in rows}
    problems = []
    for layer, crate, named, open_list in rows:
        actual = manifest_deps(crate)
        missing = sorted(named - actual)
        if missing:
            problems.append(f"{crate}: ARCHITECTURE.md names {', '.join(missing)}, which its Cargo.toml does not depend on")
        extra = sorted(actual - named)
        if extra and not open_list:
            problems.append(f"{crate}: depends on {', '.join(extra)}, which its row in ARCHITECTURE.md does not name")
        for d in sorted(actual):
            if d not in order:
                problems.append(f"{crate}: depends on {d}, which ARCHITECTURE.md's table does not list")
            elif order[d] >= order[crate]:
                problems.append(f"{crate} ({layer}): depends on {d} ({layer_of[d]}), which the table lists after it: the table is lowest first")
    listed = set(order)
    for path in sorted((ROOT / "crates").glob("*/Cargo.toml")):
        name = tomllib.loads(path.read_text())["package"]["name"]
        if name not in listed:
            problems.append(f"{name}: not in ARCHITECTURE.md's crate table")
    if problems:
        print("ARCHITECTURE.md's crate table differs from the manifests:")
        for p in problems:
            print(f"  {p}")
        sys.exit(1)
    print(f"ok: ARCHITECTURE.md's crate table matches the {len(rows)} crates' manifests, each above what it depends on")


if __name__ == "__main__":
    main()
