#!/usr/bin/env bash
# The hostile sweep's file and flag cases (2026-12-05), run through a cps-cli binary: one
# Markdown row per case with its exit code, wall time (s), peak memory (MB) and first line
# of error. `bash benches/hostile.sh target/checked/cps-cli` (BENCHMARKS.md › Hostile
# inputs has the numbers before and after cps-files). Each case runs under a 20 GB
# address-space limit and is killed 150 s after a SIGTERM it ignores.
set -uo pipefail
B=$(realpath "$1")
repo=$(cd "$(dirname "$0")/.." && pwd)
W=$(mktemp -d)
trap 'rm -rf "$W"' EXIT
cd "$W"
python3 - "$repo" <<'PY'
import math, random, sys
repo = sys.argv[1]
H = 't,q1,q2,q3,q4,q5,q6,q7\n'
home = [0, -0.785, 0, -2.356, 0, 1.571, 0.785]
row = lambda t, q: ','.join(str(x) for x in [t] + q) + '\n'
open('span.csv', 'w').write(H + row(0, home) + row(1, home) + row(10000000, home))
open('huge.csv', 'w').write(H + row(0, home) + row(1, home) + row(1e300, home))
open('rec.csv', 'w').write(H + ''.join(row(k * 0.01, [v + 0.05 * math.sin(k * 0.01 + j) for j, v in enumerate(home)]) for k in range(201)))
h = ['t'] + [f'{p}{j}' for p in ['q', 'dq', 'tau', 'q_d'] for j in range(1, 8)]
with open('idrec.csv', 'w') as f:
    f.write(','.join(h) + '\n')
    for k in range(2000):
        t = 1e300 if k == 1999 else k * 1e-3
        q = [0.1 * math.sin(t * 3 + j) for j in range(7)]
        f.write(','.join(str(x) for x in [t] + q + [0] * 7 + [0.1] * 7 + q) + '\n')
def scene(name, obstacle):
    open(name, 'w').write('[robot]\nmodel = "fr3"\ninitial_q = [0, -0.785, 0, -2.356, 0, 1.571, 0.785]\n\n[[obstacle]]\nname = "o"\n' + obstacle)
scene('plate.toml', 'shape = "box"\nsize = [1e15, 1e15, 0.01]\nxyz = [0, 0, 0.5]\n')
scene('box154.toml', 'shape = "box"\nsize = [1e154, 1, 1]\nxyz = [0, 0, -1e154]\n')
scene('cyl160.toml', 'shape = "cylinder"\nradius = 1e160\nlength = 1\nxyz = [0, 0, -3]\n')
scene('zero.toml', 'shape = "mesh"\nfile = "/dev/zero"\nxyz = [0, 0, -3]\n')
scene('fifo.toml', 'shape = "mesh"\nfile = "pipe.stl"\nxyz = [0, 0, -3]\n')
scene('hull.toml', 'shape = "mesh"\nfile = "sphere100k.obj"\nxyz = [2, 0, 0]\n')
random.seed(1)
with open('sphere100k.obj', 'w') as f:
    for _ in range(100000):
        v = [random.gauss(0, 1) for _ in range(3)]
        n = math.sqrt(sum(x * x for x in v))
        f.write('v %f %f %f\n' % tuple(0.1 * x / n for x in v))
    for i in range(0, 100000 - 2, 3):
        f.write('f %d %d %d\n' % (i + 1, i + 2, i + 3))
