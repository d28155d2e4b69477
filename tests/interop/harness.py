"""What the interop tests share, with ROS (rclpy and the generated tracer_calib_msgs):
the node under test as a process, the rclpy peer, scans, ellipse geometry, params files
and their read-back by a stock rclpy node (the suites' fixtures, in conftest.py, build on
it).

Imported by the test scripts (test_node.py, test_records.py, test_graph.py,
test_launch.py, cell_graph.py, and test_two_hosts.py's peer process); test_zenoh.py
runs test_node.py's, test_records.py's and some of test_runtime.py's tests on Zenoh. What
needs no ROS is in processes.py (test_two_hosts.py's controller imports only that).

At import: NODE_BIN and TOOL_BIN from $TRACER_CALIB_NODE and $TRACER_CALIB (run.sh sets
them to the release binaries in cargo's target directory); WORK, a fresh temporary
directory for scans, params files and node logs.
"""

import json
import math
import os
import socket
import subprocess
import sys
import tempfile
import time

from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.parameter_client import AsyncParameterClient
from rclpy.qos import QoSProfile

from tracer_calib_msgs.msg import Contour, RawScan
from tracer_calib_msgs.srv import Calibrate

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import processes  # noqa: E402

NODE_BIN = os.environ["TRACER_CALIB_NODE"]
TOOL_BIN = os.environ["TRACER_CALIB"]
WORK = tempfile.mkdtemp(prefix="tracer_calib_interop_")
TRUTH = dict(alpha0_deg=2.0, offset=0.005, delta_l=0.002)
ELLIPSE = dict(cx=0.0008, cy=-0.0005, a=0.025, b=0.015)


def simulate(name, shape, noise=5e-6, seed=1, **kw):
    """A scan from `tracer_calib simulate`, as (steps, counts). `meters_per_count`: the
    encoder's (the tool's default, 1 µm, unless given)."""
    path = os.path.join(WORK, name + ".csv")
    args = dict(
        shape=shape,
        alpha0_deg=kw.get("alpha0_deg", TRUTH["alpha0_deg"]),
        offset=kw.get("offset", TRUTH["offset"]),
        delta_l=kw.get("delta_l", TRUTH["delta_l"]),
        scale=kw.get("scale", 1.0),
        noise=noise,
        seed=seed,
        out=path,
    )
    for extra in ("meters_per_count", "tip_radius", "ring_diameter"):
        if extra in kw:
            args[extra] = kw[extra]
    if shape == "ellipse":
        args.update(width=2 * ELLIPSE["a"], height=2 * ELLIPSE["b"], center_x=ELLIPSE["cx"], center_y=ELLIPSE["cy"])
    cmd = [TOOL_BIN, "simulate"] + [f"--{k.replace('_', '-')}={v}" for k, v in args.items()]
    subprocess.run(cmd, check=True)
    steps, counts = [], []
    with open(path) as f:
        next(f)
        for line in f:
            s, c = line.strip().split(",")
            steps.append(int(s))
            counts.append(int(c))
    return steps, counts


def raw_scan(scan_id, target, steps, counts, n=400):
    msg = RawScan()
    msg.header.frame_id = "tracer"
    msg.header.stamp.sec = 1700000000 + scan_id
    msg.scan_id = scan_id
    msg.target = target
    msg.steps_per_revolution = n
    msg.step = steps
    msg.counts = counts
    return msg


def rosidl_hash(ros_type):
    """The hash rosidl generated for `pkg/kind/Name` (a service half: `pkg/srv/S_Request`),
    from the `.json` the ament prefixes install."""
    package, kind, name = ros_type.split("/")
    file_name = name.removesuffix("_Request").removesuffix("_Response").removesuffix("_Event")
    for prefix in os.environ["AMENT_PREFIX_PATH"].split(":"):
        path = os.path.join(prefix, "share", package, kind, file_name + ".json")
        if os.path.exists(path):
            with open(path) as f:
                hashes = json.load(f)["type_hashes"]
            return next(h["hash_string"] for h in hashes if h["type_name"] == ros_type)
    raise AssertionError(f"no rosidl .json for {ros_type}")


