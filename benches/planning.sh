#!/usr/bin/env bash
# The planner's benchmark (benches/planning.rs): 20 seeded problems of each kind — table
# pick, shelves small, tall and thin, an open box, a cage — on the FR3 with its hand at the
# guard's 5 mm margin; prints solved, planning-time median and 95th percentile, path
# length and clearance per kind. `bash benches/planning.sh --per-kind 50` for more.
set -euo pipefail
cd "$(dirname "$0")/.."
cargo bench -p cps-bench --bench planning -- "$@"
