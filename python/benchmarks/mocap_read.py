"""Import time of a 10-minute take at 240 Hz with 40 markers (144 000 frames, C3D floats):
cps (its reader, and the whole import to a demonstration) against ezc3d reading the
same file.

    cargo run --release -p cps-mocap --example synthetic_take -- /tmp/take10min.c3d \
        --markers 40 --seconds 600 --noise-mm 0.5 --gaps
    python python/benchmarks/mocap_read.py /tmp/take10min.c3d

Both read all 144 000 frames (the file gives its length in TRIAL:ACTUAL_END_FIELD; the
header holds at most 65 535); the comparison is also given per frame read.
"""

import sys
import time

import ezc3d

import cps.mocap


def best(f, n=3):
    times = []
    for _ in range(n):
        t = time.perf_counter()
        out = f()
        times.append(time.perf_counter() - t)
    return min(times), out


path = sys.argv[1]
t_cps, take = best(lambda: cps.mocap.take(path))
t_demo, demo = best(lambda: cps.mocap.read(path, ["tool1", "tool2", "tool3", "tool4"]))
t_ez, c = best(lambda: ezc3d.c3d(path), n=2)
ez_frames = c["data"]["points"].shape[2]
print(f"file: {path}: {take['frames']} frames x {len(take['labels'])} markers")
print(f"cps.mocap.take (to numpy):           {t_cps:8.3f} s  ({take['frames'] / t_cps:,.0f} frames/s)")
print(f"cps.mocap.read (4 markers -> poses): {t_demo:8.3f} s  ({demo['t'].size} poses)")
print(f"ezc3d.c3d:                            {t_ez:8.3f} s  ({ez_frames} frames read: {ez_frames / t_ez:,.0f} frames/s)")
print(f"cps is {t_ez / t_cps * take['frames'] / ez_frames:.1f}x ezc3d per frame")
