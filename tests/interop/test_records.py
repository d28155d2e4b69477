"""Calibration records against a real ROS 2 peer: the history file, the latched
`calibration` topic, max age and drift on /diagnostics, the `history` CLI, a history
location that cannot be written.

Run by tests/interop/run.sh (pytest, conftest.py) after test_node.py's tests, with the helpers
of harness.py.
"""

import datetime
import json
import math
import os
import subprocess
import time

from rclpy.parameter import Parameter
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy

from diagnostic_msgs.msg import DiagnosticArray
from tracer_calib_msgs.msg import Calibration, Contour, RawScan
from tracer_calib_msgs.srv import Calibrate

from harness import TOOL_BIN, TRUTH, WORK, NodeProcess, calibrate_then_lens, node_in_mount_namespace, raw_scan, simulate

PEER_NAME = "interop_peer"  # conftest.py's peer: test_node.py's and test_records.py's, one

LATCHED = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL)


def read_history(path):
    with open(path) as f:
        return [json.loads(line) for line in f if line.strip()]


def latched_subscription(peer, topic="/calibration"):
    """A subscriber that joins now, as `ros2 topic echo --qos-durability transient_local` would."""
    box = []
    peer.node.create_subscription(Calibration, topic, box.append, LATCHED)
    return box


class Calibrator:
    """Calls /calibrate from one client, each call once. (Peer.call asks again when an
    answer is slow, as discovery may not be complete; a calibrate that applies is not
    idempotent: asked twice, it is recorded twice.) A dry run, repeated until answered,
    first makes sure both sides have matched."""

    def __init__(self, peer, service="/calibrate"):
        self.peer = peer
        self.client = peer.node.create_client(Calibrate, service)
        peer.spin_until(self.client.service_is_ready, 20, f"service {service}")
        self.matched = False

    def __call__(self, scan_id, dry_run=False, timeout=30):
        if not self.matched:
            self.peer.retry(lambda: self.client.call_async(Calibrate.Request(scan_id=scan_id, dry_run=True)), "a first answer")
            self.matched = True
        future = self.client.call_async(Calibrate.Request(scan_id=scan_id, dry_run=dry_run))
        self.peer.spin_until(future.done, timeout, "the calibrate response")
        return future.result()


def history_cli(*args):
    return subprocess.run([TOOL_BIN, "history", *args], capture_output=True, text=True, timeout=30)


