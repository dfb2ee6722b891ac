"""A policy in another process driving a robot through cps's chunk executor over UDP.

Start the executor on the robot, listening on loopback:

    cps-cli franka follow --listen 127.0.0.1:7771 --host 172.16.0.2 --record run.csv

then run this client. It stands in for a learned policy: it asks the executor for the
robot's state, "infers" for `--delay` seconds, and sends a chunk of 50 joint targets at
50 Hz predicted from that state (joint 1 swinging about where the arm stood), `--hz`
times a second, for `--seconds`; then it ends the stream, so the arm follows the last
chunk to its end and comes to rest. Replace `predict` with your policy.

The messages (little-endian; docs/policies.md has the table):
  CPS?                                   -> CPSS u32 n, f64 t, n x f64 q
  CPSC u32 n, u32 H, f64 rate, f64 observed_s, H*n x f64 targets
                                         -> CPSA u32 index | CPSR sentence
  CPSE                                   (end of stream)
Only numpy and the standard library.
"""

import argparse
import math
import socket
import struct
import time

import numpy as np

HORIZON = 50
TARGET_HZ = 50.0


def state(sock, executor):
    """The robot's time (s, the executor's clock) and joint positions."""
    sock.sendto(b"CPS?", executor)
    data, _ = sock.recvfrom(65536)
    if data[:4] != b"CPSS":
        raise RuntimeError(f"unexpected answer {data[:4]!r}")
    (n,) = struct.unpack_from("<I", data, 4)
    (t,) = struct.unpack_from("<d", data, 8)
    q = np.frombuffer(data, dtype="<f8", count=n, offset=16).copy()
    return t, q


def send_chunk(sock, executor, targets, observed_s, rate_hz=TARGET_HZ):
    """Sends a chunk (H x n targets, rad) predicted from the state at `observed_s`;
    returns the executor's answer: ("taken", index) or ("refused", sentence)."""
    targets = np.ascontiguousarray(targets, dtype="<f8")
    h, n = targets.shape
    head = b"CPSC" + struct.pack("<IIdd", n, h, rate_hz, observed_s)
    sock.sendto(head + targets.tobytes(), executor)
    data, _ = sock.recvfrom(65536)
    if data[:4] == b"CPSA":
        return "taken", struct.unpack_from("<I", data, 4)[0]
    return "refused", data[4:].decode("utf-8", "replace")


def wait_for_robot(sock, executor, seconds=20.0):
    """The first state once the executor listens and the robot's loop runs."""
    until = time.monotonic() + seconds
    while True:
        try:
            t, q = state(sock, executor)
            if not math.isnan(t):
                return t, q
        except (socket.timeout, ConnectionRefusedError):
            if time.monotonic() > until:
                raise RuntimeError(f"no executor answers at {executor[0]}:{executor[1]}")
        time.sleep(0.05)


def end_stream(sock, executor):
    sock.sendto(b"CPSE", executor)


def predict(q0, t0, t):
    """The stand-in policy: joint 1 swings 0.2 rad about q0 at 0.25 Hz from t0."""
    times = t + np.arange(HORIZON) / TARGET_HZ
    s = 0.5 - 0.5 * np.cos(math.pi / 2 * np.clip(times - t0, 0.0, None))
    targets = np.tile(q0, (HORIZON, 1))
    targets[:, 0] += 0.2 * s
    return targets


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--to", default="127.0.0.1:7771", help="the executor's address")
    p.add_argument("--bind", default="127.0.0.1", help="the address to send from")
    p.add_argument("--hz", type=float, default=10.0, help="chunks per second")
    p.add_argument("--seconds", type=float, default=4.0)
    p.add_argument("--delay", type=float, default=0.08, help="simulated inference (s)")
    a = p.parse_args()
    host, port = a.to.rsplit(":", 1)
    executor = (host, int(port))
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sock.bind((a.bind, 0))
    sock.settimeout(0.5)
    t0, q0 = wait_for_robot(sock, executor)
    taken = refused = 0
    start = time.monotonic()
    k = 0
    while time.monotonic() - start < a.seconds:
        t, _q = state(sock, executor)
        time.sleep(a.delay)  # inference
        answer, detail = send_chunk(sock, executor, predict(q0, t0, t), t)
        if answer == "taken":
            taken += 1
        else:
            refused += 1
            print(f"refused: {detail}")
        k += 1
        next_at = start + k / a.hz
        time.sleep(max(0.0, next_at - time.monotonic()))
    end_stream(sock, executor)
    print(f"{taken} chunks taken, {refused} refused")


if __name__ == "__main__":
    main()