RUNNING = []


class NodeProcess:
    """tracer_calib_node in a subprocess, stopped with SIGTERM. `argv`, if given, is the
    command that runs the node instead of `NODE_BIN --ros-args ROS_ARGS`; `peer=True`
    runs it with the peer's environment whole (a stock rclpy node in the node's place);
    `log_filters` (env_logger's, e.g. "ros2_client::service::server=debug") are added to
    the node's RUST_LOG."""

    def __init__(self, label, ros_args=(), argv=None, peer=False, log_filters=None):
        self.label = label
        self.log_path = os.path.join(WORK, label + ".log")
        self.log = open(self.log_path, "w")
        argv = argv or [NODE_BIN, "--ros-args", *ros_args]
        # The node never takes a peer's preload (the SONAME shims that put rclpy on Cyclone
        # DDS or rmw_zenoh_cpp): it speaks its middleware itself.
        env = {k: v for k, v in os.environ.items() if peer or k != "LD_PRELOAD"}
        if log_filters:
            env["RUST_LOG"] = ",".join(f for f in (env.get("RUST_LOG"), log_filters) if f)
        self.proc = subprocess.Popen(argv, stdout=self.log, stderr=subprocess.STDOUT, env=env)
        RUNNING.append(self)

    def check_alive(self):
        if self.proc.poll() is not None:
            raise AssertionError(f"{self.label}: the node exited with {self.proc.returncode}:\n{self.output()}")

    def stop(self, timeout=5):
        """SIGTERM, then the seconds it took to exit."""
        if self in RUNNING:
            RUNNING.remove(self)
        took = processes.terminate(self.proc, timeout)
        if took is None:
            raise AssertionError(f"{self.label}: did not exit within {timeout} s of SIGTERM")
        return took

    def output(self):
        self.log.flush()
        with open(self.log_path) as f:
            return f.read()


def node_in_mount_namespace(label, script):
    """`script` (sh, starting the node) as a NodeProcess in a mount namespace of its own,
    so that what it mounts (a tmpfs, a read-only bind) is the node's alone."""
    return NodeProcess(label, argv=["unshare", "--mount", "--propagation", "private", "sh", "-c", script])


class Peer:
    """An rclpy node with helpers that wait with deadlines."""

    def __init__(self, name="interop_peer", context=None):
        """`context`: an rclpy Context of its own (a DDS participant of its own), or the
        default one."""
        self.node = Node(name, context=context)
        self.executor = SingleThreadedExecutor(context=context)
        self.executor.add_node(self.node)
        self.received = {}

    def spin_until(self, cond, timeout, what):
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            if cond():
                return
            for n in RUNNING:
                n.check_alive()
            self.executor.spin_once(timeout_sec=0.05)
        raise AssertionError(f"timed out after {timeout} s waiting for {what() if callable(what) else what}")

    def subscribe(self, msg_type, topic):
        box = []
        self.node.create_subscription(msg_type, topic, box.append, QoSProfile(depth=50))
        return box

    def publisher(self, topic):
        return self.node.create_publisher(RawScan, topic, QoSProfile(depth=50))

    def wait_matched(self, pub, timeout=15):
        self.spin_until(lambda: pub.get_subscription_count() > 0, timeout, f"a subscriber on {pub.topic_name}")

    def retry(self, start, what, timeout=20, attempt=3.0):
        """Start a request (a future) and wait for it; if discovery was not complete in
        both directions yet (DDS matches each side on its own), ask again."""
        deadline = time.monotonic() + timeout
        while True:
            future = start()
            try:
                self.spin_until(future.done, min(attempt, max(0.1, deadline - time.monotonic())), what)
                return future.result()
            except AssertionError:
                if time.monotonic() >= deadline:
                    raise

    def call(self, service, request, timeout=20):
        client = self.node.create_client(Calibrate, service)
        self.spin_until(client.service_is_ready, timeout, f"service {service}")
        return self.retry(lambda: client.call_async(request), f"the response of {service}", timeout)

    def send_scan(self, pub, msg, contours, timeout=20):
        """Publish a scan until its contour comes back (a volatile topic drops what is
        sent before both sides have matched)."""
        self.wait_matched(pub)
        deadline = time.monotonic() + timeout
        while True:
            pub.publish(msg)
            try:
                self.spin_until(lambda: any(c.scan_id == msg.scan_id for c in contours), 1.0, "a contour")
                return next(c for c in contours if c.scan_id == msg.scan_id)
            except AssertionError:
                if time.monotonic() >= deadline:
                    raise AssertionError(f"no contour for scan {msg.scan_id} within {timeout} s")

    def param_client(self, node_fqn, timeout=20):
        client = AsyncParameterClient(self.node, node_fqn)
        self.spin_until(lambda: client.services_are_ready(), timeout, f"parameter services of {node_fqn}")
        return client

    def param(self, start, what="a parameter call"):
        return self.retry(start, what)

    def close(self):
        self.executor.remove_node(self.node)
        self.node.destroy_node()