def test_history_and_latched_calibration(peer):
    """Two calibrations in a row: two records, the second naming the first; a subscriber
    joining later gets the second at once; a set of calibration.alpha0 republishes; after
    a restart the history supplies the uncertainties; the history CLI reads the node's
    file, also with a torn last line."""
    persisted = os.path.join(WORK, "records.yaml")
    history = os.path.join(WORK, "records.history.jsonl")  # the default: beside params_file
    node = NodeProcess("records", ["-p", f"params_file:={persisted}"])
    try:
        pub = peer.publisher("/raw_scan")
        contours = peer.subscribe(Contour, "/contour")
        # At start-up: not calibrated yet, latched all the same.
        first_seen = latched_subscription(peer)
        peer.spin_until(lambda: len(first_seen) > 0, 15, "the calibration in force at start-up")
        assert first_seen[-1].valid is False and first_seen[-1].scan_id == 0, first_seen[-1]

        peer.send_scan(pub, raw_scan(10, RawScan.TARGET_CALIBRATION_PLATE, *simulate("rec_plate_a", "plate", seed=21)), contours)
        calibrate = Calibrator(peer)
        r1 = calibrate(10)
        assert r1.success, r1.message
        assert "moved" not in r1.message, r1.message
        peer.send_scan(pub, raw_scan(11, RawScan.TARGET_CALIBRATION_PLATE, *simulate("rec_plate_b", "plate", seed=22)), contours)
        r2 = calibrate(11)
        assert r2.success, r2.message
        assert "moved since the previous calibration: alpha0" in r2.message, r2.message
        assert "drift_warn_sigma" not in r2.message, "the same tracer twice is no drift: " + r2.message

        records = read_history(history)
        assert len(records) == 2, records
        a, b = records
        assert a["previous"] is None and a["scan_id"] == 10 and b["scan_id"] == 11, records
        assert a["node"] == "/tracer_calibrator" and a["model"] == "full", a
        assert a["time"].endswith("Z") and a["time"] < b["time"], (a["time"], b["time"])
        assert b["previous"] == {"alpha0": a["alpha0"], "offset": a["offset"], "delta_l": a["delta_l"], "scale": a["scale"]}, b
        assert (b["alpha0"], b["offset"], b["delta_l"]) == (r2.alpha0, r2.offset, r2.delta_l), (b, r2)
        assert b["stddev"] == list(r2.stddev) and b["iterations"] == r2.iterations, (b, r2)
        assert b["samples_used"] == r2.samples_used and b["rms_residual"] == r2.rms_residual, (b, r2)

        # A subscriber that joins now gets the second calibration at once.
        late = latched_subscription(peer)
        peer.spin_until(lambda: any(m.scan_id == 11 for m in late), 10, "the latched calibration")
        m = late[-1]
        assert len(late) == 1, [x.scan_id for x in late]
        assert m.valid and m.model == "full" and m.header.frame_id == "tracer_axis", m
        assert (m.alpha0, m.offset, m.delta_l, m.scale) == (r2.alpha0, r2.offset, r2.delta_l, 1.0), (m, r2)
        assert list(m.stddev) == list(r2.stddev) and m.rms_residual == r2.rms_residual, m
        assert m.samples_used == r2.samples_used, m
        assert abs(m.header.stamp.sec + m.header.stamp.nanosec * 1e-9 - time.time()) < 60, m.header.stamp

        # A parameter set changes the calibration in force: republished, as set by hand.
        pc = peer.param_client("/tracer_calibrator")
        ok = peer.param(lambda: pc.set_parameters([Parameter("calibration.alpha0", value=0.0345)])).results[0]
        assert ok.successful, ok.reason
        peer.spin_until(lambda: any(x.alpha0 == 0.0345 for x in late), 10, "the republished calibration")
        m = next(x for x in late if x.alpha0 == 0.0345)
        assert m.valid and m.scan_id == 0 and len(m.stddev) == 0 and m.rms_residual == 0.0, m
        assert m.offset == r2.offset, m
        assert len(read_history(history)) == 2, "a parameter set is not a calibration"
        # Back to the calibrated value: the history's last record matches again at restart.
        ok = peer.param(lambda: pc.set_parameters([Parameter("calibration.alpha0", value=r2.alpha0)])).results[0]
        assert ok.successful, ok.reason
    finally:
        took = node.stop()
    assert took < 1.0, took

    # Restarted from the persisted parameters: the history's last record supplies the fit.
    node = NodeProcess("records_restart", ["--params-file", persisted])
    try:
        again = latched_subscription(peer)
        peer.spin_until(lambda: any(x.scan_id == 11 for x in again), 15, "the calibration in force after a restart")
        m = next(x for x in again if x.scan_id == 11)
        assert m.valid and m.alpha0 == r2.alpha0 and list(m.stddev) == list(r2.stddev), m
        stamp = m.header.stamp.sec + m.header.stamp.nanosec * 1e-9
        t_b = datetime.datetime.strptime(b["time"], "%Y-%m-%dT%H:%M:%S.%fZ").replace(tzinfo=datetime.timezone.utc).timestamp()
        assert abs(stamp - t_b) < 1e-3, (stamp, b["time"])
    finally:
        node.stop()

    # The history CLI reads the node's file; a torn last line (a crash mid-write) is
    # skipped with a warning.
    out = history_cli("--input", history, "--json")
    assert out.returncode == 0, out.stderr
    assert json.loads(out.stdout) == records
    with open(history, "a") as f:
        f.write('{"time": "2026-11-23T11:00:00.000Z", "node": "/tracer_cal')
    svg = os.path.join(WORK, "records_history.svg")
    out = history_cli("--input", history, "--svg", svg)
    assert out.returncode == 0, out.stderr
    assert "records.history.jsonl:3: skipped a torn last line" in out.stderr, out.stderr
    rows = [line for line in out.stdout.splitlines() if line[:2] == "20"]
    assert len(rows) == 2 and rows[0].split()[1:3] == ["10", "full"] and rows[1].split()[1] == "11", out.stdout
    assert os.path.getsize(svg) > 1000
    out = history_cli("--input", history, "--json")
    assert out.returncode == 0 and json.loads(out.stdout) == records, out

    # The node appends after the torn line, on a line of its own.
    node = NodeProcess("records_append", ["--params-file", persisted])
    try:
        pub = peer.publisher("/raw_scan")
        contours = peer.subscribe(Contour, "/contour")
        peer.send_scan(pub, raw_scan(12, RawScan.TARGET_CALIBRATION_PLATE, *simulate("rec_plate_c", "plate", seed=23)), contours)
        calibrate = Calibrator(peer)
        r3 = calibrate(12)
        assert r3.success, r3.message
    finally:
        node.stop()
    out = history_cli("--input", history, "--json")
    got = json.loads(out.stdout)
    assert [x["scan_id"] for x in got] == [10, 11, 12], got
    assert got[2]["previous"]["alpha0"] == r2.alpha0, got[2]
    assert "records.history.jsonl:3: skipped not a record" in out.stderr, out.stderr


