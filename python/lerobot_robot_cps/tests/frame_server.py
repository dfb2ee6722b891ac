"""A camera stand-in for the tests: synthetic frames served as LeRobot's ZMQ camera reads
them (`--robot.cameras="{front: {type: zmq, server_address: 127.0.0.1, port: P, ...}}"`):
a PUB socket sending `{"timestamps": {name: t}, "images": {name: <base64 JPEG>}}` at a
steady rate. The frame is a colour gradient whose phase moves with time, so a visuomotor
policy sees a changing scene.

    python frame_server.py --port 5555 --name front --width 64 --height 48 --fps 30
"""

import argparse
import base64
import json
import time

import cv2
import numpy as np
import zmq


def frame(t: float, width: int, height: int) -> np.ndarray:
    x = np.linspace(0.0, 1.0, width)[None, :, None]
    y = np.linspace(0.0, 1.0, height)[:, None, None]
    phase = np.array([0.0, 2.1, 4.2])[None, None, :]
    image = 127.5 * (1.0 + np.sin(2 * np.pi * (x + 0.5 * y) + phase + t))
    return image.astype(np.uint8)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--port", type=int, required=True)
    ap.add_argument("--name", default="front")
    ap.add_argument("--width", type=int, default=64)
    ap.add_argument("--height", type=int, default=48)
    ap.add_argument("--fps", type=float, default=30.0)
    args = ap.parse_args()
    socket = zmq.Context().socket(zmq.PUB)
    socket.bind(f"tcp://127.0.0.1:{args.port}")
    start = time.monotonic()
    k = 0
    while True:
        t = time.monotonic() - start
        ok, jpeg = cv2.imencode(".jpg", frame(t, args.width, args.height))
        assert ok
        socket.send_string(json.dumps({
            "timestamps": {args.name: time.time()},
            "images": {args.name: base64.b64encode(jpeg.tobytes()).decode()},
        }))
        k += 1
        time.sleep(max(0.0, start + k / args.fps - time.monotonic()))


if __name__ == "__main__":
    main()