ZENOH_ROUTER_PORT = 7447  # where rmw_zenoh_cpp and the node look for the router


def zenoh_close_timed_out(out):
    """Whether a finished stock process on rmw_zenoh_cpp (a `subprocess.run` result) failed
    only by rmw_zenoh_cpp 0.2.10's known failure as a process leaves, after its work is done:
    zenoh-c's session close timing out (docs/ros2-peer.md: "close operation timed out!",
    10 s, exit 1; rclpy's "Failed to close the session")."""
    text = out.stdout + out.stderr
    return out.returncode == 1 and any(m in text for m in ("Failed to close the session", "close operation timed out"))


def port_open(port):
    with socket.socket() as s:
        s.settimeout(0.2)
        return s.connect_ex(("127.0.0.1", port)) == 0


class ZenohRouter:
    """rmw_zenohd (TRACER_ZENOHD) on tcp/127.0.0.1:ZENOH_ROUTER_PORT only, its output in
    LOG_DIR/router.log, once it listens (within `wait` seconds). Under `timeout`: a router
    orphaned by a killed test ends too; stop() sends SIGTERM, which `timeout` passes on
    (SIGKILL would orphan it)."""

    def __init__(self, log_dir, wait=10.0):
        port = ZENOH_ROUTER_PORT
        assert not port_open(port), f"something listens on 127.0.0.1:{port} already"
        self.log_path = os.path.join(log_dir, "router.log")
        env = dict(os.environ, ZENOH_CONFIG_OVERRIDE=f'listen/endpoints=["tcp/127.0.0.1:{port}"]')
        self.proc = subprocess.Popen(
            ["timeout", "-s", "KILL", "300", os.environ["TRACER_ZENOHD"]],
            env=env, stdout=open(self.log_path, "w"), stderr=subprocess.STDOUT,
        )
        deadline = time.monotonic() + wait
        while not port_open(port):
            assert self.proc.poll() is None, f"rmw_zenohd exited with {self.proc.returncode}:\n{self.output()}"
            assert time.monotonic() < deadline, f"rmw_zenohd not listening after {wait} s:\n{self.output()}"
            time.sleep(0.05)

    def output(self):
        with open(self.log_path) as f:
            return f.read()

    def stop(self):
        processes.terminate(self.proc)


