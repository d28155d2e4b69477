"""tracer_calib_node against a real ROS 2 peer: rclpy (ROS 2 Kilted, Fast DDS, PyPI wheels)
with the tracer_calib_msgs package built from msg/ by rosidl.

What `ros2 topic pub`, `ros2 service call` and `ros2 param` do, done with rclpy directly
(the stock commands themselves run in test_launch.py): publish RawScan messages of simulated scans, call /calibrate
with the generated Calibrate type, receive Contour, PolygonStamped and DiagnosticArray,
list/get/set parameters with rclpy's parameter client, and load the YAML the node
persisted into an rclpy node with --params-file.

Run by tests/interop/run.sh (pytest, conftest.py; with test_records.py, one rclpy peer)
inside a private network namespace, with the helpers of harness.py. Each test starts its
own node processes and stops them with SIGTERM (checking they exit promptly).
"""

import json
import math
import os
import signal
import subprocess
import sys
import time

from rclpy.parameter import Parameter

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from geometry_msgs.msg import PolygonStamped
from tracer_calib_msgs.msg import Contour, RawScan
from tracer_calib_msgs.srv import Calibrate

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from processes import peer_program  # noqa: E402
from harness import (  # noqa: E402
    ELLIPSE,
    NODE_BIN,
    TOOL_BIN,
    TRUTH,
    WORK,
    NodeProcess,
    assert_fit,
    calibrate_then_lens,
    ellipse_distance,
    ellipse_radius,
    node_in_mount_namespace,
    params_file,
    raw_scan,
    read_back_with_rclpy,
    simulate,
)

PEER_NAME = "interop_peer"  # conftest.py's peer: test_node.py's and test_records.py's, one


# ---------------------------------------------------------------------------------------
# Tests


def test_calibrate_and_correct(peer):
    """Plate scan in, /calibrate called as `ros2 service call` would, lens scan corrected;
    the calibration is persisted and a stock rclpy node reads the file back."""
    persisted = os.path.join(WORK, "root.yaml")
    initial = params_file("root_initial.yaml", "tracer_calibrator:\n  ros__parameters:\n    plate.side: 0.045\n")
    node = NodeProcess("root", ["--params-file", initial, "-p", f"params_file:={persisted}"])
    try:
        pub = peer.publisher("/raw_scan")
        contours = peer.subscribe(Contour, "/contour")
        polygons = peer.subscribe(PolygonStamped, "/contour_polygon")
        peer.wait_matched(pub)
        lens = simulate("lens", "ellipse", seed=3)

        # Before any calibration: uncorrected, flagged so.
        first = peer.send_scan(pub, raw_scan(1, RawScan.TARGET_LENS, *lens), contours)
        assert first.calibrated is False

        # A failed calibration (no plate scan yet) says why, in words and as a code (the
        # constant rosidl generated from the .srv).
        r = peer.call("/calibrate", Calibrate.Request())
        assert not r.success and "no calibration-plate scan" in r.message, r.message
        assert r.error_code == Calibrate.Response.ERROR_NO_PLATE_SCAN == 1, r.error_code

        plate = simulate("plate", "plate", seed=2)
        peer.send_scan(pub, raw_scan(10, RawScan.TARGET_CALIBRATION_PLATE, *plate), contours)

        r = peer.call("/calibrate", Calibrate.Request())  # scan_id 0: the latest plate scan
        assert_fit(r)
        assert len(r.stddev) == 3 and all(s > 0 for s in r.stddev), r.stddev
        assert r.samples_used == 400 and r.iterations > 0 and 0 < r.rms_residual < 2e-5, r

        c = peer.send_scan(pub, raw_scan(11, RawScan.TARGET_LENS, *lens), contours)
        # The node builds polygons only while someone subscribes (it checks once a
        # second), so a subscriber that has just joined may miss the first: resend.
        deadline = time.monotonic() + 15
        while not any(p.header.stamp.sec == 1700000011 for p in polygons):
            assert time.monotonic() < deadline, "no PolygonStamped for the lens scan"
            pub.publish(raw_scan(11, RawScan.TARGET_LENS, *lens))
            try:
                peer.spin_until(lambda: any(p.header.stamp.sec == 1700000011 for p in polygons), 1.0, "a polygon")
            except AssertionError:
                pass
        assert c.calibrated and c.target == RawScan.TARGET_LENS
        assert c.header.frame_id == "tracer_axis" and c.header.stamp.sec == 1700000011
        assert len(c.points) == 400 and all(p.z == 0.0 for p in c.points)
        worst = max(ellipse_distance(p.x, p.y) for p in c.points)
        assert worst < 40e-6, f"corrected points up to {worst * 1e3:.4f} mm off the ellipse"
        raw = first
        raw_worst = max(ellipse_distance(p.x, p.y) for p in raw.points)
        assert raw_worst > 2e-3, f"uncorrected points only {raw_worst * 1e3:.3f} mm off?"
        assert len(c.radii) == 400
        worst_r = max(abs(r_k - ellipse_radius(2 * math.pi * k / 400)) for k, r_k in enumerate(c.radii))
        assert worst_r < 40e-6, f"radii up to {worst_r * 1e3:.4f} mm off"
        poly = next(p for p in polygons if p.header.stamp.sec == 1700000011)
        assert len(poly.polygon.points) == 400 and poly.header.frame_id == "tracer_axis"

        # Persisted, and a stock ROS 2 node reads the file back.
        back = read_back_with_rclpy(persisted, "tracer_calibrator", "/")
        assert back["calibration.valid"] is True, back
        assert abs(back["calibration.alpha0"] - r.alpha0) < 1e-12, back
        assert abs(back["calibration.offset"] - r.offset) < 1e-12, back
        # The file was created from the --params-file given (plate.side); the node wrote
        # what differs from it, not the parameters at their defaults.
        assert back["plate.side"] == 0.045 and "model" not in back and "resample_points" not in back, back
        with open(initial) as f:
            assert f.read() in open(persisted).read()
    finally:
        took = node.stop()
    assert took < 1.0, f"the node took {took:.2f} s to shut down"
    # Quiet by default: nothing at error level in normal operation or at shutdown
    # (asking ros2-client's Publisher for its subscriber count logged an error every
    # second until a first polygon subscriber had matched; rustdds logged two errors
    # leaving the multicast group as the node closed).
    errors = [line for line in node.output().splitlines() if "ERROR" in line]
    assert not errors, "\n".join(errors)


