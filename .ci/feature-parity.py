#!/usr/bin/env python3
"""README's first command (`cargo run -p cps-cli --no-default-features`), the Python package's build (`-p
cps-python`), CI's numbers-only check (`cargo check -p cps-experiment -p cps-workspace-hack
--no-default-features`) and the test command (`cargo test --workspace`) must resolve every
shared dependency with the same features, so that each dependency is compiled once for all three
(a difference recompiles it and everything above it: with serde's derive macro, the whole
tree — minutes on two cores). Compares the features `cargo tree` resolves for each package
(its normal and build dependencies: what its build compiles) with the workspace's
(dev-dependencies included: what the tests compile), crate by crate and version by
version, and names each difference with what to add to crates/cps-workspace-hack/Cargo.toml
(a procedural macro's dependencies go under [build-dependencies] there)."""

import collections
import re
import subprocess
import sys


def features(edges, *args):
    out = subprocess.run(["cargo", "tree", "-e", edges, "--prefix", "none", "--format", "{p}|{f}", *args],
                         check=True, capture_output=True, text=True).stdout
    found = collections.defaultdict(set)
    for line in out.splitlines():
        line = line.replace(" (*)", "").strip()
        if "|" not in line:
            continue
        package, feats = line.rsplit("|", 1)
        m = re.match(r"(\S+) v(\S+)", package)
        if not m or package.endswith("(proc-macro)") and False:
            continue
        key = f"{m.group(1)} {m.group(2)}"
        found[key] |= {f for f in feats.split(",") if f}
    return found


# What the README's first command (`cargo run -p cps-cli --no-default-features`) leaves
# out on purpose: the transports, the web server and the dataset formats, each a feature
# of the cps crate that holds it (and the workspace hack's async runtime). Crates above them are compiled again for the tests; nothing
# below them is.
TRANSPORTS = {"dds", "zmq", "web", "mcap", "parquet", "default", "ros2", "coppelia", "studio", "datasets", "transports"}


def main():
    workspace = features("normal,build,dev", "--workspace")
    failed = False
    # The numbers-only build leaves out every feature of cps's own crates that brings a
    # format, a transport or figures (cps-report's `figures` and what turns it on): they
    # are checked again there, on purpose; nothing they depend on is.
    builds = (("cps-cli", ["--no-default-features"], TRANSPORTS),
              ("cps-python", [], set()),
              ("cps-experiment", ["-p", "cps-workspace-hack", "--no-default-features"], None))
    for package, args, left_out in builds:
        have = features("normal,build", "-p", package, *args)
        missing = {}
        for name, f in have.items():
            wanted = workspace.get(name, set())
            if name.startswith("cps"):
                # left_out None: every feature of cps's own crates.
                wanted = set() if left_out is None else wanted - left_out
            if wanted - f:
                missing[name] = sorted(wanted - f)
        if not missing:
            print(f"feature parity: {package} resolves its dependencies as the workspace's tests do")
            continue
        failed = True
        print(f"feature parity: {package} resolves these dependencies with fewer features than "
              "`cargo test --workspace`, so they would be compiled twice; add them to "
              "crates/cps-workspace-hack/Cargo.toml:", file=sys.stderr)
        for name, f in sorted(missing.items()):
            print(f"  {name}: {', '.join(f)}", file=sys.stderr)
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