def peer_envs():
    """{"fastdds": env, "cyclone": env or None, "zenoh": env or None}: this environment on
    Fast DDS, and with target/ros/DISTRO/cyclone_env.sh or zenoh_env.sh sourced (when
    tests/interop/cyclone.sh or zenoh.sh made them)."""
    fast = {k: v for k, v in os.environ.items() if k not in ("LD_PRELOAD", "CYCLONEDDS_URI")}
    envs = {"fastdds": fast}
    for rmw in ("cyclone", "zenoh"):
        env_sh = os.path.join(os.environ.get("TRACER_ROS_DIR", ""), f"{rmw}_env.sh")
        envs[rmw] = None
        if os.path.isfile(env_sh):
            out = subprocess.run(
                ["bash", "-c", '. "$0" && env -0', env_sh], env=fast, capture_output=True, check=True
            ).stdout
            envs[rmw] = dict(kv.split("=", 1) for kv in out.decode().split("\0") if "=" in kv)
    return envs


def percentile(xs, p):
    xs = sorted(xs)
    return xs[min(len(xs) - 1, int(round(p / 100.0 * (len(xs) - 1))))]


def assert_fit(r, scan_id=None):
    """A /calibrate response that applied a fit of a simulated plate scan (`scan_id`, if
    given): success, and alpha0, d, dL within 0.1 deg, 50 um, 10 um of TRUTH."""
    assert r.success, r.message
    if scan_id is not None:
        assert r.message.startswith(f"scan {scan_id}:"), r.message
    assert abs(math.degrees(r.alpha0) - TRUTH["alpha0_deg"]) < 0.1, r
    assert abs(r.offset - TRUTH["offset"]) < 5e-5, r
    assert abs(r.delta_l - TRUTH["delta_l"]) < 1e-5, r


def calibrate_then_lens(peer, scan_id, name, seed, calibrate):
    """A plate scan `scan_id` to /raw_scan, `calibrate(scan_id)`, then a lens scan
    `scan_id + 1` (simulated with seeds `seed` and `seed + 1`): the calibrate response and
    the lens's Contour."""
    pub = peer.publisher("/raw_scan")
    contours = peer.subscribe(Contour, "/contour")
    plate = simulate(f"{name}_plate", "plate", seed=seed)
    peer.send_scan(pub, raw_scan(scan_id, RawScan.TARGET_CALIBRATION_PLATE, *plate), contours)
    r = calibrate(scan_id)
    lens = simulate(f"{name}_lens", "ellipse", seed=seed + 1)
    return r, peer.send_scan(pub, raw_scan(scan_id + 1, RawScan.TARGET_LENS, *lens), contours)


def ellipse_distance(x, y, e=ELLIPSE):
    """First-order distance of (x, y) from an ellipse (default: the simulated one), metres."""
    u, v = x - e["cx"], y - e["cy"]
    a2, b2 = e["a"] ** 2, e["b"] ** 2
    f = u * u / a2 + v * v / b2 - 1.0
    g = math.hypot(2 * u / a2, 2 * v / b2)
    return abs(f) / g


def ellipse_radius(phi, e=ELLIPSE):
    """Where the ray from the rotation axis at angle phi leaves an ellipse."""
    ux, uy = math.cos(phi), math.sin(phi)
    px, py = -e["cx"], -e["cy"]
    a2, b2 = e["a"] ** 2, e["b"] ** 2
    qa = ux * ux / a2 + uy * uy / b2
    qb = px * ux / a2 + py * uy / b2
    qc = px * px / a2 + py * py / b2 - 1.0
    return (-qb + math.sqrt(qb * qb - qa * qc)) / qa


def params_file(name, body):
    path = os.path.join(WORK, name)
    with open(path, "w") as f:
        f.write(body)
    return path


def read_back_with_rclpy(path, node_name, namespace):
    """Load a params file into a stock rclpy node with --params-file (a fresh process,
    as `ros2 run ... --ros-args --params-file` would) and return its parameters."""
    out = subprocess.run([sys.executable, processes.peer_program("params_read_back"), path, node_name, namespace],
                         capture_output=True, text=True, timeout=60)
    if out.returncode != 0:
        raise AssertionError(f"rclpy could not load {path}:\n{out.stderr}")
    # The last JSON line: a middleware may log after it (rmw_zenoh_cpp's session, closing).
    return json.loads(next(ln for ln in reversed(out.stdout.splitlines()) if ln.startswith("{")))
