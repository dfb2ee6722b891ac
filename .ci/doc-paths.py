#!/usr/bin/env python3
"""Every repository path the README, ARCHITECTURE, BENCHMARKS and docs/ name exists.

A path is a backticked word that starts with one of the repository's own top-level
folders (crates/, experiments/, configs/, docs/, python/, benches/, src/, .ci/, vendor/,
fuzz/), or a relative link target (resolved from the document's folder). Glob-like words (`*`, `<name>`,
`…`) name families, not files, and are left alone; so are paths under target/ and
results/, which runs make. Exits 1 naming each missing path with its file and line."""

import os
import re
import sys

ROOT = os.path.normpath(os.path.join(os.path.dirname(__file__), ".."))
TOP = ("crates/", "experiments/", "configs/", "docs/", "python/", "benches/", "src/",
       ".ci/", "vendor/", "fuzz/")
DOCS = ["README.md", "ARCHITECTURE.md", "BENCHMARKS.md"] + sorted(
    os.path.join("docs", f) for f in os.listdir(os.path.join(ROOT, "docs")) if f.endswith(".md"))
WORD = re.compile(r"`([^`\s]+)`|\]\(([^)\s#]+)")


def candidates(line):
    """(word, is a link) for each backticked word and link target on the line."""
    for m in WORD.finditer(line):
        if m.group(1):
            yield m.group(1).rstrip(".,;:"), False
        else:
            yield m.group(2), True


def main():
    missing = []
    checked = 0
    for doc in DOCS:
        base = os.path.dirname(os.path.join(ROOT, doc))
        with open(os.path.join(ROOT, doc), encoding="utf-8") as f:
            for n, line in enumerate(f, 1):
                for word, link in candidates(line):
                    if any(c in word for c in "*<>…{}$|") or "://" in word:
                        continue
                    path = word.split(":")[0]
                    if path.startswith("./"):
                        path = path[2:]
                    if link and not path.startswith(("http", "mailto")):
                        full = os.path.normpath(os.path.join(base, path))
                    elif path.startswith(TOP):
                        full = os.path.join(ROOT, path)
                    else:
                        continue
                    checked += 1
                    if not os.path.exists(full):
                        missing.append(f"{doc}:{n}: `{word}` does not exist")
    if missing:
        print("\n".join(missing))
        print(f"FAIL: {len(missing)} path(s) the docs name are not in the tree")
        return 1
    print(f"ok: the {checked} repository paths the README, ARCHITECTURE, BENCHMARKS and docs/ name exist")
    return 0


if __name__ == "__main__":
    sys.exit(main())