def test_parameters(peer):
    """`ros2 param list/get/set` through rclpy's parameter client; validation; persistence;
    a dry run changes nothing; a restarted node comes back with the calibration."""
    persisted = os.path.join(WORK, "params.yaml")
    node = NodeProcess("params", ["-p", f"params_file:={persisted}", "-p", "resample_points:=100"])
    try:
        pc = peer.param_client("/tracer_calibrator")
        names = peer.param(lambda: pc.list_parameters()).result.names
        for n in ["calibration.alpha0", "calibration.offset", "calibration.delta_l", "calibration.valid", "plate.side",
                  "plate.corner_radius", "encoder.meters_per_count", "model", "output_frame_id", "resample_points",
                  "params_file"]:
            assert n in names, (n, names)
        values = peer.param(lambda: pc.get_parameters(["plate.side", "resample_points", "params_file"])).values
        assert values[0].double_value == 0.045 and values[1].integer_value == 100, values
        assert values[2].string_value == persisted, values

        ok = peer.param(lambda: pc.set_parameters([Parameter("output_frame_id", value="cell_axis")])).results[0]
        assert ok.successful, ok.reason
        bad = peer.param(lambda: pc.set_parameters([Parameter("plate.side", value=-0.045)])).results[0]
        assert not bad.successful and "positive" in bad.reason, bad
        bad = peer.param(lambda: pc.set_parameters([Parameter("model", value="magic")])).results[0]
        assert not bad.successful and "unknown model" in bad.reason, bad
        bad = peer.param(lambda: pc.set_parameters([Parameter("resample_points", value="many")])).results[0]
        assert not bad.successful, bad

        pub = peer.publisher("/raw_scan")
        contours = peer.subscribe(Contour, "/contour")
        peer.wait_matched(pub)
        c = peer.send_scan(pub, raw_scan(1, RawScan.TARGET_CALIBRATION_PLATE, *simulate("plate_p", "plate", seed=4)), contours)
        assert c.header.frame_id == "cell_axis" and len(c.radii) == 100

        dry = peer.call("/calibrate", Calibrate.Request(scan_id=1, dry_run=True))
        assert dry.success and dry.message.startswith("dry run"), dry.message
        valid = peer.param(lambda: pc.get_parameters(["calibration.valid"])).values[0].bool_value
        assert valid is False

        r = peer.call("/calibrate", Calibrate.Request(scan_id=1))
        assert r.success and r.error_code == Calibrate.Response.ERROR_NONE, (r.message, r.error_code)
        got = peer.param(lambda: pc.get_parameters(["calibration.alpha0", "calibration.valid"])).values
        assert got[0].double_value == r.alpha0 and got[1].bool_value is True, got
        with open(persisted) as f:
            text = f.read()
        assert "output_frame_id: cell_axis" in text and "calibration.valid: true" in text, text
    finally:
        took = node.stop()
    assert took < 1.0, f"the node took {took:.2f} s to shut down"

    # The persisted file brings the calibration back on restart.
    node = NodeProcess("params_restart", ["--params-file", persisted])
    try:
        pc = peer.param_client("/tracer_calibrator")
        got = peer.param(lambda: pc.get_parameters(["calibration.alpha0", "calibration.valid", "output_frame_id"])).values
        assert got[0].double_value == r.alpha0 and got[1].bool_value is True and got[2].string_value == "cell_axis"
    finally:
        node.stop()


def test_two_cells(peer):
    """Two nodes in two namespaces in one graph, each calibrating its own tracer."""
    cells = {
        "cell1": dict(alpha0_deg=1.5, offset=0.004, delta_l=0.001),
        "cell2": dict(alpha0_deg=-3.0, offset=-0.007, delta_l=0.0025),
    }
    nodes = []
    try:
        for cell in cells:
            persisted = os.path.join(WORK, f"{cell}.yaml")
            nodes.append(NodeProcess(cell, ["-r", f"__ns:=/{cell}", "-r", "__node:=tracer", "-p", f"params_file:={persisted}"]))
        for i, (cell, truth) in enumerate(cells.items()):
            pub = peer.publisher(f"/{cell}/raw_scan")
            contours = peer.subscribe(Contour, f"/{cell}/contour")
            scan = raw_scan(100 + i, RawScan.TARGET_CALIBRATION_PLATE, *simulate(f"plate_{cell}", "plate", seed=10 + i, **truth))
            peer.send_scan(pub, scan, contours)
        for cell, truth in cells.items():
            r = peer.call(f"/{cell}/calibrate", Calibrate.Request())
            assert r.success, (cell, r.message)
            assert abs(math.degrees(r.alpha0) - truth["alpha0_deg"]) < 0.1, (cell, r)
            assert abs(r.offset - truth["offset"]) < 5e-5, (cell, r)
            back = read_back_with_rclpy(os.path.join(WORK, f"{cell}.yaml"), "tracer", f"/{cell}")
            assert abs(back["calibration.offset"] - r.offset) < 1e-12, (cell, back)
        # The graph as ROS sees it: each node serves its own namespaced services.
        out = subprocess.run([sys.executable, peer_program("node_graph_probe")], capture_output=True, text=True, timeout=60)
        by_node = json.loads(out.stdout.strip().splitlines()[-1])
        for ns in ("/cell1", "/cell2"):
            services = by_node[ns]
            assert f"{ns}/calibrate" in services and f"{ns}/tracer/get_parameters" in services, services
            assert "/calibrate" not in services, services
    finally:
        for n in nodes:
            n.stop()


