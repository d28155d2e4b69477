#!/usr/bin/env python3
"""Smoke test of the real ROS 2 peer toolchain (rclpy + tracer_calib_msgs).

Run it with target/ros/env.sh sourced (tests/interop/setup.sh writes it), inside
tests/interop/netns.sh and under `timeout -s KILL`; tests/interop/run_smoke.sh does
all of that.

Roles:
  self (default)  one process: publishes a tracer_calib_msgs/msg/RawScan and receives
                  it on a subscription, serves tracer_calib_msgs/srv/Calibrate and
                  calls it once.
  pub / sub       the topic half in two processes: `pub` publishes until a subscriber
                  has matched and then for --linger seconds; `sub` waits for one
                  correct message.
  server / client the service half in two processes: `server` answers until it has
                  served one call and --linger seconds passed; `client` calls once.

Prints one line `smoke[ROLE]: PASS ...` or `smoke[ROLE]: FAIL ...` and exits 0 or 1.
The process ends with os._exit after a bounded shutdown, because rclpy's
destroy_node() occasionally hangs.
"""

import argparse
import os
import sys
import threading
import time


def log(role, text):
    print(f"smoke[{role}]: {text}", flush=True)


def make_scan(RawScan, scan_id):
    msg = RawScan()
    msg.header.frame_id = "tracer"
    msg.header.stamp.sec = 1_700_000_000
    msg.header.stamp.nanosec = 123_456_789
    msg.scan_id = scan_id
    msg.target = RawScan.TARGET_CALIBRATION_PLATE
    msg.steps_per_revolution = 400
    msg.step = list(range(0, 400, 1))
    msg.counts = [20_000 + 7 * i - 3_000 * (i % 2) for i in range(400)]
    return msg


def scan_ok(RawScan, msg, scan_id=None):
    ref = make_scan(RawScan, msg.scan_id if scan_id is None else scan_id)
    return (
        msg.scan_id == ref.scan_id
        and msg.header.frame_id == ref.header.frame_id
        and msg.header.stamp.sec == ref.header.stamp.sec
        and msg.header.stamp.nanosec == ref.header.stamp.nanosec
        and msg.target == ref.target
        and msg.steps_per_revolution == ref.steps_per_revolution
        and list(msg.step) == list(ref.step)
        and list(msg.counts) == list(ref.counts)
    )


def fill_response(request, response):
    response.success = True
    response.message = f"smoke fit of scan {request.scan_id} (dry_run={request.dry_run})"
    response.alpha0 = 0.0349
    response.offset = 1.5e-3
    response.delta_l = -2.5e-4
    response.stddev = [1e-5, 2e-7, 3e-7]
    response.rms_residual = 4.2e-6
    response.iterations = 7
    response.samples_used = 400
    return response


