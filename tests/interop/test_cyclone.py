"""tracer_calib_node with stock ROS 2 peers on Cyclone DDS: rclpy on rmw_cyclonedds_cpp
(built from source by tests/interop/cyclone.sh against Debian's Cyclone DDS), alone and
next to rclpy on rmw_fastrtps_cpp (Fast DDS) in one cell.

Run by tests/interop/run.sh inside a private network namespace, with
target/ros/DISTRO/env.sh and then target/ros/DISTRO/cyclone_env.sh sourced: this process's
rclpy is on Cyclone DDS (checked first). Node processes are started without the Cyclone
preload; Fast DDS peers are subprocesses with the Fast DDS environment of env.sh.

- cyclone_calibrate: a Cyclone peer publishes a lens and a plate scan (contours come
  back), calls /calibrate (answered, success, the fit right), and the lens comes back
  corrected; the node logs no unreadable request.
- cyclone_parameters: rclpy's parameter client on Cyclone lists, gets and sets the
  node's parameters (a bad value refused with its reason).
- cyclone_cli: the real `ros2 lifecycle get/set` (a managed node configured and activated),
  `ros2 service call`, `ros2 param get/set` and `ros2 topic info -v`
  from a Cyclone environment (when tests/interop/ros2cli.sh has installed them): the
  node's type hash read from USER_DATA, rosidl's; no type-hash warning from Cyclone.
- mixed_cell: a Cyclone client process and a Fast DDS client process, 30 /calibrate calls
  each at once, every one answered with the fit of the plate scan it named.

Run with pytest (conftest.py).
"""

import json
import os
import shutil
import subprocess
import sys

from rclpy.parameter import Parameter
from rclpy.utilities import get_rmw_implementation_identifier

from tracer_calib_msgs.msg import Contour, RawScan
from tracer_calib_msgs.srv import Calibrate

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
# The shared helpers (node processes, scans, an rclpy peer with deadlines).
import harness as tn  # noqa: E402
import pytest  # noqa: E402
import processes  # noqa: E402
from processes import peer_program  # noqa: E402

if get_rmw_implementation_identifier() != "rmw_cyclonedds_cpp":
    pytest.exit(f"test_cyclone.py: this rclpy is on {get_rmw_implementation_identifier()}, not rmw_cyclonedds_cpp: "
                "source cyclone_env.sh", returncode=2)
pytestmark = pytest.mark.cyclone

# This process's environment is Cyclone's; the preload is already in this interpreter.
# Children get it only when they are peers meant for Cyclone DDS.
CYCLONE_ENV = dict(os.environ)
FAST_ENV = {k: v for k, v in os.environ.items() if k not in ("LD_PRELOAD", "CYCLONEDDS_URI")}
FAST_ENV.update(
    RMW_IMPLEMENTATION="rmw_fastrtps_cpp",
    FASTDDS_DEFAULT_PROFILES_FILE=os.path.join(os.environ["TRACER_ROS_DIR"], "fastdds_localhost.xml"),
)
os.environ.pop("LD_PRELOAD", None)  # the node (and `tracer_calib simulate`) run without it

CALLS = 30


def node_warnings(node):
    """What the node logged about requests it could not read."""
    return [line for line in node.output().splitlines() if "cannot read" in line or "fits no service" in line]


def send_plate_scans(peer, ids_and_seeds):
    """Publish plate scans (scan id, seed) and wait for each one's contour."""
    pub = peer.publisher("/raw_scan")
    contours = peer.subscribe(Contour, "/contour")
    for scan_id, seed in ids_and_seeds:
        plate = tn.simulate(f"plate_{scan_id}", "plate", seed=seed)
        peer.send_scan(pub, tn.raw_scan(scan_id, RawScan.TARGET_CALIBRATION_PLATE, *plate), contours)
    return pub, contours


