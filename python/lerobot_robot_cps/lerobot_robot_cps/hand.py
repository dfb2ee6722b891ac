"""A Franka Hand driven by LeRobot's actions.

A gripper command blocks until the fingers settle (a second or more), while LeRobot
calls `send_action` 30 times a second: the newest width asked for is kept, and a thread of
the hand's own moves the fingers to it when it differs from the last one commanded by
more than `TOLERANCE`; between commands the thread reads the fingers' width for the
observations. Closing is a grasp — the fingers stop on what they meet and hold it with
the force — opening a move.
"""

from __future__ import annotations

import logging
import threading

import cps

logger = logging.getLogger(__name__)

# The smallest change of the width asked for that moves the fingers (m).
TOLERANCE = 0.002
# How often the width is read while no command runs (s).
READ_PERIOD_S = 0.1


class Hand:
    """The hand of the Franka at `host` (see the module's text)."""

    def __init__(self, host: str, speed: float, force: float):
        self._franka = cps.Franka(host, realtime="ignore")
        self._speed, self._force = speed, force
        state = self._franka.gripper("state")
        if not state["max_width"] > 0.0:
            raise cps.CpsError(
                f"{host}: the hand's maximum width is unknown (it has not been homed since the robot "
                f"started): home it once with `cps-cli franka gripper home --host {host}`"
            )
        self.max_width = float(state["max_width"])
        self.width = float(state["width"])
        self._wanted: float | None = None
        self._done = False
        self._wake = threading.Condition()
        self._thread = threading.Thread(target=self._run, name="cps hand", daemon=True)
        self._thread.start()

    def want(self, width: float) -> float:
        """Asks for `width` (m), within [0, max_width]; returns that width."""
        width = min(max(float(width), 0.0), self.max_width)
        with self._wake:
            self._wanted = width
            self._wake.notify()
        return width

    def close(self) -> None:
        """Ends the thread once the running command has settled (the fingers keep what
        they hold)."""
        with self._wake:
            self._done = True
            self._wake.notify()
        self._thread.join()

    def _run(self) -> None:
        last: float | None = None

        def pending() -> bool:
            return self._wanted is not None and (last is None or abs(self._wanted - last) > TOLERANCE)

        while True:
            with self._wake:
                self._wake.wait_for(lambda: self._done or pending(), timeout=READ_PERIOD_S)
                if self._done:
                    return
                wanted = self._wanted if pending() else None
            try:
                if wanted is None:
                    state = self._franka.gripper("state")
                elif wanted < self.width - TOLERANCE:
                    # Any width within the hand's counts as grasped: the fingers stop on
                    # what they meet, or at the width asked for.
                    state = self._franka.gripper("grasp", wanted, speed=self._speed, force=self._force,
                                                 epsilon=self.max_width)
                else:
                    state = self._franka.gripper("move", wanted, speed=self._speed)
                if wanted is not None:
                    last = wanted
                self.width = float(state["width"])
            except cps.CpsError as e:
                logger.warning("the hand: %s", e)
                last = wanted if wanted is not None else last
                with self._wake:
                    self._wake.wait_for(lambda: self._done, timeout=1.0)
