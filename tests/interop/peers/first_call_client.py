"""A new service client: a fresh participant, one /calibrate call (dry run) as soon as the
service is ready; the answer waited for up to WAIT seconds.

Run by test_first_scan.py as `python peers/first_call_client.py WAIT`. Prints one JSON line:
"answer" (seconds from the call to its answer; null: none within WAIT), "ready_after"
(seconds from the client's creation to the service ready), and the moments of the steps on
this machine's clocks, for a late answer to be set beside the node's log: "started" (the
program's first line, monotonic), "created" (the client made), "called", "called_wall"
(time.time(), the node's log's clock).
"""

import json
import os
import sys
import time

started = time.monotonic()

import rclpy  # noqa: E402
from rclpy.node import Node  # noqa: E402

from tracer_calib_msgs.srv import Calibrate  # noqa: E402


def main(wait):
    rclpy.init()
    node = Node("first_call_client")
    client = node.create_client(Calibrate, "/calibrate")
    created = time.monotonic()
    while not client.service_is_ready():
        if time.monotonic() - created > 20:
            print(json.dumps({"error": "no service within 20 s"}), flush=True)
            return
        rclpy.spin_once(node, timeout_sec=0.001)
    called_wall = time.time()
    called = time.monotonic()
    future = client.call_async(Calibrate.Request(dry_run=True))
    while not future.done() and time.monotonic() - called < wait:
        rclpy.spin_once(node, timeout_sec=0.001)
    answered = time.monotonic() - called if future.done() else None
    print(json.dumps({
        "answer": answered,
        "ready_after": called - created,
        "started": started,
        "created": created,
        "called": called,
        "called_wall": called_wall,
    }), flush=True)


if __name__ == "__main__":
    main(float(sys.argv[1]))
    os._exit(0)
