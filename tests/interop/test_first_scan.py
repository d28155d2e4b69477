#!/usr/bin/env python3
"""A new driver's first scan reaches the node at once.

A tracer driver that starts next to a running node sees the node's raw_scan subscription
within milliseconds (its publisher's subscription count turns 1) and publishes. The node
must have matched that publisher by then, or match it at once and have the scan repaired
(RTPS: the reader's preemptive ACKNACK, the writer's HEARTBEAT): a driver, or a test, that
publishes a plate scan and calls /calibrate right away must find it there.

One node runs throughout; an observer (this process's rclpy) subscribes to /contour and
checks the path once. Then TRIES times (default 50): a fresh peer process (rclpy, a DDS
participant of its own) creates a RawScan publisher (reliable, volatile: the node's
subscription's QoS), waits until its subscription count is 1, publishes one plate scan at
once and stays up; the time from that publish to the scan's corrected Contour at the
observer is the try's latency. Every try must be within LIMIT (100 ms). Late ones are
waited for up to 6 s so that the figures show how late they were.

- first_scan_fastdds: the peers on rmw_fastrtps_cpp (this process's environment);
- first_scan_cyclone: the peers on rmw_cyclonedds_cpp (target/ros/DISTRO/cyclone_env.sh,
  made by tests/interop/cyclone.sh; skipped with a message when it is missing);
- first_scan_call_fastdds, first_scan_call_cyclone: the same for a service client, CALL_TRIES
  (default 20) times: a fresh rclpy process calls /calibrate as soon as the service is
  ready; the answer must come within LIMIT (a client whose request comes before the node
  has matched its response reader must not wait for good, nor for a repair).

Run by tests/interop/run.sh with pytest (conftest.py) inside a private network namespace
(names `first_scan`, or the tests' above), with target/ros/DISTRO/env.sh sourced; this
file is also the peers' program (`--peer`, `--client`, `--stock-node`). Environment: FIRST_SCAN_TRIES (50),
FIRST_SCAN_LIMIT_MS (100), FIRST_SCAN_NODE=rclpy (for reference: a stock rclpy node on
Fast DDS in the node's place, answering each scan with an uncorrected Contour). Prints
the latency distribution of each test.
"""

import json
import os
import select
import subprocess
import sys
import time

import pytest

PEER_NAME = "first_scan_observer"  # conftest.py's peer
TRIES = int(os.environ.get("FIRST_SCAN_TRIES", "50"))
CALL_TRIES = int(os.environ.get("FIRST_SCAN_CALL_TRIES", "20"))
LIMIT = float(os.environ.get("FIRST_SCAN_LIMIT_MS", "100")) / 1000.0
WAIT_LATE = 6.0


def peer_main(plate_csv, scan_id):
    """The driver: a fresh participant, one publisher, one scan as soon as it is matched.
    Prints {"published": monotonic seconds} and stays up until stdin closes."""
    import rclpy
    from rclpy.node import Node
    from rclpy.qos import QoSProfile

    from tracer_calib_msgs.msg import RawScan

    steps, counts = [], []
    with open(plate_csv) as f:
        next(f)
        for line in f:
            s, c = line.strip().split(",")
            steps.append(int(s))
            counts.append(int(c))
    msg = RawScan()
    msg.header.frame_id = "tracer"
    msg.header.stamp.sec = 1700000000 + scan_id
    msg.scan_id = scan_id
    msg.target = RawScan.TARGET_CALIBRATION_PLATE
    msg.steps_per_revolution = 400
    msg.step = steps
    msg.counts = counts

    rclpy.init()
    node = Node(f"first_scan_driver_{scan_id}")
    pub = node.create_publisher(RawScan, "/raw_scan", QoSProfile(depth=10))
    t0 = time.monotonic()
    while pub.get_subscription_count() < 1:
        if time.monotonic() - t0 > 20:
            print(json.dumps({"error": "no subscription within 20 s"}), flush=True)
            return
        time.sleep(0.0005)
    published = time.monotonic()
    pub.publish(msg)
    print(json.dumps({"published": published, "matched_after": published - t0}), flush=True)
    # Stay up (the writer must be there to repair) until told to go.
    sys.stdin.read()
    node.destroy_node()
    rclpy.shutdown()


