#!/usr/bin/env python3
"""SROS2: tracer_calib_node (built with the cargo feature `security`) with a stock secure
ROS 2 peer, rclpy on rmw_cyclonedds_cpp with Debian's Cyclone DDS security plugins.

Run by tests/interop/run.sh (selector `security`, Jazzy only) inside a private network
namespace, with target/ros/DISTRO/env.sh and cyclone_env.sh sourced (this process's rclpy
is on Cyclone DDS, checked first), `ros2 security` installed (tests/interop/sros2.sh), and
$TRACER_CALIB_NODE_SECURE the secure build of the node.

At start: a keystore made by the real `ros2 security create_keystore`, and enclaves
`/tracer_calibrator` (the node) and `/planner` (this process) by `create_enclave`: the
default governance (discovery and liveliness ENCRYPT, RTPS SIGN, every topic ENCRYPT,
join and topic access control on) and permissions that allow everything. This process
then joins as `/planner`, Enforce.

- secure_calibrate: the node (enclave /tracer_calibrator, Enforce) and the secure peer
  find each other; a plate scan goes in, its contour comes back, /calibrate answers with
  the fit; the parameter services answer too. Reports discovery and round-trip times.
- secure_restart: the same with a new node process (a new participant in the same
  enclave) after the first one stopped, the peer still running.
- insecure_peer_sees_nothing: an rclpy process on Cyclone without security, beside a
  secure exchange: it sees no tracer_calibrator in its graph and gets no contour.
- enforce_missing_enclave: `--enclave /nowhere` under Enforce: the node exits non-zero at
  once with one line naming the enclave and the reason.
- permissive_missing_enclave: the same under Permissive: one warning, and the node runs
  (unsecured).

Prints one line per test and a closing 'N passed, N failed'.
"""

import json
import math
import os
import subprocess
import sys
import time

def make_keystore(work):
    ks = os.path.join(work, "keystore")
    env = {k: v for k, v in os.environ.items() if not k.startswith("ROS_SECURITY_")}
    for argv in (
        ["ros2", "security", "create_keystore", ks],
        ["ros2", "security", "create_enclave", ks, "/tracer_calibrator"],
        ["ros2", "security", "create_enclave", ks, "/planner"],
    ):
        out = subprocess.run(argv, capture_output=True, text=True, timeout=120, env=env)
        if out.returncode != 0:
            raise SystemExit(f"test_security.py: {' '.join(argv)} failed:\n{out.stdout}{out.stderr}")
    return ks


sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import harness as tn  # noqa: E402

KEYSTORE = make_keystore(tn.WORK)
SECURE_ENV = dict(ROS_SECURITY_ENABLE="true", ROS_SECURITY_STRATEGY="Enforce", ROS_SECURITY_KEYSTORE=KEYSTORE)
os.environ.update(SECURE_ENV)
# The Cyclone plugins (libdds_security_*.so) of Debian's libddsc0debian.
PLUGINS = "/usr/lib/x86_64-linux-gnu/libddsc0debian"
os.environ["LD_LIBRARY_PATH"] = PLUGINS + ":" + os.environ.get("LD_LIBRARY_PATH", "")

import rclpy  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402
from rclpy.utilities import get_rmw_implementation_identifier  # noqa: E402

from tracer_calib_msgs.msg import Contour, RawScan  # noqa: E402
from tracer_calib_msgs.srv import Calibrate  # noqa: E402

CYCLONE_ENV = dict(os.environ)
NODE_ENV = {k: v for k, v in os.environ.items() if k not in ("LD_PRELOAD", "CYCLONEDDS_URI")}
SECURE_NODE = os.environ.get("TRACER_CALIB_NODE_SECURE", tn.NODE_BIN)


class SecureNode(tn.NodeProcess):
    """The secure build of the node, in the given security environment."""

    def __init__(self, label, ros_args=(), env=None):
        self.label = label
        self.log_path = os.path.join(tn.WORK, label + ".log")
        self.log = open(self.log_path, "w")
        self.proc = subprocess.Popen(
            [SECURE_NODE, "--ros-args", *ros_args],
            stdout=self.log,
            stderr=subprocess.STDOUT,
            env=env if env is not None else NODE_ENV,
        )
        tn.RUNNING.append(self)


def test_secure_calibrate(peer, label="secure_calibrate"):
    t0 = time.monotonic()
    node = SecureNode(label, ["--enclave", "/tracer_calibrator"])
    try:
        pub = peer.publisher("/raw_scan")
        contours = peer.subscribe(Contour, "/contour")
        peer.wait_matched(pub, timeout=30)
        discovered = time.monotonic() - t0
        plate = tn.simulate("sec_plate", "plate", seed=2)
        t1 = time.monotonic()
        c = peer.send_scan(pub, tn.raw_scan(10, RawScan.TARGET_CALIBRATION_PLATE, *plate), contours)
        first_contour = time.monotonic() - t1
        assert len(c.points) == 400, c
        r = peer.call("/calibrate", Calibrate.Request(), timeout=30)
        assert r.success, r.message
        assert r.message.startswith("scan 10:"), r.message
        assert abs(math.degrees(r.alpha0) - tn.TRUTH["alpha0_deg"]) < 0.1, r
        assert abs(r.offset - tn.TRUTH["offset"]) < 5e-5, r
        # Round trips, once matched: scan -> contour.
        lens = tn.simulate("sec_lens", "ellipse", seed=3)
        times = []
        for i in range(20):
            msg = tn.raw_scan(100 + i, RawScan.TARGET_LENS, *lens)
            t2 = time.monotonic()
            peer.send_scan(pub, msg, contours)
            times.append(time.monotonic() - t2)
        times.sort()
        # The parameter services, secured too.
        client = peer.param_client("/tracer_calibrator", timeout=30)
        got = peer.param(lambda: client.get_parameters(["model"]))
        assert got.values[0].string_value == "full", got
        res = peer.param(lambda: client.set_parameters([Parameter("resample_points", value=200)]))
        assert res.results[0].successful, res
    finally:
        node.stop()
    return (
        f"matched after {discovered:.2f} s, first contour {first_contour * 1e3:.0f} ms, "
        f"scan->contour median {times[len(times) // 2] * 1e3:.1f} ms (20), calibrated, parameters answered"
    )


