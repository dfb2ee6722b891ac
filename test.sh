#!/usr/bin/env bash
# The tests, as the README gives them: `cargo test --workspace --profile checked
# --no-fail-fast` (extra arguments are passed on), then one closing line that counts what ran. A test whose peer
# (franky-sim, CycloneDDS, rclpy, MuJoCo, Chromium, Lua, the CoppeliaSim client) is not
# installed checks nothing: it is counted as skipped, not passed, and named, with the
# command that installs the peers (`bash .ci/peers`). Under CI (`CI` set) a missing peer
# fails its test instead.
set -uo pipefail
cd "$(dirname "$0")"
out=$(mktemp)
skips=$(mktemp)
trap 'rm -f "$out" "$skips"' EXIT
CPS_SKIP_LOG="$skips" cargo test --workspace --profile checked --no-fail-fast "$@" 2>&1 | tee "$out"
status=${PIPESTATUS[0]}
# libtest's per-program lines: "test result: ok. 16 passed; 0 failed; 2 ignored; ..."
read -r passed failed ignored < <(awk '/^test result:/ {
    for (i = 1; i <= NF; i++) {
      if ($(i) ~ /^passed;?$/) p += $(i-1)
      if ($(i) ~ /^failed;?$/) f += $(i-1)
      if ($(i) ~ /^ignored;?$/) g += $(i-1)
    }
  } END { print p + 0, f + 0, g + 0 }' "$out")
skipped=$(sort -u "$skips" | cut -d: -f1 | sort -u | wc -l)
echo
if [ "$skipped" -gt 0 ]; then
  echo "$skipped test(s) could not meet their peer and checked nothing:"
  sort -u "$skips" | sed 's/^/  /'
  echo "install every peer with \`bash .ci/peers\`, then run \`bash test.sh\` again"
fi
if [ "$ignored" -gt 0 ]; then
  echo "$ignored test(s) marked #[ignore] (measurements, run on demand with: bash test.sh -- --ignored)"
fi
echo "tests: $((passed - skipped)) passed, $failed failed, $((ignored + skipped)) skipped"
exit "$status"
