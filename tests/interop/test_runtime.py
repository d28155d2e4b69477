#!/usr/bin/env python3
"""tracer_calib_node's runtime contract with stock rclpy peers (issue 21): simulated time,
parameter descriptors, and the `-p` rules as rcl reads them.

Run by tests/interop/run.sh inside a private network namespace, with the distribution's
peer environment (target/ros/DISTRO/env.sh). Prints one line per test.

- sim_time: an rclpy /clock (rosgraph_msgs/msg/Clock) from 5000 s; the node, started with
  `-p use_sim_time:=true`, stamps /diagnostics, rosout and the `calibration` message with
  that clock, and its history record keeps that ROS time beside the system time; a clock
  that jumps back moves the node's time back, and it serves on.
- sim_time_no_clock: `use_sim_time: true` in the params file and no /clock: the node's
  time stands at 0, it answers /calibrate, and /diagnostics warns within a few seconds.
- replay_clock: `tracer_calib replay --clock` of a simulated bag drives a node on sim time:
  a calibration stamped within the bag's time.
- describe: every parameter described (description, ranges as rcl_interfaces has them,
  read_only), with `ros2 param describe` too where tests/interop/ros2cli.sh installed it;
  a set outside a range or of a read-only parameter refused with rclcpp's reason;
  the README's `-p qos_overrides./raw_scan.subscription.reliability:=best_effort` starts
  the node.
- rcl_param_rules: tests/data/rcl_param_rules.json (what the Rust tests check our parser
  against) is what rcl itself reads, through rclpy: each rule taken or refused as the file
  says, with the name, type and value it gives.
"""

import json
import math
import os
import shutil
import subprocess
import sys
import time

import rclpy
from rclpy.context import Context
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import QoSProfile, qos_profile_sensor_data

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from rcl_interfaces.msg import Log, ParameterType
from rosgraph_msgs.msg import Clock
from tracer_calib_msgs.msg import Calibration, Contour, RawScan
from tracer_calib_msgs.srv import Calibrate
from builtin_interfaces.msg import Time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import harness as h  # noqa: E402

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


def seconds(stamp):
    return stamp.sec + stamp.nanosec * 1e-9


class SimClock:
    """/clock from rclpy, as a simulator or `ros2 bag play --clock` publishes it: `start`
    seconds, advancing with the system clock, published every 25 ms while spun."""

    def __init__(self, peer, start):
        self.peer = peer
        self.pub = peer.node.create_publisher(Clock, "/clock", qos_profile_sensor_data)
        self.set(start)
        self.timer = peer.node.create_timer(0.025, self.tick)

    def set(self, start):
        self.start, self.t0 = start, time.monotonic()

    def now(self):
        return self.start + (time.monotonic() - self.t0)

    def tick(self):
        t = self.now()
        self.pub.publish(Clock(clock=Time(sec=int(t), nanosec=int((t % 1) * 1e9))))

    def close(self):
        self.peer.node.destroy_timer(self.timer)
        self.peer.node.destroy_publisher(self.pub)


def diag_of(msgs, node_fqn):
    """The node's statuses among DiagnosticArrays received."""
    return [(m.header.stamp, s) for m in msgs for s in m.status if s.name == f"tracer_calib: {node_fqn}"]


def value(status, key):
    return next(kv.value for kv in status.values if kv.key == key)


