"""Every command that drives a Franka, run again and again against franka-sim with the
robot's reflexes on, on a loaded machine: the numbers behind issue 61's closing note.

For each mode (execute, execute --retime, a DMP stepped online, follow a chunk file, follow
a live policy over UDP, identify's chirps, guide's torques) and each cps-cli given (the one
before and the one after, say), N runs, each in a network namespace of its own (franka-sim
binds 0.0.0.0:1337) with a CPU hog per core beside it; franka-sim at a realtime priority
(the robot's Control, a machine of its own) unless --sim-normal. Then pylibfranka, the
official client, replaying the quintic the libfranka way on the same load.

Per mode and binary: runs, runs ended by a reflex, and (where the binary reports them)
cycles the robot extrapolated, commands it dropped, commands limited. As root (namespaces):

    sudo python3 python/benchmarks/franka_lost_cycles.py \\
        --cli before=/path/to/old/cps-cli --cli after=target/checked/cps-cli --runs 3

The franka-sim and franky-sim venvs are .ci/peers's (target/franka-sim-venv,
target/franka-venv). Prints a Markdown table; --json writes every run.
"""

import argparse
import json
import math
import os
import subprocess
import sys
import tempfile
import textwrap

import franka_sim_peer

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
FRANKY_PY = franka_sim_peer.FRANKY_PY
HOME = [0.0, 0.0, 0.0, -1.57, 0.0, 1.57, 0.785]
MODES = ["execute", "execute --retime", "DMP online", "follow file", "follow --listen",
         "identify", "guide", "pylibfranka"]


def quintic(path, start, delta, seconds):
    with open(path, "w") as f:
        f.write("t,q1,q2,q3,q4,q5,q6,q7\n")
        n = int(seconds * 100)
        for k in range(n + 1):
            s = k / n
            p = 10 * s**3 - 15 * s**4 + 6 * s**5
            q = [a + d * p for a, d in zip(start, delta)]
            f.write(f"{s * seconds:.3f}," + ",".join(f"{x:.9f}" for x in q) + "\n")


def chunks(path, start, seconds=3.0, chunk_hz=30.0, horizon=50, rate=50.0):
    """A policy stand-in's chunks of a 0.25 Hz swing, each predicted from an observation
    80 ms before its arrival (the replay form of `cps-cli franka follow`)."""

    def demo(t):
        s = 0.5 - 0.5 * math.cos(math.pi / 2 * max(t, 0.0))
        q = list(start)
        q[0] += 0.3 * s
        q[3] += 0.2 * s
        return q

    with open(path, "w") as f:
        f.write("chunk,arrived_s,observed_s,k,q1,q2,q3,q4,q5,q6,q7\n")
        c, t = 0, 0.1
        while t < seconds:
            observed = t - 0.08
            for k in range(horizon):
                q = demo(observed + k / rate)
                f.write(f"{c},{t:.6f},{observed:.6f},{k}," + ",".join(f"{x:.9f}" for x in q) + "\n")
            c += 1
            t += 1.0 / chunk_hz


