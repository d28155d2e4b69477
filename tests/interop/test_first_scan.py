#!/usr/bin/env python3
"""A new driver's first scan reaches the node at once.

A tracer driver that starts next to a running node sees the node's raw_scan subscription
within milliseconds (its publisher's subscription count turns 1) and publishes. The node
must have matched that publisher by then, or match it at once and have the scan repaired
(RTPS: the reader's preemptive ACKNACK, the writer's HEARTBEAT): a driver, or a test, that
publishes a plate scan and calls /calibrate right away must find it there.

One node runs throughout; an observer (this process's rclpy) subscribes to /contour and
checks the path once. Then TRIES times (default 50): a fresh peer process
(peers/first_scan_driver.py: rclpy, a DDS participant of its own) creates a RawScan publisher (reliable, volatile: the node's
subscription's QoS), waits until its subscription count is 1, publishes one plate scan at
once and stays up; the time from that publish to the scan's corrected Contour at the
observer is the try's latency. Every try must be within LIMIT (100 ms). Late ones are
waited for up to 6 s so that the figures show how late they were.

- first_scan_fastdds: the peers on rmw_fastrtps_cpp (this process's environment);
- first_scan_cyclone: the peers on rmw_cyclonedds_cpp (target/ros/DISTRO/cyclone_env.sh,
  made by tests/interop/cyclone.sh; skipped with a message when it is missing);
- first_scan_call_fastdds, first_scan_call_cyclone: the same for a service client, CALL_TRIES
  (default 20) times: a fresh rclpy process (peers/first_call_client.py) calls /calibrate
  as soon as the service is ready; the answer must come within LIMIT (a client whose
  request comes before the node has matched its response reader must not wait for good,
  nor for a repair). The node logs how long each response waited for its client's
  response reader; a late answer's report shows those lines and the client's steps.

Run by tests/interop/run.sh with pytest (conftest.py) inside a private network namespace
(names `first_scan`, or the tests' above), with target/ros/DISTRO/env.sh sourced. Environment: FIRST_SCAN_TRIES (50),
FIRST_SCAN_CALL_TRIES (20), FIRST_SCAN_LIMIT_MS (100), FIRST_SCAN_NODE=rclpy (for
reference: a stock rclpy node on Fast DDS in the node's place,
peers/first_scan_stock_node.py, answering each scan with an uncorrected Contour). Prints
the latency distribution of each test.
"""

import json
import os
import select
import subprocess
import sys
import time
from datetime import datetime, timezone

import pytest
from rclpy.qos import QoSProfile

import harness as h
import processes
from tracer_calib_msgs.msg import Contour, RawScan

PEER_NAME = "first_scan_observer"  # conftest.py's peer
TRIES = int(os.environ.get("FIRST_SCAN_TRIES", "50"))
CALL_TRIES = int(os.environ.get("FIRST_SCAN_CALL_TRIES", "20"))
LIMIT = float(os.environ.get("FIRST_SCAN_LIMIT_MS", "100")) / 1000.0
WAIT_LATE = 6.0


def first_scans(peer, env, label, scan_base):
    """TRIES fresh peers, one scan each: the latencies (seconds; None: never arrived)."""
    arrivals = {}

    def on_contour(c):
        arrivals.setdefault(c.scan_id, time.monotonic())

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
                ["timeout", "-s", "KILL", "60", sys.executable, processes.peer_program("first_scan_driver"), csv, str(scan_id)],
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


def first_calls(env, label, node):
    """CALL_TRIES fresh clients, one call each: the latencies (seconds; None: no answer).
    A late answer's report: the client's steps and the node's log lines about responses."""
    latencies = []
    for k in range(CALL_TRIES):
        out = subprocess.run(
            ["timeout", "-s", "KILL", "60", sys.executable, processes.peer_program("first_call_client"), str(WAIT_LATE)],
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
        if info["answer"] is None or info["answer"] > LIMIT:
            print(f"  {label} call {k + 1} was late: started {info['started']:.4f}, client made"
                  f" {info['created']:.4f}, called {info['called']:.4f} (monotonic s), called at"
                  f" {time.strftime('%H:%M:%S', time.gmtime(info['called_wall']))}"
                  f".{int(info['called_wall'] % 1 * 1e6):06d} UTC; the node's log on requests and responses:", flush=True)
            for line in node_lines_near(node, info["called_wall"], info["answer"] or WAIT_LATE):
                print(f"    {line}", flush=True)
    return latencies


def node_lines_near(node, wall, seconds):
    """The node's log lines on requests and responses stamped from 0.1 s before `wall`
    (time.time()) to 0.1 s after `wall + seconds` (env_logger's "[2026-12-08T02:13:05.871688Z")."""
    near = []
    for line in node.output().splitlines():
        if "request" not in line and "response" not in line:
            continue
        try:
            stamp = datetime.strptime(line[1:28], "%Y-%m-%dT%H:%M:%S.%fZ").replace(tzinfo=timezone.utc).timestamp()
        except ValueError:
            continue
        if wall - 0.1 <= stamp <= wall + seconds + 0.1:
            near.append(line)
    return near


def summarize(label, latencies):
    got = [x for x in latencies if x is not None]
    in_time = sum(1 for x in got if x <= LIMIT)
    ms = [x * 1e3 for x in got]
    text = f"{in_time} of {len(latencies)} within {LIMIT * 1e3:.0f} ms"
    if ms:
        text += (
            f"; latency min {min(ms):.1f}, median {h.percentile(ms, 50):.1f}, p90 {h.percentile(ms, 90):.1f},"
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
    return h.peer_envs()


BY_RMW = [pytest.param("fastdds", id="fastdds", marks=pytest.mark.fastdds),
          pytest.param("cyclone", id="cyclone", marks=pytest.mark.cyclone)]


@pytest.mark.parametrize("rmw", BY_RMW)
def test_first_scan(peer, envs, rmw):
    """first_scan_fastdds, first_scan_cyclone (their scans' ids from 10000 and 20000)."""
    scan_base = {"fastdds": 10000, "cyclone": 20000}[rmw]
    env = envs[rmw]
    if env is None:
        return "skipped: no cyclone_env.sh (tests/interop/cyclone.sh builds it)"
    if os.environ.get("FIRST_SCAN_NODE") == "rclpy":
        # Reference: a stock rclpy node (this environment's RMW) in the node's place.
        node = h.NodeProcess(f"first_scan_{rmw}", argv=[sys.executable, processes.peer_program("first_scan_stock_node")])
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
    """first_scan_call_fastdds, first_scan_call_cyclone (the node logs each response's wait
    for its client's response reader)."""
    env = envs[rmw]
    if env is None:
        return "skipped: no cyclone_env.sh (tests/interop/cyclone.sh builds it)"
    node = h.NodeProcess(f"first_call_{rmw}", [], log_filters="ros2_client::service::server=debug")
    try:
        time.sleep(1.0)  # the node up; each client then finds it as a new peer does
        latencies = first_calls(env, f"call {rmw}", node)
    finally:
        node.stop()
    in_time, text = summarize(f"call {rmw}", latencies)
    assert in_time == len(latencies), text
    return text