def test_sim_time(peer):
    history = os.path.join(h.WORK, "sim_time.history.jsonl")
    node = h.NodeProcess(
        "sim_time",
        ["-r", "__node:=sim_tracer", "-p", "use_sim_time:=true", "-p", f"history_file:={history}"],
    )
    clock = SimClock(peer, 5000.0)
    try:
        diags = peer.subscribe(DiagnosticArray, "/diagnostics")
        logs = peer.subscribe(Log, "/rosout")
        latched = QoSProfile(depth=1, durability=1)  # transient local, as the node publishes it
        calibrations = []
        peer.node.create_subscription(Calibration, "calibration", calibrations.append, latched)
        # /diagnostics stamped with the sim clock once the node has it.
        peer.spin_until(lambda: any(seconds(s) >= 5000 for s, _ in diag_of(diags, "/sim_tracer")), 20, "a sim-time /diagnostics")
        stamp, status = next((s, st) for s, st in diag_of(diags, "/sim_tracer") if seconds(s) >= 5000)
        assert seconds(stamp) <= clock.now() + 0.1, (seconds(stamp), clock.now())
        assert value(status, "use_sim_time") == "true", status
        # A plate scan, a calibration: its message and rosout record stamped with the clock.
        contours = peer.subscribe(Contour, "contour")
        steps, counts = h.simulate("sim_plate", "plate", seed=31)
        peer.send_scan(peer.publisher("raw_scan"), h.raw_scan(31, RawScan.TARGET_CALIBRATION_PLATE, steps, counts), contours)
        before = clock.now()
        r = peer.call("/calibrate", Calibrate.Request(scan_id=31))
        after = clock.now()
        assert r.success, r.message
        peer.spin_until(lambda: any(c.scan_id == 31 for c in calibrations), 10, "the calibration message")
        cal = next(c for c in calibrations if c.scan_id == 31)
        assert before - 0.2 <= seconds(cal.header.stamp) <= after + 0.1, (before, seconds(cal.header.stamp), after)
        peer.spin_until(lambda: any(l.name == "sim_tracer" and "calibrate:" in l.msg for l in logs), 10, "the rosout record")
        log = next(l for l in logs if l.name == "sim_tracer" and "calibrate:" in l.msg)
        assert before - 0.2 <= seconds(log.stamp) <= after + 0.1, (before, seconds(log.stamp), after)
        with open(history) as f:
            record = json.loads(f.read().splitlines()[-1])
        assert record["ros_time"]["sec"] == cal.header.stamp.sec, record
        assert record["time"].startswith(time.strftime("%Y-", time.gmtime())), record  # the system's time
        # The clock jumps back to 100 s: the node's time follows, and it serves on.
        clock.set(100.0)
        n = len(diags)
        peer.spin_until(
            lambda: any(seconds(s) < 200 for s, _ in diag_of(diags[n:], "/sim_tracer")), 10, "a /diagnostics after the jump back"
        )
        assert peer.call("/calibrate", Calibrate.Request(scan_id=31, dry_run=True)).success
        node.check_alive()
    finally:
        clock.close()
        node.stop()
    return f"stamps at {seconds(cal.header.stamp):.2f} s of a clock from 5000 s; back to 100 s served"


def test_sim_time_no_clock(peer):
    params = h.params_file(
        "no_clock", "lonely_tracer:\n  ros__parameters:\n    use_sim_time: true\n    plate.side: 0.045\n"
    )
    node = h.NodeProcess("sim_time_no_clock", ["-r", "__node:=lonely_tracer", "--params-file", params])
    try:
        diags = peer.subscribe(DiagnosticArray, "/diagnostics")
        peer.spin_until(lambda: diag_of(diags, "/lonely_tracer"), 20, "/diagnostics")
        t0 = time.monotonic()
        r = peer.call("/calibrate", Calibrate.Request())
        assert not r.success and "no calibration-plate scan" in r.message, r.message
        peer.spin_until(
            lambda: any("no /clock" in s.message for _, s in diag_of(diags, "/lonely_tracer")), 10, "the no-/clock warning"
        )
        stamp, status = next((s, st) for s, st in diag_of(diags, "/lonely_tracer") if "no /clock" in st.message)
        assert status.level == DiagnosticStatus.WARN and seconds(stamp) == 0.0, (status.level, stamp)
        waited = time.monotonic() - t0
        pc = peer.param_client("/lonely_tracer")
        got = peer.param(lambda: pc.get_parameters(["use_sim_time"])).values[0]
        assert got.type == ParameterType.PARAMETER_BOOL and got.bool_value, got
    finally:
        node.stop()
    return f"time 0, calibrate answered, warned within {waited:.1f} s"