def inner(args):
    """Inside the namespace: start franka-sim, the hogs, run one mode, print its JSON."""
    work = tempfile.mkdtemp(prefix="cps-lost-")
    server, log = franka_sim_peer.start(work, realtime=not args.sim_normal)
    hogs = franka_sim_peer.hogs(os.cpu_count() or 2)
    cli, mode = args.run_cli, args.run_mode
    realtime = ["--realtime", args.realtime]
    rec = os.path.join(work, "rec.csv")
    common = ["--host", "127.0.0.1", "--json"] + realtime
    result = {"mode": mode}
    try:
        if mode == "pylibfranka":
            code = textwrap.dedent("""
                import json, pylibfranka as p
                robot = p.Robot("127.0.0.1", p.RealtimeConfig.kIgnore)
                q0 = list(robot.read_once().q_d)
                d = [0.4, 0.2, -0.3, 0.3, 0.2, -0.2, 0.3]
                ctl = robot.start_joint_position_control(p.ControllerMode.JointImpedance)
                t, long_periods = 0.0, 0
                try:
                    while True:
                        state, period = ctl.readOnce()
                        t += period.to_sec()
                        long_periods += period.to_sec() > 0.0015
                        s = min(t / 4.0, 1.0)
                        pp = 10 * s**3 - 15 * s**4 + 6 * s**5
                        cmd = p.JointPositions([a + b * pp for a, b in zip(q0, d)])
                        cmd.motion_finished = t >= 4.0
                        ctl.writeOnce(cmd)
                        if t >= 4.0:
                            break
                    print(json.dumps({"complete": True, "long_periods": long_periods}))
                except Exception as e:
                    print(json.dumps({"complete": False, "ending": str(e), "long_periods": long_periods}))
            """)
            out = subprocess.run(["setpriv", "--bounding-set", "-sys_nice", FRANKY_PY, "-c", code],
                                 capture_output=True, text=True, timeout=120)
            report = json.loads(out.stdout.strip().splitlines()[-1])
        else:
            if mode.startswith("execute"):
                path = os.path.join(work, "q.csv")
                delta = [0.4, 0.2, -0.3, 0.3, 0.2, -0.2, 0.3]
                if mode == "execute --retime":
                    delta = [x / 2 for x in delta]
                quintic(path, HOME, delta, 4.0)
                argv = [cli, "franka", "execute", path, "--record", rec, "--approach"]
                if mode == "execute --retime":
                    argv.append("--retime")
            elif mode == "DMP online":
                path = os.path.join(work, "swing.csv")
                quintic(path, HOME, [0.3, 0, 0, 0.2, 0, 0, 0], 3.0)
                model_json = os.path.join(work, "swing.json")
                subprocess.run([cli, "imitate", path, "--columns", "q1,q2,q3,q4,q5,q6,q7", "--out",
                                model_json], check=True, capture_output=True)
                argv = [cli, "franka", "execute", model_json, "--record", rec]
            elif mode == "follow file":
                path = os.path.join(work, "chunks.csv")
                chunks(path, HOME)
                argv = [cli, "franka", "follow", path, "--rate", "50", "--record", rec]
            elif mode == "follow --listen":
                argv = [cli, "franka", "follow", "--listen", "127.0.0.1:7771", "--record", rec]
            elif mode == "identify":
                argv = [cli, "franka", "identify", "--out", os.path.join(work, "c.toml"), "--record", rec]
            elif mode == "guide":
                argv = [cli, "franka", "guide", "--duration", "2", "--out", rec]
            argv += common
            # Without the right to realtime scheduling (a normal kernel, no rtprio): the loop
            # at normal priority whatever it asks for, as most researchers run their arm.
            argv = ["setpriv", "--bounding-set", "-sys_nice"] + argv
            if mode == "follow --listen":
                follow = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
                subprocess.run([FRANKY_PY, os.path.join(ROOT, "python/examples/chunk_client.py"), "--to",
                                "127.0.0.1:7771", "--hz", "10", "--seconds", "3"], capture_output=True, timeout=60)
                stdout, _ = follow.communicate(timeout=60)
            else:
                stdout = subprocess.run(argv, capture_output=True, text=True, timeout=120).stdout
            report_path = rec[:-4] + ".report.json"
            report = json.load(open(report_path)) if os.path.exists(report_path) else json.loads(stdout)
        result["complete"] = bool(report.get("complete"))
        result["ending"] = report.get("ending", "")
        t = report.get("timing", {})
        for k in ["stale_states", "missed_ticks", "extrapolated_cycles", "dropped_commands",
                  "limited_commands", "withheld_answers", "applied_late", "p99_us"]:
            if k in t:
                result[k] = t[k]
        if "long_periods" in report:
            result["long_periods"] = report["long_periods"]
    except Exception as e:  # a run that failed to report is a failed run
        result["complete"] = False
        result["ending"] = f"no report: {e}"
    finally:
        franka_sim_peer.stop(server, log, hogs)
    text = open(os.path.join(work, "sim.log")).read()
    result["reflex"] = any(w in text for w in ("violated", "aborting the motion", "kReflexAborted"))
    result["sim"] = [line for line in text.splitlines() if "violated" in line][:1]
    print("RESULT " + json.dumps(result), flush=True)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cli", action="append", default=[], help="NAME=PATH of a cps-cli (repeat)")
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--modes", default=",".join(MODES))
    ap.add_argument("--sim-normal", action="store_true", help="franka-sim at normal priority too")
    ap.add_argument("--json", help="write every run here")
    ap.add_argument("--run-cli", help=argparse.SUPPRESS)
    ap.add_argument("--run-mode", help=argparse.SUPPRESS)
    ap.add_argument("--realtime", default="off", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.run_mode:
        return inner(args)
    rows, runs = [], []
    for spec in args.cli or [f"after={os.path.join(ROOT, 'target/checked/cps-cli')}"]:
        name, path = spec.split("=", 1)
        # `ignore`, without the right to SCHED_FIFO (see inner): normal priority.
        realtime = "ignore"
        for mode in args.modes.split(","):
            if mode == "pylibfranka" and rows and any(r[1] == "pylibfranka" for r in rows):
                continue
            results = []
            for _ in range(args.runs):
                cmd = ["unshare", "-n", "sh", "-c", 'ip link set lo up && exec "$0" "$@"', sys.executable,
                       os.path.abspath(__file__), "--run-cli", path, "--run-mode", mode, "--realtime", realtime]
                if args.sim_normal:
                    cmd.append("--sim-normal")
                out = subprocess.run(cmd, capture_output=True, text=True, timeout=300).stdout
                line = [x for x in out.splitlines() if x.startswith("RESULT ")]
                r = json.loads(line[-1][7:]) if line else {"complete": False, "reflex": True, "ending": "no result"}
                r["cli"] = name if mode != "pylibfranka" else "pylibfranka 0.21.3"
                results.append(r)
                runs.append(r)
                print(json.dumps(r), file=sys.stderr, flush=True)
            rows.append((r["cli"], mode, results))
    print("| cps-cli | mode | runs | ended by a reflex | cycles extrapolated | commands dropped | limited | "
          "stale states |")
    print("|---|---|---|---|---|---|---|---|")
    for name, mode, results in rows:
        def total(k):
            v = [r[k] for r in results if k in r]
            return str(sum(v)) if v else "—"
        reflexes = sum(1 for r in results if r.get("reflex") or not r.get("complete"))
        print(f"| {name} | {mode} | {len(results)} | {reflexes} | {total('extrapolated_cycles')} | "
              f"{total('dropped_commands')} | {total('limited_commands')} | {total('stale_states')} |")
    if args.json:
        json.dump(runs, open(args.json, "w"), indent=1)


if __name__ == "__main__":
    main()