def test_cyclone_calibrate(peer):
    node = tn.NodeProcess("cyclone_calibrate")
    try:
        pub = peer.publisher("/raw_scan")
        contours = peer.subscribe(Contour, "/contour")
        lens = tn.simulate("cy_lens", "ellipse", seed=3)
        # Topics both ways: a scan from the Cyclone peer, its contour back to it.
        first = peer.send_scan(pub, tn.raw_scan(1, RawScan.TARGET_LENS, *lens), contours)
        assert first.calibrated is False

        r = peer.call("/calibrate", Calibrate.Request())
        assert not r.success and "no calibration-plate scan" in r.message, r.message

        plate = tn.simulate("cy_plate", "plate", seed=2)
        peer.send_scan(pub, tn.raw_scan(10, RawScan.TARGET_CALIBRATION_PLATE, *plate), contours)
        r = peer.call("/calibrate", Calibrate.Request())
        tn.assert_fit(r, 10)
        assert len(r.stddev) == 3 and r.samples_used == 400, r

        c = peer.send_scan(pub, tn.raw_scan(11, RawScan.TARGET_LENS, *lens), contours)
        assert c.calibrated and len(c.points) == 400
        worst = max(tn.ellipse_distance(p.x, p.y) for p in c.points)
        assert worst < 40e-6, f"corrected points up to {worst * 1e3:.4f} mm off the ellipse"
        raw_worst = max(tn.ellipse_distance(p.x, p.y) for p in first.points)
        assert raw_worst > 2e-3, f"uncorrected points only {raw_worst * 1e3:.3f} mm off?"
    finally:
        node.stop()
    bad = node_warnings(node)
    assert not bad, "\n".join(bad)
    return f"lens within {worst * 1e6:.1f} um after calibrating over Cyclone DDS"


def test_cyclone_parameters(peer):
    node = tn.NodeProcess("cyclone_params", ["-p", "resample_points:=100"])
    try:
        pc = peer.param_client("/tracer_calibrator")
        names = peer.param(lambda: pc.list_parameters()).result.names
        for n in ["calibration.alpha0", "plate.side", "model", "resample_points"]:
            assert n in names, (n, names)
        got = peer.param(lambda: pc.get_parameters(["plate.side", "resample_points", "model"])).values
        assert [got[0].double_value, got[1].integer_value, got[2].string_value] == [0.045, 100, "full"], got
        res = peer.param(lambda: pc.set_parameters([Parameter("plate.side", value=0.05)])).results
        assert res[0].successful, res[0].reason
        got = peer.param(lambda: pc.get_parameters(["plate.side"])).values
        assert got[0].double_value == 0.05, got
        res = peer.param(lambda: pc.set_parameters([Parameter("plate.side", value=-1.0)])).results
        assert not res[0].successful and "plate.side" in res[0].reason, res[0]
        got = peer.param(lambda: pc.get_parameters(["plate.side"])).values
        assert got[0].double_value == 0.05, got
    finally:
        node.stop()
    bad = node_warnings(node)
    assert not bad, "\n".join(bad)


