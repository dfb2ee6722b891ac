"""Latency of a well-behaved client (the official CoppeliaSim Python client) against
`cps-cli sim serve`, alone and while other peers pipeline requests without reading
replies; then the server's peak memory while peers declare 64 GiB frames.

    python3 -m venv target/bench-python
    target/bench-python/bin/pip install coppeliasim-zmqremoteapi-client==2.0.4 cbor
    cargo build --release -p cps-cli
    target/bench-python/bin/python benches/sim_serve_flood.py target/release/cps-cli

Every address is loopback; each load is bounded (2 000 calls, 50 peers) and stops by itself.
"""
import socket, struct, subprocess, sys, threading, time, statistics, re
import cbor
from coppeliasim_zmqremoteapi_client import RemoteAPIClient

BIN = sys.argv[1]
srv = subprocess.Popen([BIN, "sim", "serve", "--bind", "127.0.0.1:0"], stdout=subprocess.PIPE, text=True)
line = srv.stdout.readline()
port = int(re.search(r"127\.0\.0\.1:(\d+)", line).group(1))

def rss_kib(kind="VmHWM"):
    for l in open(f"/proc/{srv.pid}/status"):
        if l.startswith(kind):
            return int(l.split()[1])

def raw_peer():
    s = socket.create_connection(("127.0.0.1", port))
    g = bytearray(64); g[0] = 0xFF; g[9] = 0x7F; g[10] = 3; g[12:16] = b"NULL"
    s.sendall(bytes(g))
    ready = b"\x05READY" + bytes([11]) + b"Socket-Type" + struct.pack(">I", 3) + b"REQ"
    s.sendall(bytes([0x04, len(ready)]) + ready)
    s.recv(64 + 2 + 64)
    return s

def measure(client, n):
    sim = client.require("sim")
    lat = []
    for _ in range(n):
        t = time.perf_counter()
        sim.getSimulationTime()
        lat.append(time.perf_counter() - t)
    return lat

client = RemoteAPIClient("127.0.0.1", port)
base = measure(client, 2000)

stop = False
def flood():
    s = raw_peer()
    s.setblocking(False)
    body = cbor.dumps({"func": "sim.getSimulationTime", "args": [], "uuid": "flood"})
    msg = bytes([0x01, 0x00, 0x00, len(body)]) + body
    chunk = msg * 200
    sent = 0
    while not stop:
        try:
            sent += s.send(chunk)
        except BlockingIOError:
            time.sleep(0.0005)
    s.close()
floods = [threading.Thread(target=flood) for _ in range(4)]
for f in floods: f.start()
time.sleep(0.5)
flooded = measure(client, 2000)
stop = True
for f in floods: f.join()

def show(name, lat):
    lat_ms = sorted(x * 1e3 for x in lat)
    print(f"{name}: median {statistics.median(lat_ms):.3f} ms, p99 {lat_ms[int(0.99*len(lat_ms))]:.3f} ms, worst {lat_ms[-1]:.3f} ms over {len(lat_ms)} calls")
show("alone", base)
show("4 flooding peers", flooded)

before = rss_kib()
peers = []
for _ in range(50):
    s = raw_peer()
    s.sendall(bytes([0x02]) + struct.pack(">Q", 64 << 30))
    peers.append(s)
time.sleep(0.5)
ok = measure(client, 100)
after = rss_kib()
print(f"peak RSS before the huge frames {before/1024:.1f} MiB, after 50 peers declared 64 GiB frames {after/1024:.1f} MiB; server still answering ({len(ok)} calls)")
srv.terminate(); srv.wait()
print(srv.stdout.read().strip())