text = open(f'{repo}/experiments/imitation.toml').read().replace('scene = "thesis"', f'scene = "{repo}/configs/scenes/thesis.toml"')
open('bent.toml', 'w').write(text + '\n[[obstacle]]\nname = "ball"\nshape = "sphere"\nxyz = [0.82, 0.10, 1.86]\nradius = 0.03\n\n[clearance]\ndistance = 0.05\n')
PY
mkfifo pipe.stl
m() { # the case's name, then the command
  local name=$1; shift
  local code
  code=$( { ulimit -v 20000000; /usr/bin/time -f "TIME %e %M" timeout -k 150 150 "$@" >/dev/null 2>err.txt; echo $?; } 2>&1 | tail -1)
  local t mem msg
  t=$(grep -a "^TIME" err.txt | tail -1 | awk '{print $2}')
  mem=$(grep -a "^TIME" err.txt | tail -1 | awk '{printf "%.0f", $3/1024}')
  msg=$(grep -av "^TIME\|^Command" err.txt | grep -a . | head -1 | cut -c1-110)
  echo "| $name | $code | ${t:--} | ${mem:--} | $msg |"
}
"$B" lerobot write rec.csv --out theirs --task t >/dev/null 2>&1
ln -s theirs mine
m "lerobot write --force onto a link to another dataset" "$B" lerobot write rec.csv --out mine --task t --force
echo "| (the other dataset's files left: $(find theirs -type f | wc -l) of 5) | | | | |"
"$B" lerobot write rec.csv --out ds --task t >/dev/null 2>&1
mkdir ds/videos
m "lerobot write --force onto a dataset with an empty videos/" "$B" lerobot write rec.csv --out ds --task t --force
echo "| (the dataset's files left: $(find ds -type f | wc -l) of 5) | | | | |"
"$B" lerobot write rec.csv --out dsx --task t >/dev/null 2>&1
mkdir outside
mv dsx/data/chunk-000/file-000.parquet outside/real.parquet
sed -i 's|"data/chunk-{chunk_index:03d}/file-{file_index:03d}.parquet"|"../outside/real.parquet"|' dsx/meta/info.json
m "imitate: a dataset whose data_path is ../outside/real.parquet" "$B" imitate dsx --out m.json
"$B" lerobot write rec.csv --out dsw --task t >/dev/null 2>&1
sed -i 's|{chunk_index:03d}|{chunk_index:070000d}|' dsw/meta/info.json
m "imitate: a data_path padded to 70 000 digits" "$B" imitate dsw --out m2.json
m "limits check: a joint CSV whose last time is 1e300" "$B" limits check huge.csv
m "limits check: a joint CSV spanning 1e7 s" "$B" limits check span.csv
m "lerobot write --fps 4000000000" "$B" lerobot write rec.csv --out dsf --task t --fps 4000000000
m "collide --scene: an obstacle file /dev/zero" "$B" collide rec.csv --scene zero.toml
m "collide --scene: an obstacle file that is a FIFO" "$B" collide rec.csv --scene fifo.toml
m "collide --scene: a mesh of 100 000 points on a sphere" "$B" collide rec.csv --scene hull.toml
m "collide --scene: a 1e15 m plate through the arm" "$B" collide rec.csv --scene plate.toml
m "collide --scene: a 1e154 m box" "$B" collide rec.csv --scene box154.toml
m "collide --scene: a cylinder of radius 1e160 m" "$B" collide rec.csv --scene cyl160.toml
m "identify: a recording with a time of 1e300" "$B" identify idrec.csv --out c.toml
m "run: the shipped imitation, [clearance] 0.05 m, a ball at its start" "$B" run bent.toml --out bent --quiet
"$B" lerobot write rec.csv --out dsm --task t >/dev/null 2>&1
python3 - "$B" <<'PY'
import os, random, subprocess, sys
B = sys.argv[1]
random.seed(7)
path = 'dsm/data/chunk-000/file-000.parquet'
data = open(path, 'rb').read()
codes = {}
for _ in range(300):
    b = bytearray(data)
    for _ in range(random.randint(1, 4)):
        b[random.randrange(len(b))] = random.randrange(256)
    open(path, 'wb').write(b)
    c = subprocess.run([B, 'imitate', 'dsm', '--out', 'mm.json'], capture_output=True).returncode
    codes[c] = codes.get(c, 0) + 1
    if os.path.exists('mm.json'):
        os.remove('mm.json')
print('| imitate on 300 byte-mutated frames files: exit codes | ' + ', '.join(f'{k}: {v}' for k, v in sorted(codes.items())) + ' | | | |')
PY