INSECURE_PEER = r"""
import json, sys, time, rclpy
from tracer_calib_msgs.msg import Contour
rclpy.init()
n = rclpy.create_node('insecure_peer')
got = []
n.create_subscription(Contour, '/contour', got.append, 10)
seen = set()
t0 = time.time()
while time.time() - t0 < float(sys.argv[1]):
    rclpy.spin_once(n, timeout_sec=0.1)
    seen.update(name for name, _ in n.get_node_names_and_namespaces())
print(json.dumps(dict(contours=len(got), nodes=sorted(seen))), flush=True)
import os; os._exit(0)
"""


def test_insecure_peer_sees_nothing(peer):
    node = SecureNode("insecure_peer", ["--enclave", "/tracer_calibrator"])
    env = {k: v for k, v in CYCLONE_ENV.items() if not k.startswith("ROS_SECURITY_")}
    spy = subprocess.Popen(
        [sys.executable, "-c", INSECURE_PEER, "10"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env
    )
    try:
        pub = peer.publisher("/raw_scan")
        contours = peer.subscribe(Contour, "/contour")
        lens = tn.simulate("sec_spy_lens", "ellipse", seed=5)
        sent = 0
        deadline = time.monotonic() + 8
        while time.monotonic() < deadline:
            peer.send_scan(pub, tn.raw_scan(200 + sent, RawScan.TARGET_LENS, *lens), contours, timeout=30)
            sent += 1
            pause = time.monotonic() + 0.5
            peer.spin_until(lambda: time.monotonic() >= pause, 5, "a pause")
        out, err = spy.communicate(timeout=30)
    finally:
        if spy.poll() is None:
            spy.kill()
        node.stop()
    lines = [line for line in out.splitlines() if line.startswith("{")]
    assert lines, f"the insecure peer printed nothing:\n{out}\n{err}"
    seen = json.loads(lines[-1])
    assert seen["contours"] == 0, f"the insecure peer got {seen['contours']} contours"
    assert "tracer_calibrator" not in seen["nodes"], f"the insecure peer saw {seen['nodes']}"
    return f"{sent} secure scans and contours; the insecure peer saw nodes {seen['nodes']} and 0 contours"


def run_missing(strategy):
    env = dict(NODE_ENV, ROS_SECURITY_STRATEGY=strategy)
    return SecureNode(f"missing_{strategy}", ["--enclave", "/nowhere"], env=env)


def test_enforce_missing_enclave(peer):
    node = run_missing("Enforce")
    t0 = time.monotonic()
    try:
        rc = node.proc.wait(timeout=10)
    finally:
        if node in tn.RUNNING:
            tn.RUNNING.remove(node)
    took = time.monotonic() - t0
    out = node.output().strip()
    assert rc != 0, f"exit code {rc}"
    lines = out.splitlines()
    assert len(lines) == 1, f"expected one line, got:\n{out}"
    assert "enclave '/nowhere'" in lines[0] and "does not exist" in lines[0], lines[0]
    return f"exit {rc} after {took * 1e3:.0f} ms: {lines[0]}"


def test_permissive_missing_enclave(peer):
    node = run_missing("Permissive")
    try:
        time.sleep(2.0)
        node.check_alive()
    finally:
        node.stop()
    warnings = [line for line in node.output().splitlines() if "running without security" in line]
    assert len(warnings) == 1, node.output()
    assert "'/nowhere'" in warnings[0], warnings[0]
    return "ran unsecured with one warning"


def main():
    rmw = get_rmw_implementation_identifier()
    if rmw != "rmw_cyclonedds_cpp":
        print(f"test_security.py: this rclpy is on {rmw}, not rmw_cyclonedds_cpp: source cyclone_env.sh", flush=True)
        os._exit(2)
    rclpy.init(args=["--ros-args", "--enclave", "/planner"])
    peer = tn.Peer("planner")
    tests = [
        ("secure_calibrate", lambda: test_secure_calibrate(peer)),
        # The node restarted (a new participant, the same enclave): the peer meets it again.
        ("secure_restart", lambda: test_secure_calibrate(peer, "secure_restart")),
        ("insecure_peer_sees_nothing", lambda: test_insecure_peer_sees_nothing(peer)),
        ("enforce_missing_enclave", lambda: test_enforce_missing_enclave(peer)),
        ("permissive_missing_enclave", lambda: test_permissive_missing_enclave(peer)),
    ]
    tn.run_tests_and_exit("test_security.py", tests, sys.argv[1:], "interop::", "security")

if __name__ == "__main__":
    main()