OK, WARN = 0, 1


def diagnostic(diags, name_part):
    """The latest status of the node named `name_part`, as (level, message, values)."""
    for d in reversed(diags):
        for st in d.status:
            if name_part in st.name:
                level = st.level if isinstance(st.level, int) else st.level[0]  # a `byte` field
                return level, st.message, {v.key: v.value for v in st.values}
    return None


def test_max_age_and_drift_on_diagnostics(peer):
    """calibration.max_age_days: WARN once the calibration in force is older;
    calibration.drift_warn_sigma: WARN when a calibration moved d far beyond its
    uncertainty, and the Calibrate reply says by how much."""
    persisted = os.path.join(WORK, "drift.yaml")
    node = NodeProcess("drift", ["-r", "__node:=drift_tracer", "-p", f"params_file:={persisted}"])
    try:
        pub = peer.publisher("/raw_scan")
        contours = peer.subscribe(Contour, "/contour")
        diags = peer.subscribe(DiagnosticArray, "/diagnostics")
        peer.send_scan(pub, raw_scan(1, RawScan.TARGET_CALIBRATION_PLATE, *simulate("drift_plate_a", "plate", seed=31)), contours)
        calibrate = Calibrator(peer)
        r1 = calibrate(1)
        assert r1.success, r1.message

        def fresh(level):
            def ok():
                got = diagnostic(diags, "drift_tracer")
                return got is not None and got[0] == level and got[2].get("calibration_scan_id") == "1"
            return ok

        peer.spin_until(fresh(OK), 10, "an OK diagnostic after the calibration")
        _, _, values = diagnostic(diags, "drift_tracer")
        assert values["max_age_days"] == "0" and values["history_records"] == "1", values
        assert values["history_file"] == os.path.join(WORK, "drift.history.jsonl"), values

        # A limit of a second and a half: overdue a moment later.
        pc = peer.param_client("/drift_tracer")
        ok = peer.param(lambda: pc.set_parameters([Parameter("calibration.max_age_days", value=1.5 / 86400)])).results[0]
        assert ok.successful, ok.reason
        peer.spin_until(
            lambda: (d := diagnostic(diags, "drift_tracer")) is not None and "calibration overdue" in d[1], 10, "an overdue warning"
        )
        level, message, values = diagnostic(diags, "drift_tracer")
        assert level == WARN and "calibration.max_age_days is" in message, (level, message)
        ok = peer.param(lambda: pc.set_parameters([Parameter("calibration.max_age_days", value=0.0)])).results[0]
        assert ok.successful, ok.reason

        # The tracer knocked: the rail 0.2 mm further out (about 20 combined σ).
        knocked = dict(TRUTH, offset=TRUTH["offset"] + 2e-4)
        peer.send_scan(pub, raw_scan(2, RawScan.TARGET_CALIBRATION_PLATE, *simulate("drift_plate_b", "plate", seed=32, **knocked)), contours)
        r2 = calibrate(2)
        assert r2.success, r2.message
        assert "moved since the previous calibration" in r2.message, r2.message
        assert "more than calibration.drift_warn_sigma = 10" in r2.message, r2.message
        moved = r2.message.split("moved since the previous calibration: ")[1]
        sigmas = float(moved.split(" mm (")[1].split("σ")[0])  # "alpha0 ...° (xσ), d ... mm (yσ), ..."
        expected = abs(r2.offset - r1.offset) / math.hypot(r1.stddev[1], r2.stddev[1])
        assert sigmas > 10 and abs(sigmas - expected) < 0.1, (sigmas, expected, r2.message)
        peer.spin_until(
            lambda: (d := diagnostic(diags, "drift_tracer")) is not None and "the last calibration moved d by" in d[1],
            10,
            "a drift warning",
        )
        level, message, values = diagnostic(diags, "drift_tracer")
        assert level == WARN and float(values["drift_sigma"]) > 10, (level, message, values)
        # A dry run reports the move too, and changes nothing.
        dry = calibrate(1, dry_run=True)
        assert dry.success and dry.message.startswith("dry run") and "more than calibration.drift_warn_sigma" in dry.message, dry.message
        assert len(read_history(os.path.join(WORK, "drift.history.jsonl"))) == 2
        # A third calibration on the knocked tracer: no move, no warning.
        peer.send_scan(pub, raw_scan(3, RawScan.TARGET_CALIBRATION_PLATE, *simulate("drift_plate_c", "plate", seed=33, **knocked)), contours)
        r3 = calibrate(3)
        assert r3.success and "drift_warn_sigma" not in r3.message, r3.message
        peer.spin_until(
            lambda: (d := diagnostic(diags, "drift_tracer")) is not None and d[0] == OK and d[2].get("calibration_scan_id") == "3",
            10,
            "OK again",
        )
    finally:
        took = node.stop()
    assert took < 1.0, took


