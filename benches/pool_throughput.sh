#!/usr/bin/env bash
# Candidates executed per second against the number of simulators, with simulated
# physics: `cps-cli sim pool --step-cost 5` makes every stand-in step take 5 ms of wall
# time (sleeping, as a simulator busy with physics would be). Runs the shipped
# experiments/viapoint_executed.toml on pools of 1, 2, 4, 8 and 16 simulators, with a
# 0.1 s control period (101 steps, ≈ 0.5 s of simulator time per execution) and 2·N
# generations of 16 candidates, and prints executions/s and the efficiency against N × the
# single simulator's rate. Usage: benches/pool_throughput.sh [sizes...]
set -euo pipefail
cd "$(dirname "$0")/.."
cargo build --release -q -p cps-cli
cli=target/release/cps-cli
sizes=("${@:-1 2 4 8 16}")
sizes=(${sizes[@]})
max=${sizes[-1]}
base=24100
work=$(mktemp -d)
"$cli" sim pool --n "$max" --base-port "$base" --dt 0.1 --step-cost 5 > "$work/pool.log" 2>&1 &
pool=$!
trap 'kill -INT $pool 2>/dev/null; wait $pool 2>/dev/null; rm -rf "$work"' EXIT
for _ in $(seq 50); do grep -q "Ctrl-C" "$work/pool.log" && break; sleep 0.1; done
printf '%-6s %-12s %-10s %-14s %s\n' simulators executions wall_s executions/s efficiency
single=""
for n in "${sizes[@]}"; do
  endpoints=$(for i in $(seq 0 $((n - 1))); do printf '"tcp://127.0.0.1:%d",' $((base + 2 * i)); done)
  sed -e 's/^backend = "kinematic"/backend = "coppelia"/' \
      -e "s|^# endpoints = \[.*|endpoints = [${endpoints%,}]|" \
      -e '/^#              "tcp/d' \
      -e 's/^dt = 0.01               #/dt = 0.1                #/' \
      -e "s/^generations = 30/generations = $((2 * n))/" \
      experiments/viapoint_executed.toml > "$work/pool$n.toml"
  "$cli" run "$work/pool$n.toml" --out "$work/out$n" --quiet
  python3 - "$work/out$n/summary.json" "$n" "${single:-0}" <<'PY' | tee -a "$work/table"
import json, sys
s = json.load(open(sys.argv[1]))
n, single = int(sys.argv[2]), float(sys.argv[3])
rate = s["evaluations"] / s["wall_time_s"]
eff = rate / (n * single) if single else 1.0
print(f"{n:<6} {s['evaluations']:<12} {s['wall_time_s']:<10.2f} {rate:<14.2f} {eff:.2f}")
PY
  if [ -z "$single" ]; then single=$(awk 'NR==1 {print $4}' "$work/table"); fi
done