def client_main():
    """The client: a fresh participant, one /calibrate call as soon as the service is
    ready. Prints {"answer": seconds from the call to its answer, or null}."""
    import rclpy
    from rclpy.node import Node

    from tracer_calib_msgs.srv import Calibrate

    rclpy.init()
    node = Node("first_call_client")
    client = node.create_client(Calibrate, "/calibrate")
    t0 = time.monotonic()
    while not client.service_is_ready():
        if time.monotonic() - t0 > 20:
            print(json.dumps({"error": "no service within 20 s"}), flush=True)
            return
        rclpy.spin_once(node, timeout_sec=0.001)
    called = time.monotonic()
    future = client.call_async(Calibrate.Request(dry_run=True))
    while not future.done() and time.monotonic() - called < WAIT_LATE:
        rclpy.spin_once(node, timeout_sec=0.001)
    answered = time.monotonic() - called if future.done() else None
    print(json.dumps({"answer": answered, "ready_after": called - t0}), flush=True)


def stock_node_main():
    """FIRST_SCAN_NODE=rclpy: a stock rclpy node in the node's place, for reference. It
    subscribes to /raw_scan with the node's QoS (reliable, keep last 100) and answers
    each scan with a Contour carrying its scan_id (no correction)."""
    import rclpy
    from rclpy.node import Node
    from rclpy.qos import QoSProfile

    from tracer_calib_msgs.msg import Contour, RawScan

    rclpy.init()
    node = Node("tracer_calibrator")
    pub = node.create_publisher(Contour, "/contour", QoSProfile(depth=10))

    def on_scan(scan):
        c = Contour()
        c.header = scan.header
        c.scan_id = scan.scan_id
        pub.publish(c)

    node.create_subscription(RawScan, "/raw_scan", on_scan, QoSProfile(depth=100))
    rclpy.spin(node)


def first_scans(peer, env, label, scan_base):
    """TRIES fresh peers, one scan each: the latencies (seconds; None: never arrived)."""
    import harness as h
    import processes
    from tracer_calib_msgs.msg import Contour, RawScan

    arrivals = {}

    def on_contour(c):
        arrivals.setdefault(c.scan_id, time.monotonic())

    from rclpy.qos import QoSProfile

    sub = peer.node.create_subscription(Contour, "/contour", on_contour, QoSProfile(depth=100))
    try:
        # The observer's own path first: its contour subscription is matched both ways.
        pub = peer.publisher("/raw_scan")
        contours = peer.subscribe(Contour, "/contour")
        plate = h.simulate(f"first_scan_{label}", "plate", seed=7)
        peer.send_scan(pub, h.raw_scan(scan_base, RawScan.TARGET_CALIBRATION_PLATE, *plate), contours)
        peer.node.destroy_publisher(pub)
        csv = os.path.join(h.WORK, f"first_scan_{label}.csv")
        latencies = []
        for k in range(TRIES):
            scan_id = scan_base + 1 + k
            proc = subprocess.Popen(
                ["timeout", "-s", "KILL", "60", sys.executable, os.path.abspath(__file__), "--peer", csv, str(scan_id)],
                env=env,
                stdin=subprocess.PIPE,
                stdout=subprocess.PIPE,
                text=True,
            )
            try:
                line = ""
                deadline = time.monotonic() + 30
                while not line and time.monotonic() < deadline:
                    for n in h.RUNNING:
                        n.check_alive()
                    peer.executor.spin_once(timeout_sec=0.002)
                    if select.select([proc.stdout], [], [], 0)[0]:
                        line = proc.stdout.readline()
                        if not line:
                            raise AssertionError(f"try {k}: the peer exited ({proc.wait()})")
                assert line, f"try {k}: the peer did not publish within 30 s"
                info = json.loads(line)
                assert "published" in info, info
                published = info["published"]
                end = published + WAIT_LATE
                while scan_id not in arrivals and time.monotonic() < end:
                    peer.executor.spin_once(timeout_sec=0.002)
                got = arrivals.get(scan_id)
                latencies.append(None if got is None else got - published)
                shown = "lost" if got is None else f"{(got - published) * 1e3:.1f} ms"
                print(f"  {label} try {k + 1}: matched after {info['matched_after'] * 1e3:.1f} ms, contour {shown}", flush=True)
            finally:
                try:
                    proc.stdin.close()
                    proc.wait(timeout=5)
                except subprocess.TimeoutExpired:
                    processes.kill(proc)
        return latencies
    finally:
        peer.node.destroy_subscription(sub)