def response_ok(request, response):
    return (
        response.success
        and response.message == f"smoke fit of scan {request.scan_id} (dry_run={request.dry_run})"
        and response.alpha0 == 0.0349
        and response.offset == 1.5e-3
        and response.delta_l == -2.5e-4
        and list(response.stddev) == [1e-5, 2e-7, 3e-7]
        and response.rms_residual == 4.2e-6
        and response.iterations == 7
        and response.samples_used == 400
    )


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("role", nargs="?", default="self", choices=["self", "pub", "sub", "server", "client"])
    ap.add_argument("--timeout", type=float, default=20.0, help="seconds for the whole test (default 20)")
    ap.add_argument("--linger", type=float, default=2.0, help="pub/server: seconds to go on after success")
    ap.add_argument("--topic", default="smoke_raw_scan")
    ap.add_argument("--service", default="smoke_calibrate")
    args = ap.parse_args()
    role = args.role
    deadline = time.monotonic() + args.timeout

    def left():
        return max(0.0, deadline - time.monotonic())

    try:
        import rclpy
        from rclpy.executors import SingleThreadedExecutor
        from rclpy.qos import QoSProfile, ReliabilityPolicy, DurabilityPolicy, HistoryPolicy
        from tracer_calib_msgs.msg import RawScan
        from tracer_calib_msgs.srv import Calibrate
    except Exception as exc:  # noqa: BLE001
        log(role, f"FAIL import: {exc!r} (is target/ros/env.sh sourced?)")
        return 1

    rclpy.init()
    node = rclpy.create_node(f"smoke_{role}")
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    qos = QoSProfile(
        history=HistoryPolicy.KEEP_LAST,
        depth=10,
        reliability=ReliabilityPolicy.RELIABLE,
        durability=DurabilityPolicy.VOLATILE,
    )
    result = {"ok": False, "why": "timed out"}
    received = []
    served = []

    def on_scan(msg):
        received.append(msg)

    def on_calibrate(request, response):
        served.append(request)
        return fill_response(request, response)

    def spin_until(cond, limit):
        end = time.monotonic() + limit
        while not cond() and time.monotonic() < end:
            executor.spin_once(timeout_sec=0.05)
        return cond()

    try:
        if role in ("self", "sub"):
            node.create_subscription(RawScan, args.topic, on_scan, qos)
        if role in ("self", "server"):
            node.create_service(Calibrate, args.service, on_calibrate)
        pub = node.create_publisher(RawScan, args.topic, qos) if role in ("self", "pub") else None
        cli = node.create_client(Calibrate, args.service) if role in ("self", "client") else None

        topic_ok = service_ok = True
        if role in ("self", "pub", "sub"):
            topic_ok = False
            if pub is not None:
                if not spin_until(lambda: pub.get_subscription_count() > 0, left()):
                    raise TimeoutError("no subscription matched the publisher")
            t_match = time.monotonic()
            scan_id = 1
            next_pub = 0.0
            while left() > 0:
                if pub is not None and time.monotonic() >= next_pub:
                    pub.publish(make_scan(RawScan, scan_id))
                    scan_id += 1
                    next_pub = time.monotonic() + 0.1
                executor.spin_once(timeout_sec=0.02)
                if received:
                    if not all(scan_ok(RawScan, m) for m in received):
                        raise AssertionError(f"received a RawScan that differs: {received[0]}")
                    topic_ok = True
                    if role != "pub":
                        break
                if role == "pub" and time.monotonic() - t_match >= args.linger:
                    topic_ok = True
                    break
            if not topic_ok:
                raise TimeoutError("no RawScan received")

        if role in ("self", "server", "client"):
            service_ok = False
            if cli is not None:
                if not cli.wait_for_service(timeout_sec=left()):
                    raise TimeoutError(f"service {args.service} not available")
                req = Calibrate.Request()
                req.scan_id = 42
                req.dry_run = True
                future = cli.call_async(req)
                if not spin_until(future.done, left()):
                    raise TimeoutError("no answer to the Calibrate call")
                resp = future.result()
                if not response_ok(req, resp):
                    raise AssertionError(f"unexpected Calibrate response: {resp}")
                service_ok = True
            if role == "server":
                if not spin_until(lambda: bool(served), left()):
                    raise TimeoutError("no Calibrate call served")
                spin_until(lambda: False, min(args.linger, left()))
                service_ok = True
            elif role == "self" and not served:
                raise AssertionError("client got an answer but the server saw no call")

        result = {"ok": topic_ok and service_ok, "why": ""}
    except Exception as exc:  # noqa: BLE001
        result = {"ok": False, "why": f"{type(exc).__name__}: {exc}"}

    detail = f"received={len(received)} served={len(served)}"
    if result["ok"]:
        log(role, f"PASS ({detail})")
    else:
        log(role, f"FAIL {result['why']} ({detail})")
    sys.stdout.flush()
    sys.stderr.flush()

    # Bounded clean shutdown (frees Fast DDS resources, tells peers we left).
    def shutdown():
        try:
            executor.shutdown(timeout_sec=1.0)
            node.destroy_node()
            rclpy.shutdown()
        except Exception:  # noqa: BLE001
            pass

    t = threading.Thread(target=shutdown, daemon=True)
    t.start()
    t.join(3.0)
    if t.is_alive():
        print(f"smoke[{role}]: note: shutdown hung, exiting anyway", file=sys.stderr, flush=True)
    os._exit(0 if result["ok"] else 1)


if __name__ == "__main__":
    sys.exit(main())