def test_replay_clock(peer):
    bag = os.path.join(h.WORK, "replay_clock.mcap")
    subprocess.run(
        [h.TOOL_BIN, "simulate", "--shape", "plate", "--shape", "ellipse", "--repeat", "2", "--period", "0.5", "--out", bag],
        check=True, capture_output=True,
    )
    node = h.NodeProcess("replay_clock", ["-r", "__node:=replay_tracer", "-p", "use_sim_time:=true"])
    try:
        diags = peer.subscribe(DiagnosticArray, "/diagnostics")
        peer.spin_until(lambda: diag_of(diags, "/replay_tracer"), 20, "/diagnostics")
        out = subprocess.run(
            [h.TOOL_BIN, "replay", "--input", bag, "--clock", "--wait", "15", "--linger", "2"],
            capture_output=True, text=True, timeout=60,
        )
        assert out.returncode == 0 and "and /clock" in out.stdout, out
        r = peer.call("/calibrate", Calibrate.Request(scan_id=0))
        assert r.success, r.message
        calibrations = []
        latched = QoSProfile(depth=1, durability=1)
        peer.node.create_subscription(Calibration, "calibration", calibrations.append, latched)
        peer.spin_until(lambda: any(c.valid for c in calibrations), 10, "the calibration message")
        stamp = seconds(next(c for c in calibrations if c.valid).header.stamp)
        # The bag's scans are 0.5 s apart from 1.7e9 s (tracer_calib simulate); after the
        # replay the clock stands at its last message.
        assert 1.7e9 <= stamp <= 1.7e9 + 2.0, stamp
    finally:
        node.stop()
    return f"calibration stamped {stamp - 1.7e9:.2f} s into the bag's time"


def ros2_cli(*args):
    """A real `ros2` command (no daemon), its stdout; None without the CLI."""
    if not shutil.which("ros2"):
        return None
    out = subprocess.run(
        ["timeout", "-s", "KILL", "60", "ros2", *args], capture_output=True, text=True,
        env=dict(os.environ, ROS2CLI_NO_DAEMON="1"),
    )
    assert out.returncode == 0, f"ros2 {' '.join(args)}: {out.returncode}\n{out.stdout}\n{out.stderr}"
    return out.stdout


def test_describe(peer):
    node = h.NodeProcess(
        "describe",
        ["-r", "__node:=described", "-p", "qos_overrides./raw_scan.subscription.reliability:=best_effort"],
    )
    try:
        pc = peer.param_client("/described")
        names = ["calibration.scale", "resample_points", "calibration.alpha0", "plate.side", "managed",
                 "use_sim_time", "calibration.max_age_days", "qos_overrides./raw_scan.subscription.reliability"]
        ds = {d.name: d for d in peer.param(lambda: pc.describe_parameters(names)).descriptors}
        assert set(ds) == set(names), ds.keys()
        for d in ds.values():
            assert d.description and "not implemented" not in d.description, d
        scale = ds["calibration.scale"]
        assert scale.type == ParameterType.PARAMETER_DOUBLE and "encoder scale" in scale.description, scale
        assert [(r.from_value, r.to_value) for r in scale.floating_point_range] == [(0.5, 2.0)], scale
        points = ds["resample_points"]
        assert [(r.from_value, r.to_value) for r in points.integer_range] == [(0, 100000)], points
        alpha0 = ds["calibration.alpha0"].floating_point_range[0]
        assert (alpha0.from_value, alpha0.to_value) == (-math.pi, math.pi), alpha0
        assert "(m)" in ds["plate.side"].description and "greater than 0" in ds["plate.side"].additional_constraints
        assert math.isinf(ds["calibration.max_age_days"].floating_point_range[0].to_value)
        assert ds["managed"].read_only and not ds["use_sim_time"].read_only
        qos = ds["qos_overrides./raw_scan.subscription.reliability"]
        assert qos.read_only and qos.type == ParameterType.PARAMETER_STRING, qos
        # Refusals, with rclcpp's reasons; the value stays.
        r = peer.param(lambda: pc.set_parameters([Parameter("calibration.scale", value=2.5)])).results[0]
        assert not r.successful and "floating point range" in r.reason, r
        r = peer.param(lambda: pc.set_parameters([Parameter("resample_points", value=100001)])).results[0]
        assert not r.successful and "integer range" in r.reason, r
        r = peer.param(lambda: pc.set_parameters([Parameter("managed", value=True)])).results[0]
        assert not r.successful and "read-only" in r.reason, r
        r = peer.param(lambda: pc.set_parameters([Parameter("calibration.scale", value=1.5)])).results[0]
        assert r.successful, r.reason
        got = peer.param(lambda: pc.get_parameters(["calibration.scale", "qos_overrides./raw_scan.subscription.reliability"]))
        assert got.values[0].double_value == 1.5 and got.values[1].string_value == "best_effort", got
        cli = ros2_cli("param", "describe", "--no-daemon", "/described", "calibration.scale", "managed")
        if cli is not None:
            assert "Description: calibration in force: encoder scale" in cli, cli
            assert "Min value: 0.5" in cli and "Max value: 2.0" in cli, cli
            assert "Read only: true" in cli.split("Parameter name: managed")[1], cli
    finally:
        node.stop()
    return f"{len(names)} described" + ("" if cli is not None else "; no ros2 CLI installed")


