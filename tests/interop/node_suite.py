#!/usr/bin/env python3
"""The node against one rclpy peer: test_node.py's tests, then test_records.py's, in one
process (one rclpy context, one DDS participant for the peer).

    python node_suite.py [TEST_NAME...]      (default: all; a leading `test_` is ignored)

Run by tests/interop/run.sh inside a private network namespace, with a distribution's
target/ros/DISTRO/env.sh sourced and TRACER_CALIB_NODE, TRACER_CALIB set. Prints one
line per test and a closing 'interop: N passed, N skipped, N failed'; after a failure, the node
logs stay in harness.WORK.
"""

import os
import sys

import rclpy

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import test_node  # noqa: E402
import test_records  # noqa: E402
from harness import WORK, Peer, run_tests  # noqa: E402


def main():
    rclpy.init()
    peer = Peer()
    tests = test_node.tests(peer) + test_records.tests(peer)
    only = [a.removeprefix("test_") for a in sys.argv[1:]]
    unknown = sorted(set(only) - {name for name, _ in tests})
    if unknown:
        print(f"interop: no such test: {', '.join(unknown)} (have: {', '.join(n for n, _ in tests)})", flush=True)
        os._exit(2)
    failed = run_tests(tests, only, "interop::", "interop")
    if failed == 0:
        import shutil

        shutil.rmtree(WORK, ignore_errors=True)
    sys.stdout.flush()
    # rclpy's shutdown can hang (docs/ros2-peer.md): leave without it.
    os._exit(0 if failed == 0 else 1)


if __name__ == "__main__":
    main()