def test_bad_scans_and_diagnostics(peer):
    """Malformed scans are rejected and counted on /diagnostics; the node keeps serving."""
    node = NodeProcess("diag", ["-r", "__node:=diag_tracer", "-r", "calibrate:=/diag/calibrate"])
    try:
        pub = peer.publisher("/raw_scan")
        contours = peer.subscribe(Contour, "/contour")
        diags = peer.subscribe(DiagnosticArray, "/diagnostics")
        steps, counts = simulate("plate_d", "plate", seed=5)
        peer.send_scan(pub, raw_scan(5, RawScan.TARGET_CALIBRATION_PLATE, steps, counts), contours)
        bad = [
            raw_scan(1, 1, steps, counts[:-1]),  # lengths differ
            raw_scan(2, 1, [s + 400 for s in steps], counts),  # step out of range
            raw_scan(3, 1, steps[:2], counts[:2]),  # too few samples
            raw_scan(4, 1, steps, counts, n=0),  # steps_per_revolution 0
        ]
        for m in bad:
            pub.publish(m)
        peer.send_scan(pub, raw_scan(6, RawScan.TARGET_CALIBRATION_PLATE, steps, counts), contours)
        assert {c.scan_id for c in contours} == {5, 6}, [c.scan_id for c in contours]
        r = peer.call("/diag/calibrate", Calibrate.Request())
        assert r.success, r.message

        def counted():
            for d in diags:
                for s in d.status:
                    kv = {v.key: v.value for v in s.values}
                    if "diag_tracer" in s.name and kv.get("scans_rejected") == "4" and kv.get("calibrated") == "true":
                        return True
            return False

        peer.spin_until(counted, 5, "diagnostics counting 4 rejected scans and the calibration")
        assert "rejected raw scan" in node.output(), node.output()
    finally:
        node.stop()


def test_wire_bad_input(peer):
    """Malformed RawScans on the wire, every field wrong in turn: each is rejected and
    counted; the node keeps publishing good scans and answering /calibrate."""
    node = NodeProcess("wire", ["-r", "__node:=wire_tracer"])
    try:
        pub = peer.publisher("/raw_scan")
        contours = peer.subscribe(Contour, "/contour")
        diags = peer.subscribe(DiagnosticArray, "/diagnostics")
        steps, counts = simulate("plate_w", "plate", seed=8)
        peer.send_scan(pub, raw_scan(1, RawScan.TARGET_CALIBRATION_PLATE, steps, counts), contours)
        huge = 1_000_000
        bad = [
            raw_scan(10, 1, [], []),  # empty arrays
            raw_scan(11, 1, steps, []),  # counts empty
            raw_scan(12, 1, steps, counts + [1]),  # lengths differ
            raw_scan(13, 1, [s + 400 for s in steps], counts),  # step out of range
            raw_scan(14, 1, [0] * 400, counts),  # one step measured 400 times
            raw_scan(15, 9, steps, counts),  # unknown target
            raw_scan(16, 1, steps, counts, n=0),  # steps_per_revolution 0
            raw_scan(17, 1, steps, counts, n=2**32 - 1),  # steps_per_revolution huge
            raw_scan(18, 1, list(range(huge)), [22500] * huge, n=huge),  # a 10^6-sample scan
        ]
        for m in bad:
            pub.publish(m)
        # Geometry that gives no plate: all counts zero, and absurd lengths. Valid scans
        # (they are corrected), but no calibration may come out of them.
        peer.send_scan(pub, raw_scan(20, 1, steps, [0] * len(steps)), contours)
        r = peer.call("/calibrate", Calibrate.Request(scan_id=20))
        assert not r.success and r.message, r
        peer.send_scan(pub, raw_scan(21, 1, steps, [2**31 - 1 - (s % 2) * 2**31 for s in steps]), contours)
        r = peer.call("/calibrate", Calibrate.Request(scan_id=21))
        assert not r.success, r
        assert all(math.isfinite(v) for v in (r.alpha0, r.offset, r.delta_l, r.rms_residual)), r
        # Still serving.
        peer.send_scan(pub, raw_scan(30, RawScan.TARGET_CALIBRATION_PLATE, steps, counts), contours)
        r = peer.call("/calibrate", Calibrate.Request(scan_id=30))
        assert r.success, r.message
        assert not any(c.scan_id in range(10, 19) for c in contours)

        def counted():
            for d in diags:
                for st in d.status:
                    kv = {v.key: v.value for v in st.values}
                    if "wire_tracer" in st.name and kv.get("scans_rejected") == str(len(bad)):
                        return True
            return False

        peer.spin_until(counted, 10, f"diagnostics counting {len(bad)} rejected scans")
        out = node.output()
        assert "more than the limit" in out or "rejected" in out, out
    finally:
        took = node.stop()
    assert took < 1.0, took


def test_concurrent_calls_and_a_vanishing_peer(peer):
    """64 calibrate calls at once from 16 clients are all answered (one fit at a time); a client that
    dies before its answer does not wedge the node."""
    node = NodeProcess("concurrent", ["-r", "__node:=busy_tracer"])
    try:
        pub = peer.publisher("/raw_scan")
        contours = peer.subscribe(Contour, "/contour")
        peer.send_scan(pub, raw_scan(1, RawScan.TARGET_CALIBRATION_PLATE, *simulate("plate_c", "plate", seed=9)), contours)
        # A client process that sends a request and dies at once.
        doomed = subprocess.run([sys.executable, peer_program("node_doomed_client")], timeout=60)
        assert doomed.returncode == 0
        clients = [peer.node.create_client(Calibrate, "/calibrate") for _ in range(16)]
        for c in clients:
            peer.spin_until(c.service_is_ready, 15, "the service")
            # Discovery first (a request sent before the node has matched this client is
            # lost, as on any volatile topic): one answered call each, then the burst.
            peer.retry(lambda c=c: c.call_async(Calibrate.Request(scan_id=1, dry_run=True)), "a warm-up answer")
        # The burst: four calls outstanding per client, 64 in all, half of them applying
        # (and persisting) the result. The node fits one at a time, so most wait in its
        # request queue, which must hold them all (at ROS's default depth of 10, the
        # eleventh call arriving during one fit would push the oldest out, its caller
        # waiting forever). The clients take their replies only once
        # all have been sent: each client's reply queue (ROS's default, KEEP_LAST 10)
        # must then hold its own four, which it can only if the node sends a reply to
        # its client alone (sent to every client, 64 replies pushed most out).
        t0 = time.monotonic()
        futures = [c.call_async(Calibrate.Request(scan_id=1, dry_run=(i % 2 == 1))) for _ in range(4) for i, c in enumerate(clients)]
        time.sleep(3)
        peer.spin_until(lambda: all(f.done() for f in futures), 30, lambda: f"{len(futures)} answers (got {sum(f.done() for f in futures)})")
        took = time.monotonic() - t0
        results = [f.result() for f in futures]
        assert all(r.success for r in results), [r.message for r in results if not r.success]
        assert len({(r.alpha0, r.offset) for r in results}) == 1, "every fit of the same scan is the same"
        print(f"    {len(futures)} concurrent calls from 16 clients answered in {took * 1e3:.0f} ms", flush=True)
    finally:
        node.stop()


