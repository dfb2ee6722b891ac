#!/usr/bin/env python3
"""The Python package (crates/cps-python) must resolve every shared dependency with the
same features as `cargo test --workspace`, so that CI's package build, after the tests,
reuses the compiled dependencies instead of compiling most of them a second time (≈ 6 min
on two cores). Compares `cargo tree -e features` of the two and names each difference with
the line to add to crates/cps-python/Cargo.toml's build-sharing block."""

import collections
import re
import subprocess
import sys


def features(*args):
    out = subprocess.run(["cargo", "tree", "-e", "features", "--prefix", "none", *args],
                         check=True, capture_output=True, text=True).stdout
    found = collections.defaultdict(set)
    for line in out.splitlines():
        line = line.replace(" (*)", "").strip()
        m = re.match(r'(\S+) feature "([^"]+)"', line)
        if m:
            found[m.group(1)].add(m.group(2))
        elif m := re.match(r"(\S+) v", line):
            found[m.group(1)]
    return found


def main():
    package, workspace = features("-p", "cps-python"), features("--workspace")
    missing = {name: sorted(workspace.get(name, set()) - have) for name, have in package.items()}
    missing = {name: f for name, f in missing.items() if f}
    if not missing:
        print("feature parity: the Python package resolves its dependencies as the workspace's tests do")
        return 0
    print("feature parity: crates/cps-python resolves these dependencies with fewer features than "
          "`cargo test --workspace`, so CI would compile them twice; add them to the build-sharing "
          "block of crates/cps-python/Cargo.toml:", file=sys.stderr)
    for name, f in sorted(missing.items()):
        print(f"  {name}: {', '.join(f)}", file=sys.stderr)
    return 1


if __name__ == "__main__":
    sys.exit(main())
