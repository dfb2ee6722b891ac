"""cps's chunk executor in a process of its own, beside LeRobot's.

The executor's 1 kHz loop is a thread of the process that opens it. In the process of a
LeRobot script it shares one memory map with torch, whose threads map and unmap memory
all the time: the loop, at a realtime priority, then waits at times on the memory map's
lock held by a thread that a busy core has preempted, and a Franka counts the lost cycles
(under two CPU hogs franka-sim ended a motion for it twice in about 30 runs). Here the
loop runs in a child process that imports only cps and numpy, and the robot talks to it
over a socket: a call and its answer take a fraction of a millisecond.

The child ignores Ctrl-C (the terminal sends it to the whole process group; LeRobot's
script handles it and disconnects, which closes the executor) and, when its parent dies
without closing it, closes the executor itself: the arm brakes to rest and the recording
is written.

Run as a script (`python process.py FD`) it is the child; imported, `LoopProcess` starts
one.
"""

from __future__ import annotations

import os
import signal
import socket
import subprocess
import sys
import threading
from multiprocessing.connection import Connection
from typing import Any

import cps

# How long the child may take to open the robot (a Franka's connection, the model).
START_TIMEOUT_S = 60.0
# How long close waits for the child once the executor has been closed.
EXIT_TIMEOUT_S = 10.0


class LoopGone(cps.CpsError):
    """The child process ended (killed, or crashed) while the robot was connected."""


class LoopProcess:
    """A `cps.ChunkExecutor` opened with `kwargs` in a child process: `observe`, `push`,
    `running` and `close` as the executor's own, its errors raised here as they were
    raised there."""

    def __init__(self, kwargs: dict[str, Any]):
        ours, theirs = socket.socketpair()
        self._proc = subprocess.Popen(
            # -P: the script's folder (this package's) stays off the child's import path.
            [sys.executable, "-P", os.path.abspath(__file__), str(theirs.fileno())],
            pass_fds=[theirs.fileno()], start_new_session=True, stdin=subprocess.DEVNULL,
        )
        theirs.close()
        self._conn = Connection(ours.detach())
        self._closed: dict[str, Any] | None = None
        # One call at a time (LeRobot may observe and act from two threads); each numbered,
        # so that an answer a Ctrl-C left unread is never taken for the next call's.
        self._lock = threading.Lock()
        self._seq = 0
        try:
            self._conn.send((0, "start", (), kwargs))
            if not self._conn.poll(START_TIMEOUT_S):
                raise cps.CpsError(f"the robot's loop process did not start within {START_TIMEOUT_S:.0f} s")
            self._answer(0)
        except (EOFError, OSError):
            self._kill()
            raise LoopGone(
                f"the robot's loop process ended before it started (exit status {self._proc.returncode})"
            ) from None
        except BaseException:
            self._kill()
            raise

    def observe(self) -> dict[str, Any]:
        """The executor's `observe()`."""
        return self._call("observe")

    def push(self, targets: Any, **kwargs: Any) -> Any:
        """The executor's `push(targets, observed_at=..., rate=...)`."""
        return self._call("push", targets, **kwargs)

    @property
    def running(self) -> bool:
        """Whether the executor's loop still runs (False once the child has gone)."""
        if self._closed is not None or self._proc.poll() is not None:
            return False
        return self._call("running")

    def close(self) -> dict[str, Any]:
        """The executor's `close()`: the arm comes to rest, the recording is written; then
        the child exits."""
        if self._closed is None:
            try:
                self._closed = self._call("close")
            except LoopGone as e:
                # Nothing to close: the process had ended (its recording, if it wrote one,
                # is where it was asked to be).
                self._closed = {"ending": str(e), "record": None, "lines": [], "report": None}
            finally:
                try:
                    self._proc.wait(EXIT_TIMEOUT_S)
                except subprocess.TimeoutExpired:
                    self._kill()
                self._conn.close()
        return self._closed

    def _call(self, op: str, *args: Any, **kwargs: Any) -> Any:
        try:
            with self._lock:
                self._seq += 1
                self._conn.send((self._seq, op, args, kwargs))
                return self._answer(self._seq)
        except (EOFError, OSError):
            try:
                code = self._proc.wait(EXIT_TIMEOUT_S)
            except subprocess.TimeoutExpired:
                self._kill()
                code = self._proc.returncode
            raise LoopGone(f"the robot's loop process ended (exit status {code})") from None

    def _answer(self, seq: int) -> Any:
        while True:
            n, kind, value = self._conn.recv()
            if n == seq:
                break
        if kind == "error":
            raise value
        return value

    def _kill(self) -> None:
        if self._proc.poll() is None:
            self._proc.kill()
            self._proc.wait()
        self._conn.close()


def _serve(fd: int) -> None:
    """The child: opens the executor, then answers calls until `close` or its parent's end."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    conn = Connection(fd)

    def reply(seq, call):
        try:
            conn.send((seq, "ok", call()))
        except Exception as e:  # noqa: BLE001 - every error goes back to the caller
            try:
                conn.send((seq, "error", e))
            except Exception:  # noqa: BLE001 - an error that does not pickle: its words
                conn.send((seq, "error", cps.CpsError(f"{type(e).__name__}: {e}")))

    executor = None

    def start(kwargs):
        nonlocal executor
        executor = cps.ChunkExecutor(**kwargs)

    seq, _, _, kwargs = conn.recv()
    reply(seq, lambda: start(kwargs))
    if executor is None:
        return
    calls = {
        "observe": lambda: executor.observe(),
        "push": lambda *a, **k: executor.push(*a, **k),
        "running": lambda: executor.running,
        "close": lambda: executor.close(),
    }
    while True:
        try:
            seq, op, args, kwargs = conn.recv()
        except (EOFError, OSError):
            # The parent is gone without closing: the arm brakes, the recording is written.
            executor.close()
            return
        reply(seq, lambda: calls[op](*args, **kwargs))
        if op == "close":
            return


if __name__ == "__main__":
    _serve(int(sys.argv[1]))