def test_cyclone_cli(peer):
    if not shutil.which("ros2"):
        return "skipped: no ros2 command (tests/interop/ros2cli.sh installs it)"
    # Managed: `ros2 lifecycle` on Cyclone DDS too (GetState's request is rosidl's one-octet
    # placeholder, behind Cyclone's request header).
    node = tn.NodeProcess("cyclone_cli", ["-p", "managed:=true"])
    env = dict(CYCLONE_ENV, ROS2CLI_NO_DAEMON="1")

    def ros2(*args):
        out = subprocess.run(["timeout", "-s", "KILL", "60", "ros2", *args], env=env, capture_output=True, text=True)
        assert out.returncode == 0, f"ros2 {' '.join(args)}: {out.returncode}\n{out.stdout}\n{out.stderr}"
        # rmw_cyclonedds warns of every endpoint whose USER_DATA has no type hash.
        assert "type hash" not in out.stderr, f"ros2 {' '.join(args)}:\n{out.stderr}"
        return out.stdout

    try:
        assert ros2("lifecycle", "get", "--no-daemon", "/tracer_calibrator").strip() == "unconfigured [1]"
        for transition, state in (("configure", "inactive [2]"), ("activate", "active [3]")):
            assert "Transitioning successful" in ros2("lifecycle", "set", "--no-daemon", "/tracer_calibrator", transition)
            assert ros2("lifecycle", "get", "--no-daemon", "/tracer_calibrator").strip() == state
        send_plate_scans(peer, [(5, 4)])
        out = ros2("service", "call", "/calibrate", "tracer_calib_msgs/srv/Calibrate", "{dry_run: true}")
        assert "success=True" in out and "scan 5:" in out, out
        assert "Double value is: 0.045" in ros2("param", "get", "--no-daemon", "/tracer_calibrator", "plate.side")
        assert "Set parameter successful" in ros2("param", "set", "--no-daemon", "/tracer_calibrator", "model", "paper")
        assert "String value is: paper" in ros2("param", "get", "--no-daemon", "/tracer_calibrator", "model")
        # Every endpoint's type hash, as Cyclone reads it from USER_DATA: rosidl's.
        info = ros2("topic", "info", "--no-daemon", "-v", "/raw_scan")
        hashes = [line.split(":", 1)[1].strip() for line in info.splitlines() if "Topic type hash" in line]
        assert hashes and all(h == tn.rosidl_hash("tracer_calib_msgs/msg/RawScan") for h in hashes), info
    finally:
        node.stop()
    bad = node_warnings(node)
    assert not bad, "\n".join(bad)


def test_mixed_cell(peer):
    """A Cyclone client and a Fast DDS client, 30 calls each at once: every call answered
    with the fit of the scan it named (each reply in its client's layout, to its client)."""
    node = tn.NodeProcess("mixed_cell", ["-r", "__node:=mixed_tracer"])
    try:
        send_plate_scans(peer, [(21, 11), (22, 12)])
        procs = {
            name: subprocess.Popen(
                ["timeout", "-s", "KILL", "120", sys.executable, peer_program("cyclone_client"), str(CALLS), "21", "22"],
                env=env, stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True,
            )
            for name, env in (("cyclone", CYCLONE_ENV), ("fastdds", FAST_ENV))
        }
        for name, p in procs.items():
            line = p.stdout.readline().strip()
            assert line == "ready", f"{name} client: {line!r} (exit {p.poll()})"
        for p in procs.values():  # both bursts at once
            p.stdin.write("go\n")
            p.stdin.flush()
        results = {}
        for name, p in procs.items():
            out, _ = p.communicate(timeout=90)
            assert p.returncode == 0, f"{name} client exited with {p.returncode}: {out}"
            results[name] = json.loads(out.strip().splitlines()[-1])
        assert results["cyclone"]["rmw"] == "rmw_cyclonedds_cpp", results["cyclone"]["rmw"]
        assert results["fastdds"]["rmw"] == "rmw_fastrtps_cpp", results["fastdds"]["rmw"]
        fits = {}
        for name, r in results.items():
            missing = [c for c in r["calls"] if c[1] is None]
            assert not missing, f"{name}: {len(missing)} of {CALLS} calls not answered"
            for scan_id, success, message, alpha0 in r["calls"]:
                assert success, f"{name}: {message}"
                assert f"scan {scan_id}:" in message, f"{name} asked for scan {scan_id}, got: {message}"
                fits.setdefault(scan_id, set()).add(alpha0)
        # Each scan's fit is one value, whoever asked; the two scans' differ.
        assert all(len(v) == 1 for v in fits.values()), fits
        assert fits[21] != fits[22], fits
    finally:
        for p in locals().get("procs", {}).values():
            processes.kill(p)
        node.stop()
    bad = node_warnings(node)
    assert not bad, "\n".join(bad)
    return ", ".join(f"{n}: {CALLS} answered in {r['took'] * 1e3:.0f} ms" for n, r in results.items())