def test_kill_during_writes():
    """SIGKILL at random moments while the node persists parameter changes as fast as it
    can: the params file is always complete (old or new), never half written."""
    import random

    random.seed(4)
    path = os.path.join(WORK, "killed.yaml")
    with open(path, "w") as f:
        f.write("tracer_calibrator:\n  ros__parameters:\n    output_frame_id: frame_0\n")
    setter = peer_program("node_param_setter")
    setter_proc = subprocess.Popen([sys.executable, setter], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    seen = set()
    try:
        for round_ in range(12):
            node = subprocess.Popen([NODE_BIN, "--ros-args", "--params-file", path], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
            time.sleep(random.uniform(1.0, 2.5))
            node.send_signal(signal.SIGKILL)
            node.wait()
            with open(path) as f:
                text = f.read()
            back = subprocess.run([TOOL_BIN, "calibrate", "--input", "/nonexistent.csv", "--params", path, "--json"], capture_output=True, text=True)
            assert "cannot read" in back.stderr and path not in back.stderr, (round_, back.stderr, text)
            assert text.startswith(("# tracer_calib: params format 2\n", "tracer_calibrator:")), text
            frame = [l for l in text.splitlines() if "output_frame_id" in l]
            assert len(frame) == 1, text
            seen.add(frame[0].split(":", 1)[1].strip())
    finally:
        setter_proc.kill()
        setter_proc.wait()
    assert len(seen) > 3, f"the node hardly wrote anything: {seen}"
    # Temporary files of killed writes are cleaned up when the node starts again.
    leftovers = [f for f in os.listdir(WORK) if f.startswith(".killed.yaml.tmp.")]
    assert len(leftovers) <= 1, leftovers
    print(f"    12 kills, the file was whole every time ({len(seen)} different versions seen)", flush=True)


def test_read_only_and_full_disk(peer):
    """A params file on a read-only or a full file system: calibrate answers
    success: false with the reason, and the calibration stays in force in memory."""
    for kind, mount_opts, fill in [("read-only", "ro", False), ("full", "size=64k", True)]:
        mnt = os.path.join(WORK, f"mnt_{kind}")
        os.makedirs(mnt, exist_ok=True)
        initial = "tracer_calibrator:\n  ros__parameters:\n    plate.side: 0.045\n"
        script = f"""
set -e
mount -t tmpfs -o size=64k tmpfs {mnt}
printf '{initial}' > {mnt}/params.yaml
if [ {int(fill)} = 1 ]; then dd if=/dev/zero of={mnt}/filler bs=4k 2>/dev/null || true; fi
mount -o remount,{mount_opts} {mnt}
exec {NODE_BIN} --ros-args -r __node:=disk_tracer -p params_file:={mnt}/params.yaml --params-file {mnt}/params.yaml
"""
        node = node_in_mount_namespace(f"disk_{kind}", script)
        try:
            r, c = calibrate_then_lens(
                peer, 1, f"disk_{kind}", 11, lambda scan_id: peer.call("/calibrate", Calibrate.Request(scan_id=scan_id))
            )
            assert not r.success, (kind, r)
            assert "applied in memory but not persisted" in r.message, (kind, r.message)
            reason = "Read-only file system" if kind == "read-only" else "No space left on device"
            assert reason in r.message, (kind, r.message)
            assert c.calibrated, f"{kind}: the calibration is not in force"
            pc = peer.param_client("/disk_tracer")
            got = peer.param(lambda: pc.get_parameters(["calibration.valid", "calibration.alpha0"])).values
            assert got[0].bool_value is True and got[1].double_value == r.alpha0, got
            bad = peer.param(lambda: pc.set_parameters([Parameter("output_frame_id", value="x")])).results[0]
            assert not bad.successful and reason in bad.reason, (kind, bad)
        finally:
            node.stop()


SHARED_PARAMS = """\
# Edging line 3. Owner: J. Doe.
/**:
  ros__parameters:
    use_sim_time: false   # the cell runs on wall time

# The edger: do not raise feed_rate (certificate 4711).
/cell1/edger:
  ros__parameters:
    feed_rate: 0.5        # do not raise
    wheel: "fine"

/cell1/tracer:
  ros__parameters:
    # Plate certificate 4711.
    plate:
      side: 0.045         # certified
    output_frame_id: cell1_axis   # the edger's frame

/cell1/plc:
  ros__parameters:
    port: 502
"""


def test_shared_params_file(peer):
    """A cell's params file shared with other nodes (a /** section, the edger's, the PLC's,
    comments): a parameter set and a calibration change the tracer's own section only,
    every other line stays, and stock rclpy nodes read their sections as before. A file the
    node cannot edit without reformatting it (a flow map) is left as it is: the parameters
    go to a sibling file, /diagnostics says so, and a restarted node reads them from it."""
    path = params_file("line3.yaml", SHARED_PARAMS)
    edger_before = read_back_with_rclpy(path, "edger", "/cell1")
    node = NodeProcess("shared", ["--params-file", path, "-r", "__ns:=/cell1", "-r", "__node:=tracer",
                                  "-r", "raw_scan:=/shared_scan"])
    try:
        pc = peer.param_client("/cell1/tracer")
        ok = peer.param(lambda: pc.set_parameters([Parameter("resample_points", value=200)])).results[0]
        assert ok.successful, ok.reason
        contours = peer.subscribe(Contour, "/cell1/contour")
        pub = peer.publisher("/shared_scan")
        peer.wait_matched(pub)
        peer.send_scan(pub, raw_scan(1, RawScan.TARGET_CALIBRATION_PLATE, *simulate("plate_shared", "plate", seed=6)), contours)
        r = peer.call("/cell1/calibrate", Calibrate.Request(scan_id=1))
        assert r.success, r.message
    finally:
        node.stop()
    with open(path) as f:
        text = f.read()
    lines = text.splitlines()
    assert lines[0] == "# tracer_calib: params format 2", text
    # Every line of the integrator's file is there, in its order; the tracer's own keys
    # follow its last one, before the PLC's section.
    kept = iter(lines)
    assert all(any(ln == k for k in kept) for ln in SHARED_PARAMS.splitlines()), text
    mine = lines[lines.index("    output_frame_id: cell1_axis   # the edger's frame") + 1:lines.index("/cell1/plc:")]
    names = [ln.split(":")[0].strip() for ln in mine if ln.strip()]
    assert names[0] == "resample_points" and "calibration.alpha0" in names and "calibration.valid" in names, text
    assert "params_file" not in names and "history_file" not in names and "use_sim_time" not in names, text
    assert read_back_with_rclpy(path, "edger", "/cell1") == edger_before
    back = read_back_with_rclpy(path, "tracer", "/cell1")
    assert back["calibration.alpha0"] == r.alpha0 and back["resample_points"] == 200, back
    assert back["plate.side"] == 0.045 and back["output_frame_id"] == "cell1_axis", back

    # A flow map: not edited; a sibling holds the parameters and a restart reads it.
    flow = params_file("flow.yaml", "/**:\n  ros__parameters:\n    use_sim_time: false\n"
                       "/cell2/tracer: {ros__parameters: {plate.side: 0.045}}  # set by the line's PLC\n")
    with open(flow) as f:
        flow_text = f.read()
    sibling = os.path.join(WORK, "flow.persisted.cell2.tracer.yaml")
    node = NodeProcess("shared_flow", ["--params-file", flow, "-r", "__ns:=/cell2", "-r", "__node:=tracer"])
    try:
        pc = peer.param_client("/cell2/tracer")
        ok = peer.param(lambda: pc.set_parameters([Parameter("output_frame_id", value="cell2_axis")])).results[0]
        assert ok.successful, ok.reason
        diags = peer.subscribe(DiagnosticArray, "/diagnostics")

        def said():
            for d in diags:
                for st in d.status:
                    kv = {k.key: k.value for k in st.values}
                    if st.name.endswith("/cell2/tracer") and sibling in kv.get("persist_problem", ""):
                        return st
            return None
        peer.spin_until(lambda: said() is not None, 10, "/diagnostics naming the sibling file")
        st = said()
        assert st.level == DiagnosticStatus.WARN and "flow map" in st.message, (st.level, st.message)
    finally:
        node.stop()
    with open(flow) as f:
        assert f.read() == flow_text, "the file it could not edit is untouched"
    assert read_back_with_rclpy(sibling, "tracer", "/cell2")["output_frame_id"] == "cell2_axis"
    node = NodeProcess("shared_flow_again", ["--params-file", flow, "-r", "__ns:=/cell2", "-r", "__node:=tracer"])
    try:
        pc = peer.param_client("/cell2/tracer")
        got = peer.param(lambda: pc.get_parameters(["output_frame_id"])).values
        assert got[0].string_value == "cell2_axis", got
    finally:
        node.stop()


FIXTURES = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "fixtures")


def test_replay_foreign_bags(peer):
    """Bags written by a foreign tool (the `rosbags` package), MCAP and sqlite3, replayed
    into the running node with `tracer_calib replay`: the plate scan calibrates to the
    truth, and the lens comes back on its ellipse."""
    with open(os.path.join(FIXTURES, "rosbags_truth.json")) as f:
        truth = json.load(f)
    m = truth["mounting"]
    e = truth["ellipse"]
    lens = dict(cx=e["center"][0], cy=e["center"][1], a=e["width"] / 2, b=e["height"] / 2)
    for storage, name in truth["bags"].items():
        bag = os.path.join(FIXTURES, name)
        node = NodeProcess(f"replay_{storage}", ["-r", f"__node:=replay_{storage}"])
        try:
            contours = peer.subscribe(Contour, "/contour")
            # The node's contour publisher must know this subscriber before the replay
            # starts (a volatile topic drops what goes out before matching): one probe.
            probe = peer.publisher("/raw_scan")
            peer.send_scan(probe, raw_scan(999, RawScan.TARGET_LENS, *simulate("probe", "ellipse")), contours)
            contours.clear()

            def replay():
                out = subprocess.run(
                    [TOOL_BIN, "replay", "--input", bag, "--topic", "/raw_scan", "--rate", "20", "--wait", "15"],
                    capture_output=True, text=True, timeout=60,
                )
                assert out.returncode == 0, out.stderr
                assert "published 3 messages on /raw_scan" in out.stdout, out.stdout

            replay()
            peer.spin_until(lambda: {1, 2, 3} <= {c.scan_id for c in contours}, 10, f"3 contours from the {storage} bag")
            assert not any(c.calibrated for c in contours)
            r = peer.call("/calibrate", Calibrate.Request(scan_id=3))  # the plate scan with gaps
            assert r.success, r.message
            assert abs(r.alpha0 - m["alpha0"]) < 1e-4 and abs(r.offset - m["offset"]) < 5e-6, r
            assert abs(r.delta_l - m["delta_l"]) < 2e-6, r
            contours.clear()
            replay()
            peer.spin_until(lambda: any(c.scan_id == 2 and c.calibrated for c in contours), 10, "the corrected lens")
            c = next(c for c in contours if c.scan_id == 2 and c.calibrated)
            worst = max(ellipse_distance(p.x, p.y, lens) for p in c.points)
            assert worst < 5e-6, f"{storage}: lens points up to {worst * 1e6:.2f} µm off the ellipse"
            worst_r = max(abs(rk - ellipse_radius(2 * math.pi * k / len(c.radii), lens)) for k, rk in enumerate(c.radii))
            assert worst_r < 5e-6, f"{storage}: radii up to {worst_r * 1e6:.2f} µm off"
        finally:
            node.stop()


def test_bad_params_file_stops_the_node():
    """A params file with a wrong type stops the node with file, line and key, untouched."""
    path = params_file("bad.yaml", "tracer_calibrator:\n  ros__parameters:\n    plate.side: 0.045\n    resample_points: lots\n")
    before = open(path).read()
    out = subprocess.run([NODE_BIN, "--ros-args", "--params-file", path], capture_output=True, text=True, timeout=20)
    assert out.returncode != 0
    assert f"{path}:4: resample_points: expected an integer" in out.stderr, out.stderr
    assert open(path).read() == before


def test_encoder_scale(peer):
    """A tracer whose encoder reads 0.25 % long: `/calibrate` with the default model
    refuses it and names the scale; after `ros2 param set model full_scale` it fits the
    scale, reports it in the response, persists `calibration.scale`, and corrects a lens
    true to size."""
    k = 1 / 1.0025
    persisted = os.path.join(WORK, "scale.yaml")
    node = NodeProcess("scale", ["-p", f"params_file:={persisted}"])
    try:
        pub = peer.publisher("/raw_scan")
        contours = peer.subscribe(Contour, "/contour")
        peer.wait_matched(pub)
        plate = simulate("plate_k", "plate", noise=3e-6, seed=21, scale=k)
        peer.send_scan(pub, raw_scan(30, RawScan.TARGET_CALIBRATION_PLATE, *plate), contours)

        r = peer.call("/calibrate", Calibrate.Request())
        assert not r.success and "encoder scale looks off" in r.message and "full_scale" in r.message, r.message
        assert r.scale == 1.0 and r.scale_stddev == 0.0, r

        pc = peer.param_client("/tracer_calibrator")
        ok = peer.param(lambda: pc.set_parameters([Parameter("model", value="full_scale")])).results[0]
        assert ok.successful, ok.reason
        r = peer.call("/calibrate", Calibrate.Request())
        assert r.success, r.message
        assert 0 < r.scale_stddev < 2e-4 and abs(r.scale - k) < 5 * r.scale_stddev, r
        assert abs(r.offset - TRUTH["offset"]) < 5 * r.stddev[1], r
        got = peer.param(lambda: pc.get_parameters(["calibration.scale"])).values[0].double_value
        assert got == r.scale, got
        # The whole covariance, row-major over [alpha0, offset, delta_l, scale,
        # tip_radius]: the scale's variance is its stddev squared, dL and the scale move
        # together, no tip radius is fitted; the parameter holds it too.
        cov = list(r.covariance)
        assert len(cov) == 25, cov
        assert abs(cov[18] ** 0.5 - r.scale_stddev) <= 1e-12 * r.scale_stddev, (cov[18], r.scale_stddev)
        assert abs(cov[13]) / (cov[12] * cov[18]) ** 0.5 > 0.9, cov
        assert cov[20:] == [0.0] * 5 and r.tip_radius == 0.0 and r.tip_radius_stddev == 0.0, r
        got = peer.param(lambda: pc.get_parameters(["calibration.covariance"])).values[0].double_array_value
        assert list(got) == cov, got

        lens = simulate("lens_k", "ellipse", noise=0.0, seed=22, scale=k)
        c = peer.send_scan(pub, raw_scan(31, RawScan.TARGET_LENS, *lens), contours)
        worst = max(ellipse_distance(p.x, p.y) for p in c.points)
        assert c.calibrated and worst < 10e-6, f"corrected points up to {worst * 1e6:.1f} µm off the ellipse"
    finally:
        took = node.stop()
    assert took < 1.0, f"the node took {took:.2f} s to shut down"
    back = read_back_with_rclpy(persisted, "tracer_calibrator", "/")
    assert back["calibration.scale"] == r.scale and back["model"] == "full_scale", back
    assert list(back["calibration.covariance"]) == cov, back


def test_stylus_tip(peer):
    """A tracer touching with a 0.4 mm ball tip: with `model: full_tip` and
    `ring.diameter` the node fits the tip from the plate and the ring-gauge scan the
    request names, answers it in the response, holds it in `stylus.tip_radius` (and
    persists it), and corrects a lens to the surface the tip touched."""
    tip = 0.0004
    persisted = os.path.join(WORK, "tip.yaml")
    node = NodeProcess(
        "tip", ["-p", f"params_file:={persisted}", "-p", "model:=full_tip", "-p", "ring.diameter:=0.04"]
    )
    try:
        pub = peer.publisher("/raw_scan")
        contours = peer.subscribe(Contour, "/contour")
        peer.wait_matched(pub)
        plate = simulate("plate_tip", "plate", noise=3e-6, seed=41, tip_radius=tip)
        ring = simulate("ring_tip", "ring", noise=3e-6, seed=42, tip_radius=tip, ring_diameter=0.04)
        peer.send_scan(pub, raw_scan(50, RawScan.TARGET_CALIBRATION_PLATE, *plate), contours)
        r = peer.call("/calibrate", Calibrate.Request())
        assert not r.success and "TARGET_RING_GAUGE" in r.message, r.message
        peer.send_scan(pub, raw_scan(51, RawScan.TARGET_RING_GAUGE, *ring), contours)
        peer.send_scan(pub, raw_scan(52, RawScan.TARGET_RING_GAUGE, *plate), contours)  # not a ring
        r = peer.call("/calibrate", Calibrate.Request(ring_scan_id=52))
        assert not r.success and "ring" in r.message, r.message
        r = peer.call("/calibrate", Calibrate.Request(ring_scan_id=51))
        assert r.success, r.message
        assert 0 < r.tip_radius_stddev < 1e-6 and abs(r.tip_radius - tip) < 5 * r.tip_radius_stddev, r
        assert abs(r.delta_l - TRUTH["delta_l"]) < 5 * r.stddev[2], r
        assert abs(list(r.covariance)[24] ** 0.5 - r.tip_radius_stddev) <= 1e-12, r.covariance
        pc = peer.param_client("/tracer_calibrator")
        got = peer.param(lambda: pc.get_parameters(["stylus.tip_radius"])).values[0].double_value
        assert got == r.tip_radius, got
        lens = simulate("lens_tip", "ellipse", noise=0.0, seed=43, tip_radius=tip)
        c = peer.send_scan(pub, raw_scan(53, RawScan.TARGET_LENS, *lens), contours)
        worst = max(ellipse_distance(p.x, p.y) for p in c.points)
        assert c.calibrated and worst < 15e-6, f"corrected points up to {worst * 1e6:.1f} µm off the lens"
        # Its size figures, as rclpy reads them: the ellipse's own, within their U95.
        a, b = ELLIPSE["a"], ELLIPSE["b"]
        q = ((a - b) / (a + b)) ** 2
        circumference = math.pi * (a + b) * (1 + 3 * q / (10 + math.sqrt(4 - 3 * q)))
        truth = [circumference, 2 * a, 2 * b, 2 * a]
        got = [c.circumference, c.box_width, c.box_height, c.effective_diameter]
        u95 = list(c.size_u95)
        assert len(u95) == 4 and all(0 < u < 20e-6 for u in u95), u95
        assert all(abs(g - t) <= u for g, t, u in zip(got, truth, u95)), (got, truth, u95)
        assert len(c.radii_u95) == len(c.radii) == 400, len(c.radii_u95)
    finally:
        took = node.stop()
    assert took < 1.0, f"the node took {took:.2f} s to shut down"
    back = read_back_with_rclpy(persisted, "tracer_calibrator", "/")
    assert back["stylus.tip_radius"] == r.tip_radius and back["ring.diameter"] == 0.04, back
    assert back["model"] == "full_tip", back


def test_rosout(peer):
    """Every record the node logs at or above its level reaches /rosout as rcl publishes it:
    the logger name `ns.node`, the level, file, function (module) and line; reliable and
    transient local, so a console that joins late gets the start-up records. `--log-level
    NAME:=LEVEL` for the node's logger and `--disable-rosout-logs` do what rcl does."""
    from rcl_interfaces.msg import Log
    from rclpy.qos import DurabilityPolicy, QoSProfile

    def console():
        box = []
        qos = QoSProfile(depth=1000, durability=DurabilityPolicy.TRANSIENT_LOCAL)
        peer.node.create_subscription(Log, "/rosout", box.append, qos)
        return box

    steps, counts = simulate("plate_rosout", "plate", seed=5)
    lengths_differ = raw_scan(1, 1, steps, counts[:-1])
    node = NodeProcess("rosout", ["-r", "__ns:=/cell7", "-r", "__node:=tracer", "-r", "raw_scan:=/rosout_scan"])
    try:
        pub = peer.publisher("/rosout_scan")
        peer.wait_matched(pub)
        time.sleep(0.5)
        logs = console()  # a console that joins after the node started

        def mine(level=None, text=""):
            return [r for r in logs if r.name == "cell7.tracer" and (level is None or r.level == level) and text in r.msg]

        peer.spin_until(lambda: mine(Log.INFO, "listening on"), 10, "the start-up record, for a late console")
        pub.publish(lengths_differ)
        peer.spin_until(lambda: mine(Log.WARN, "rejected raw scan"), 10, "the rejected scan's warning on /rosout")
        r = mine(Log.WARN, "rejected raw scan")[0]
        assert r.file.endswith(".rs") and r.line > 0 and r.function.startswith("tracer_calib"), r
        assert "rejected raw scan" in node.output(), node.output()  # and on stderr
    finally:
        node.stop()

    # The node's logger at ERROR: its warnings stay off /rosout (and stderr); rosout off:
    # nothing at all, while stderr still has them.
    quiet = NodeProcess(
        "rosout_error", ["-r", "__ns:=/cell8", "-r", "__node:=tracer", "-r", "raw_scan:=/rosout_scan", "--log-level", "cell8.tracer:=error"]
    )
    off = NodeProcess(
        "rosout_off", ["-r", "__ns:=/cell9", "-r", "__node:=tracer", "-r", "raw_scan:=/rosout_scan", "--disable-rosout-logs"]
    )
    try:
        logs = console()
        pub = peer.publisher("/rosout_scan")
        peer.spin_until(lambda: pub.get_subscription_count() >= 2, 15, "both nodes on /rosout_scan")
        time.sleep(0.5)
        pub.publish(lengths_differ)
        peer.spin_until(lambda: "rejected raw scan" in off.output(), 10, "the warning on the rosout-less node's stderr")
        deadline = time.monotonic() + 2.0
        while time.monotonic() < deadline:
            peer.executor.spin_once(timeout_sec=0.05)
        assert not [r for r in logs if r.name == "cell9.tracer"], [r.msg for r in logs if r.name == "cell9.tracer"]
        assert not [r for r in logs if r.name == "cell8.tracer" and r.level < Log.ERROR], [
            r.msg for r in logs if r.name == "cell8.tracer"
        ]
        assert "rejected raw scan" not in quiet.output(), quiet.output()
    finally:
        quiet.stop()
        off.stop()


def test_driver_health(peer):
    """The tracer driver's health on /diagnostics, as diagnostic_updater lays a task out: a
    status of its own (`tracer_calib: /ns/node: tracer driver`, the node's hardware_id)
    that warns while nothing publishes raw_scan, is OK with the publishers counted and the
    scan rate while scans come, and warns when they stop for longer than
    driver.scan_timeout."""
    node = NodeProcess(
        "driver",
        ["-r", "__ns:=/cell5", "-r", "__node:=tracer", "-r", "raw_scan:=/drv_scan", "-p", "driver.scan_timeout:=2.0", "-p", "hardware_id:=SN-42"],
    )
    try:
        diags = peer.subscribe(DiagnosticArray, "/diagnostics")

        def driver():
            for d in reversed(diags):
                for s in d.status:
                    if s.name == "tracer_calib: /cell5/tracer: tracer driver":
                        return s, {v.key: v.value for v in s.values}
            return None, {}

        def shows(level, text):
            s, _ = driver()
            return s is not None and s.level == level and text in s.message

        peer.spin_until(lambda: shows(DiagnosticStatus.WARN, "no tracer driver"), 10, lambda: f"the missing driver: {driver()}")
        s, kv = driver()
        assert s.hardware_id == "SN-42" and kv["publishers"] == "0" and kv["topic"] == "/drv_scan", (s, kv)
        pub = peer.publisher("/drv_scan")
        steps, counts = simulate("drv_lens", "ellipse", seed=4)
        t_end = time.monotonic() + 3.0
        i = 0
        while time.monotonic() < t_end:
            pub.publish(raw_scan(100 + i, RawScan.TARGET_LENS, steps, counts))
            i += 1
            deadline = time.monotonic() + 0.2
            while time.monotonic() < deadline:
                peer.executor.spin_once(timeout_sec=0.05)
        peer.spin_until(lambda: shows(DiagnosticStatus.OK, "1 publisher(s) on /drv_scan; last scan"), 5, lambda: f"the driver present: {driver()}")
        s, kv = driver()
        assert kv["publishers"] == "1" and float(kv["scan_rate_hz"]) > 1.0, kv
        peer.spin_until(lambda: shows(DiagnosticStatus.WARN, "scans stopped"), 10, lambda: f"the driver stopped: {driver()}")
        # The calibration's status is still the first, its keys unchanged.
        d = diags[-1]
        assert d.status[0].name == "tracer_calib: /cell5/tracer" and d.status[0].hardware_id == "SN-42", d.status[0]
        assert any(v.key == "scans_received" for v in d.status[0].values), d.status[0]
    finally:
        node.stop()


def test_parameter_events(peer):
    """/parameter_events as a stock node publishes them, seen by rclpy's
    ParameterEventHandler: the node's fully qualified name; one event for a request that
    sets several parameters atomically, one for a calibration (its seven parameters
    together); the declarations' announcements, where they arrive, name declared ones."""
    from rclpy.parameter_event_handler import ParameterEventHandler

    events = []
    handler = ParameterEventHandler(peer.node)
    handle = handler.add_parameter_event_callback(events.append)
    node = NodeProcess("param_events", ["-r", "__ns:=/cell6", "-r", "__node:=tracer", "-r", "raw_scan:=/pe_scan"])
    try:
        pc = peer.param_client("/cell6/tracer")
        mine = lambda: [e for e in events if e.node == "/cell6/tracer"]  # noqa: E731
        # Discovery of the event writer by the handler's reader: an event after it is matched.
        # The writer is found by its node (a count would race with an earlier test's node
        # leaving the graph as this one joins it).
        ours = lambda: any(  # noqa: E731
            i.node_name == "tracer" and i.node_namespace == "/cell6"
            for i in peer.node.get_publishers_info_by_topic("/parameter_events")
        )
        peer.spin_until(ours, 10, "the node's event writer")

        def settle(seconds=0.5):
            deadline = time.monotonic() + seconds
            while time.monotonic() < deadline:
                peer.executor.spin_once(timeout_sec=0.05)

        def changing(name):
            return [e for e in mine() if name in {p.name for p in e.changed_parameters}]

        settle()  # the declarations' events, where they arrive (Zenoh: they do)
        r = peer.param(lambda: pc.set_parameters_atomically(
            [Parameter("output_frame_id", value="cell6_axis"), Parameter("calibration.max_age_days", value=30.0)]
        )).result
        assert r.successful, r.reason
        peer.spin_until(lambda: changing("output_frame_id"), 5, "the event of an atomic set")
        settle()
        sets = changing("output_frame_id") + changing("calibration.max_age_days")
        assert len(sets) == 2 and sets[0] is sets[1], [sorted(p.name for p in e.changed_parameters) for e in sets]
        e = sets[0]
        assert sorted(p.name for p in e.changed_parameters) == ["calibration.max_age_days", "output_frame_id"], e
        assert not e.new_parameters and not e.deleted_parameters, e

        pub = peer.publisher("/pe_scan")
        contours = peer.subscribe(Contour, "/cell6/contour")
        peer.wait_matched(pub)
        peer.send_scan(pub, raw_scan(1, RawScan.TARGET_CALIBRATION_PLATE, *simulate("plate_pe", "plate", seed=4)), contours)
        r = peer.call("/cell6/calibrate", Calibrate.Request(scan_id=1))
        assert r.success, r.message
        peer.spin_until(lambda: changing("calibration.alpha0"), 5, "the calibration's event")
        settle()
        cal = changing("calibration.alpha0")
        assert len(cal) == 1 and not changing("calibration.offset")[1:], [sorted(p.name for p in e.changed_parameters) for e in mine()]
        changed = {p.name for p in cal[0].changed_parameters}
        assert {"calibration.alpha0", "calibration.offset", "calibration.delta_l", "calibration.valid"} <= changed, changed
        # Announcements of declared parameters, where they arrived, name declared ones.
        declared = {p.name for e in mine() for p in e.new_parameters}
        assert declared <= set(peer.param(lambda: pc.list_parameters()).result.names) | {"use_sim_time"}, declared
    finally:
        node.stop()
        handler.remove_parameter_event_callback(handle)