def test_read_only_history(peer):
    """A history file in a directory mounted read-only: /calibrate answers success: false
    naming the file and why, the calibration stays in force in memory (and on the latched
    topic), the history file is left byte for byte as it was, and the parameters are not
    persisted without their record."""
    ro = os.path.join(WORK, "ro_history")
    os.makedirs(ro, exist_ok=True)
    history = os.path.join(ro, "h.jsonl")
    before = '{"time":"2026-11-20T08:00:00.000Z","node":"/ro_tracer","scan_id":1,"model":"full","alpha0":0.03,"offset":0.005,"delta_l":0.002,"scale":1.0,"stddev":[0.0002,6e-06,1e-06],"rms_residual":5e-06,"samples_used":400,"iterations":7,"previous":null}\n'
    with open(history, "w") as f:
        f.write(before)
    persisted = os.path.join(WORK, "ro.yaml")
    # The directory read-only for the node alone: a bind mount in its own mount namespace.
    script = f"""
set -e
mount --bind {ro} {ro}
mount -o remount,bind,ro {ro}
exec {os.environ['TRACER_CALIB_NODE']} --ros-args -r __node:=ro_tracer -p params_file:={persisted} -p history_file:={history}
"""
    node = node_in_mount_namespace("ro_history", script)
    try:
        r, c = calibrate_then_lens(peer, 5, "ro", 41, Calibrator(peer))
        assert not r.success, r
        assert r.message.startswith(f"calibration applied in memory but not persisted: cannot append to {history}: Read-only file system"), r.message
        assert c.calibrated, "the calibration is not in force"
        late = latched_subscription(peer)
        peer.spin_until(lambda: any(m.scan_id == 5 for m in late), 10, "the calibration in force, latched")
        m = next(m for m in late if m.scan_id == 5)
        assert m.valid and m.alpha0 == r.alpha0, m
    finally:
        node.stop()
    with open(history) as f:
        assert f.read() == before, "the history file changed"
    assert not os.path.exists(persisted), "parameters persisted without their record"
    assert not [f for f in os.listdir(ro) if f != "h.jsonl"], os.listdir(ro)


def test_full_disk_history(peer):
    """A history file on a full file system, its last page all but full: the append gets
    part of the record in before the disk is full. /calibrate fails naming the file and
    why, and the part that went in is cut off again: the file is byte for byte as it was."""
    mnt = os.path.join(WORK, "mnt_full_history")
    os.makedirs(mnt, exist_ok=True)
    record = '{"time":"2026-11-20T08:00:00.000Z","node":"/full_tracer","scan_id":1,"model":"full","alpha0":0.03,"offset":0.005,"delta_l":0.002,"scale":1.0,"stddev":[0.0002,6e-06,1e-06],"rms_residual":5e-06,"samples_used":400,"iterations":7,"previous":null}\n'
    # 100 bytes short of a page: the next record starts in this page and needs another.
    before = record + "\n" * (4096 - 100 - len(record))
    seed = os.path.join(WORK, "full_history_seed.jsonl")
    after = os.path.join(WORK, "full_history_after.jsonl")
    with open(seed, "w") as f:
        f.write(before)
    persisted = os.path.join(WORK, "full.yaml")
    script = f"""
set -e
mount -t tmpfs -o size=64k tmpfs {mnt}
cp {seed} {mnt}/h.jsonl
dd if=/dev/zero of={mnt}/filler bs=4k 2>/dev/null || true
{os.environ['TRACER_CALIB_NODE']} --ros-args -r __node:=full_tracer -p params_file:={persisted} -p history_file:={mnt}/h.jsonl &
pid=$!
trap 'kill -TERM $pid' TERM
wait $pid || true
wait $pid || true
cp {mnt}/h.jsonl {after}
"""
    node = node_in_mount_namespace("full_history", script)
    try:
        r, c = calibrate_then_lens(peer, 7, "full", 51, Calibrator(peer))
        assert not r.success, r
        assert r.message.startswith(f"calibration applied in memory but not persisted: cannot append to {mnt}/h.jsonl: No space left on device"), r.message
        assert c.calibrated, "the calibration is not in force"
    finally:
        node.stop(timeout=10)
    with open(after) as f:
        assert f.read() == before, "the history file changed"
    assert not os.path.exists(persisted), "parameters persisted without their record"
    out = history_cli("--input", after, "--json")
    assert out.returncode == 0 and len(json.loads(out.stdout)) == 1 and not out.stderr, out
