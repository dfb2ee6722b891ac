#!/usr/bin/env bash
# The tests, as the README gives them: `cargo test --workspace --profile checked
# --no-fail-fast`, then one closing line that counts what ran. A test whose peer
# (franky-sim, CycloneDDS, rclpy, MuJoCo, Chromium, Lua, the CoppeliaSim client) is not
# installed checks nothing: it is counted as skipped, not passed, and named, with the
# command that installs the peers (`bash .ci/peers`). Under CI (`CI` set) a missing peer
# fails its test instead.
#
# Without arguments the same tests run in two lanes at once: the test programs that start
# franky-sim or franka-sim (a MuJoCo arm stepped against the clock, one franky-sim per
# core at a time; franka-sim's alone, with CPU hogs beside it, on purpose) in one,
# printed as they run; everything else in the other, at a lower priority so that the
# simulator never waits for a core, printed when it ends. On two cores that takes about
# two thirds of the time of one lane. With arguments it is one `cargo test --profile checked
# --no-fail-fast` with them passed on: of the whole workspace (`bash test.sh -- --ignored`)
# unless they name packages (`bash test.sh -p cps-dmp`).
set -uo pipefail
cd "$(dirname "$0")"
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
skips="$work/skips"
: >"$skips"
export CPS_SKIP_LOG="$skips"
run=(cargo test --profile checked --no-fail-fast)

if [ $# -gt 0 ]; then
  # The whole workspace unless the arguments (before a `--`) name packages.
  scope=(--workspace)
  for a in "$@"; do
    [ "$a" = "--" ] && break
    case "$a" in -p | -p?* | --package | --package=*) scope=() ;; esac
  done
  "${run[@]}" "${scope[@]}" "$@" 2>&1 | tee "$work/out"
  status=${PIPESTATUS[0]}
else
  # Everything compiled first, its test programs listed (cargo's JSON on stdout, its
  # words on stderr).
  "${run[@]}" --workspace --no-run --message-format=json-render-diagnostics \
    2>&1 >"$work/build.json" | tee "$work/build"
  status=${PIPESTATUS[0]}
  if [ "$status" = 0 ]; then
    # The lane of the clock: every test program that starts franky-sim or franka-sim, run
    # by cargo (`--workspace`, as built: the same features, nothing compiled again). The
    # other lane runs every other program as cargo would (from its package's folder), then
    # the doctests. (tests/ at the root is the facade's, package `cps`: the contract's suite.)
    declare -A clock=()
    for f in $(grep -lE 'Frank[ya]Sim::start' crates/*/tests/*.rs tests/*.rs); do
      clock[$(realpath "$f")]=1
    done
    live=()
    for f in "${!clock[@]}"; do live+=(--test "$(basename "$f" .rs)"); done
    python3 - "$work/build.json" "${!clock[@]}" >"$work/programs" <<'PY'
import json, os, sys
clock = set(sys.argv[2:])
for line in open(sys.argv[1]):
    m = json.loads(line) if line.startswith("{") else {}
    if m.get("reason") != "compiler-artifact" or not m.get("executable") or not m["profile"]["test"]:
        continue
    # A test program of the clock's name in another package runs in the clock's lane too.
    if "test" in m["target"]["kind"] and any(os.path.basename(c) == os.path.basename(m["target"]["src_path"]) for c in clock):
        continue
    print(os.path.dirname(m["manifest_path"]), m["target"]["src_path"], m["executable"], sep="\t")
PY
    ( "${run[@]}" --workspace "${live[@]}" 2>&1; echo $? >"$work/live.rc" ) | tee "$work/live" &
    live_pid=$!
    {
      # The doctests first: rustdoc compiles them now, under cargo's lock on the build
      # directory, which a cargo started beside the tests (CI's clippy and docs) would
      # otherwise hold for minutes. `CPS_DOCTESTS_DONE`, when set, names a file touched
      # once they ran (CI starts its own cargo after that).
      nice -n 10 "${run[@]}" --workspace --doc 2>&1; echo $? >"$work/rest2.rc"
      [ -n "${CPS_DOCTESTS_DONE:-}" ] && touch "$CPS_DOCTESTS_DONE"
      rc=0
      while IFS=$'\t' read -r dir src exe; do
        echo "     Running ${src#"$PWD"/} (${exe#"$PWD"/})"
        (cd "$dir" && nice -n 10 "$exe" </dev/null) 2>&1 || rc=1
      done <"$work/programs"
      echo $rc >"$work/rest1.rc"
    } >"$work/rest"
    wait "$live_pid"
    echo
    echo "== the other tests (run beside the lane above)"
    cat "$work/rest"
    for rc in live rest1 rest2; do
      [ "$(cat "$work/$rc.rc" 2>/dev/null)" = 0 ] || status=1
    done
  fi
  cat "$work/build" "$work/live" "$work/rest" >"$work/out" 2>/dev/null
fi
# libtest's per-program lines: "test result: ok. 16 passed; 0 failed; 2 ignored; ..."
read -r passed failed ignored < <(awk '/^test result:/ {
    for (i = 1; i <= NF; i++) {
      if ($(i) ~ /^passed;?$/) p += $(i-1)
      if ($(i) ~ /^failed;?$/) f += $(i-1)
      if ($(i) ~ /^ignored;?$/) g += $(i-1)
    }
  } END { print p + 0, f + 0, g + 0 }' "$work/out")
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