def test_rcl_param_rules(_peer):
    with open(os.path.join(ROOT, "tests/data/rcl_param_rules.json")) as f:
        cases = json.load(f)
    types = {getattr(Parameter.Type, t.upper()): t for t in
             ("not_set", "bool", "integer", "double", "string", "bool_array", "integer_array", "double_array", "string_array")}
    # rcl logs each refused rule on stderr ("Failed to parse global arguments"): expected here.
    saved_stderr = os.dup(2)
    devnull = os.open(os.devnull, os.O_WRONLY)
    os.dup2(devnull, 2)
    try:
        check_rules(cases, types)
    finally:
        os.dup2(saved_stderr, 2)
        os.close(devnull)
        os.close(saved_stderr)
    return f"{len(cases)} rules read as the table says"


def check_rules(cases, types):
    for case in cases:
        ctx = Context()
        try:
            rclpy.init(args=["probe", "--ros-args", "-p", case["arg"]], context=ctx)
        except Exception:
            assert case.get("error"), f"{case['arg']}: rcl refused it, the table says it takes it"
            continue
        try:
            node = Node("probe", context=ctx)
            overrides = dict(node._parameter_overrides)
            node.destroy_node()
        finally:
            rclpy.shutdown(context=ctx)
        assert not case.get("error"), f"{case['arg']}: rcl takes it, the table says it refuses it"
        assert list(overrides) == [case["name"]], (case, list(overrides))
        p = overrides[case["name"]]
        assert types[p.type_] == case["type"], (case, p.type_)
        v = p.value
        if case["value"] in ("inf", "-inf"):
            assert v == float(case["value"]), (case, v)
        elif isinstance(case["value"], list):
            assert list(v) == case["value"], (case, v)
        else:
            assert v == case["value"], (case, v)


def main():
    rclpy.init()
    peer = h.Peer("runtime_peer")
    tests = [
        ("sim_time", lambda: test_sim_time(peer)),
        ("sim_time_no_clock", lambda: test_sim_time_no_clock(peer)),
        ("replay_clock", lambda: test_replay_clock(peer)),
        ("describe", lambda: test_describe(peer)),
        ("rcl_param_rules", lambda: test_rcl_param_rules(peer)),
    ]
    only = [a for a in sys.argv[1:] if a != "runtime"]
    failed = h.run_tests(tests, only, "interop::runtime_", "runtime")
    os._exit(1 if failed else 0)


if __name__ == "__main__":
    main()