def first_calls(env, label):
    """CALL_TRIES fresh clients, one call each: the latencies (seconds; None: no answer)."""
    latencies = []
    for k in range(CALL_TRIES):
        out = subprocess.run(
            ["timeout", "-s", "KILL", "60", sys.executable, os.path.abspath(__file__), "--client"],
            env=env,
            capture_output=True,
            text=True,
        )
        lines = out.stdout.strip().splitlines()
        assert lines, f"call try {k}: the client printed nothing (exit {out.returncode}):\n{out.stderr[-2000:]}"
        info = json.loads(lines[-1])
        assert "answer" in info, info
        latencies.append(info["answer"])
        shown = "no answer" if info["answer"] is None else f"{info['answer'] * 1e3:.1f} ms"
        print(f"  {label} call {k + 1}: service ready after {info['ready_after'] * 1e3:.0f} ms, answer {shown}", flush=True)
    return latencies


def summarize(label, latencies):
    from harness import percentile

    got = [x for x in latencies if x is not None]
    in_time = sum(1 for x in got if x <= LIMIT)
    ms = [x * 1e3 for x in got]
    text = f"{in_time} of {len(latencies)} within {LIMIT * 1e3:.0f} ms"
    if ms:
        text += (
            f"; latency min {min(ms):.1f}, median {percentile(ms, 50):.1f}, p90 {percentile(ms, 90):.1f},"
            f" max {max(ms):.1f} ms"
        )
    late = sorted(x for x in ms if x > LIMIT * 1e3)
    if late:
        text += f"; {len(late)} late ({late[0]:.0f}-{late[-1]:.0f} ms)"
    if len(got) < len(latencies):
        text += f"; {len(latencies) - len(got)} not there after {WAIT_LATE:.0f} s"
    print(f"  {label}: {text}", flush=True)
    return in_time, text


@pytest.fixture(scope="module")
def envs():
    """This environment on each middleware (harness.peer_envs)."""
    import harness as h

    return h.peer_envs()


BY_RMW = [pytest.param("fastdds", id="fastdds", marks=pytest.mark.fastdds),
          pytest.param("cyclone", id="cyclone", marks=pytest.mark.cyclone)]


@pytest.mark.parametrize("rmw", BY_RMW)
def test_first_scan(peer, envs, rmw):
    """first_scan_fastdds, first_scan_cyclone (their scans' ids from 10000 and 20000)."""
    scan_base = {"fastdds": 10000, "cyclone": 20000}[rmw]
    import harness as h

    env = envs[rmw]
    if env is None:
        return "skipped: no cyclone_env.sh (tests/interop/cyclone.sh builds it)"
    if os.environ.get("FIRST_SCAN_NODE") == "rclpy":
        # Reference: a stock rclpy node (this environment's RMW) in the node's place.
        node = h.NodeProcess(f"first_scan_{rmw}", argv=[sys.executable, os.path.abspath(__file__), "--stock-node"])
    else:
        node = h.NodeProcess(f"first_scan_{rmw}", [])
    try:
        latencies = first_scans(peer, env, rmw, scan_base)
    finally:
        node.stop()
    in_time, text = summarize(rmw, latencies)
    assert in_time == len(latencies), text
    return text


@pytest.mark.parametrize("rmw", BY_RMW)
def test_call(envs, rmw):
    """first_scan_call_fastdds, first_scan_call_cyclone."""
    import harness as h

    env = envs[rmw]
    if env is None:
        return "skipped: no cyclone_env.sh (tests/interop/cyclone.sh builds it)"
    node = h.NodeProcess(f"first_call_{rmw}", [])
    try:
        time.sleep(1.0)  # the node up; each client then finds it as a new peer does
        latencies = first_calls(env, f"call {rmw}")
    finally:
        node.stop()
    in_time, text = summarize(f"call {rmw}", latencies)
    assert in_time == len(latencies), text
    return text


def main():
    if sys.argv[1:2] == ["--peer"]:
        peer_main(sys.argv[2], int(sys.argv[3]))
        os._exit(0)
    if sys.argv[1:2] == ["--client"]:
        client_main()
        os._exit(0)
    if sys.argv[1:2] == ["--stock-node"]:
        stock_node_main()
        os._exit(0)
    print("test_first_scan.py: run the tests with pytest (tests/interop/run.sh first_scan)", file=sys.stderr)
    os._exit(2)


if __name__ == "__main__":
    main()
