#!/usr/bin/env python3
"""The launch files, as `ros2 launch` would run them, against a real ROS 2 peer (rclpy).

No ROS launch runtime is on PyPI (no `launch`, `launch_ros` or `ros2` wheels), so this
reads each installed launch file itself: `<arg>` (defaults, and values given as
`name:=value`), `<let>`, `<include>` (its `<arg>` children), `<group>` (scoped),
`<push-ros-namespace>`, `<node>` with `args`, `ros_args`, `<param from=...>`,
`<param name value>` and `<remap>`; substitutions `$(var ...)`, `$(find-pkg-share ...)`,
`$(find-pkg-prefix ...)`, `$(env ...)`. Anything else is an error, not skipped. Each
`<node>` becomes the command line launch_ros builds (launch_ros/actions/node.py):

    PREFIX/lib/PKG/EXEC [args] [--ros-args ROS_ARGS] --ros-args [-r __node:=NAME]
        [-r __ns:=NS] [--params-file FILE | -p NAME:=VALUE]... [-r FROM:=TO]...

with PREFIX found through the ament index (`ros2 launch` and `ros2 run` do the same). The
processes are then started and checked with rclpy: both cells of edging_cell.launch.xml
calibrate and correct on their own topics, and a missing params file stops the node with
one line naming it. The launch runtime itself (event handlers, output handling,
respawn) is not run.

Run by tests/interop/run.sh inside a private network namespace, with a colcon workspace's
install/setup.bash sourced (tests/interop/workspace.sh builds it). Prints one line per
test and a closing 'N passed, N failed'.
"""

import os
import re
import shutil
import subprocess
import sys
import time
import xml.etree.ElementTree as ET

from ament_index_python.packages import get_package_prefix, get_package_share_directory

HERE = os.path.dirname(os.path.abspath(__file__))
PREFIX = get_package_prefix("tracer_calib")
SHARE = get_package_share_directory("tracer_calib")
NODE = os.path.join(PREFIX, "lib", "tracer_calib", "tracer_calib_node")
os.environ["TRACER_CALIB_NODE"] = NODE
os.environ["TRACER_CALIB"] = os.path.join(PREFIX, "lib", "tracer_calib", "tracer_calib")
sys.path.insert(0, HERE)

import rclpy  # noqa: E402

import harness as h  # noqa: E402  (Peer, raw_scan, ellipse geometry, read-back; reads TRACER_CALIB* set above)
from tracer_calib_msgs.msg import Contour, RawScan  # noqa: E402
from tracer_calib_msgs.srv import Calibrate  # noqa: E402

WORK = h.WORK


# ---------------------------------------------------------------------------------------
# The launch file reader


class LaunchError(Exception):
    pass


def prefix_namespace(base_ns, ns):
    """launch_ros.utilities.prefix_namespace."""
    if base_ns is None and ns is None:
        return None
    if ns is None:
        combined = base_ns
    elif not base_ns or ns.startswith("/"):
        combined = ns
    else:
        combined = ("" if base_ns == "/" else base_ns) + "/" + ns
    if combined and combined != "/" and combined.endswith("/"):
        combined = combined.rstrip("/")
    return combined


def make_namespace_absolute(ns):
    """launch_ros.utilities.make_namespace_absolute."""
    if ns is None:
        return None
    return ns if ns.startswith("/") else "/" + ns


class Context:
    def __init__(self, configs):
        self.configs = dict(configs)
        self.ros_namespace = None
        self.warnings = []


SUBST = re.compile(r"\$\(([a-z-]+)((?:\s+[^)\s]+)*)\s*\)")


def substitute(text, ctx, where):
    def one(m):
        kind, args = m.group(1), m.group(2).split()
        if kind == "var" and len(args) == 1:
            if args[0] not in ctx.configs:
                raise LaunchError(f"{where}: $(var {args[0]}): no such launch configuration")
            return ctx.configs[args[0]]
        if kind == "find-pkg-share" and len(args) == 1:
            return get_package_share_directory(args[0])
        if kind == "find-pkg-prefix" and len(args) == 1:
            return get_package_prefix(args[0])
        if kind == "env" and len(args) in (1, 2):
            if args[0] in os.environ:
                return os.environ[args[0]]
            if len(args) == 2:
                return args[1]
            raise LaunchError(f"{where}: $(env {args[0]}): not set")
        raise LaunchError(f"{where}: unsupported substitution {m.group(0)}")

    out = SUBST.sub(one, text)
    if "$(" in out:
        raise LaunchError(f"{where}: substitution not understood in {text!r}")
    return out


def cmdline(text, ctx, where):
    """launch's _parse_cmdline: split on the whitespace outside substitutions, then
    substitute each token (a value with spaces stays one argument)."""
    return [substitute(tok, ctx, where) for tok in re.findall(r"(?:\$\([^)]*\)|[^\s$]|\$(?!\())+", text)]


def node_command(n, ctx, where):
    attrs = dict(n.attrib)
    pkg = substitute(attrs.pop("pkg"), ctx, where)
    exe = substitute(attrs.pop("exec"), ctx, where)
    cmd = [os.path.join(get_package_prefix(pkg), "lib", pkg, exe)]
    if "args" in attrs:
        cmd += cmdline(attrs.pop("args"), ctx, where)
    if "ros_args" in attrs:
        cmd += ["--ros-args"] + cmdline(attrs.pop("ros_args"), ctx, where)
    cmd += ["--ros-args"]
    if "name" in attrs:
        cmd += ["-r", "__node:=" + substitute(attrs.pop("name"), ctx, where)]
    ns = substitute(attrs.pop("namespace"), ctx, where) if "namespace" in attrs else None
    ns = make_namespace_absolute(prefix_namespace(ctx.ros_namespace, ns))
    if ns is not None:
        cmd += ["-r", "__ns:=" + ns]
    attrs.pop("output", None)  # where launch sends the output: not part of the command
    if attrs:
        raise LaunchError(f"{where}: <node> attributes not understood: {sorted(attrs)}")
    for child in n:
        if child.tag == "param" and "from" in child.attrib:
            path = substitute(child.get("from"), ctx, where)
            if not os.path.isfile(path):
                # launch_ros warns and leaves the file out.
                ctx.warnings.append(f"Parameter file path is not a file: {path}")
                continue
            cmd += ["--params-file", path]
        elif child.tag == "param":
            cmd += ["-p", f"{substitute(child.get('name'), ctx, where)}:={substitute(child.get('value'), ctx, where)}"]
        elif child.tag == "remap":
            cmd += ["-r", f"{substitute(child.get('from'), ctx, where)}:={substitute(child.get('to'), ctx, where)}"]
        else:
            raise LaunchError(f"{where}: <node> child <{child.tag}> not understood")
    return cmd


def process(elem, ctx, nodes, path):
    for child in elem:
        where = f"{path}: <{child.tag}>"
        if child.tag == "arg":
            name = child.get("name")
            if name not in ctx.configs:
                if "default" not in child.attrib:
                    raise LaunchError(f"{path}: launch argument '{name}' has no default and was not given")
                ctx.configs[name] = substitute(child.get("default"), ctx, where)
        elif child.tag == "let":
            ctx.configs[child.get("name")] = substitute(child.get("value"), ctx, where)
        elif child.tag == "group":
            saved = (dict(ctx.configs), ctx.ros_namespace)
            process(child, ctx, nodes, path)
            if child.get("scoped", "true") == "true":
                ctx.configs, ctx.ros_namespace = saved
        elif child.tag == "push-ros-namespace":
            ctx.ros_namespace = prefix_namespace(ctx.ros_namespace, substitute(child.get("namespace"), ctx, where))
        elif child.tag == "include":
            inc = substitute(child.get("file"), ctx, where)
            for a in child:
                if a.tag != "arg":
                    raise LaunchError(f"{where}: child <{a.tag}> not understood")
                ctx.configs[a.get("name")] = substitute(a.get("value"), ctx, where)
            load_into(inc, ctx, nodes)
        elif child.tag == "node":
            nodes.append(node_command(child, ctx, where))
        else:
            raise LaunchError(f"{where}: element not understood")


def load_into(path, ctx, nodes):
    root = ET.parse(path).getroot()
    if root.tag != "launch":
        raise LaunchError(f"{path}: the root element is <{root.tag}>, not <launch>")
    process(root, ctx, nodes, path)


def launch_commands(file_name, *arguments):
    """`ros2 launch tracer_calib FILE name:=value ...` -> ([command line per node], warnings)."""
    configs = dict(a.split(":=", 1) for a in arguments)
    ctx = Context(configs)
    nodes = []
    load_into(os.path.join(SHARE, "launch", file_name), ctx, nodes)
    return nodes, ctx.warnings


# ---------------------------------------------------------------------------------------
# Running what the launch file says


class Launched:
    """One node process of a launch file, stopped with SIGTERM."""

    def __init__(self, label, cmd):
        self.label = label
        self.log_path = os.path.join(WORK, label + ".log")
        self.log = open(self.log_path, "w")
        self.proc = subprocess.Popen(cmd, stdout=self.log, stderr=subprocess.STDOUT)
        h.RUNNING.append(self)

    def check_alive(self):
        if self.proc.poll() is not None:
            raise AssertionError(f"{self.label}: exited with {self.proc.returncode}:\n{self.output()}")

    def stop(self):
        if self in h.RUNNING:
            h.RUNNING.remove(self)
        if self.proc.poll() is None:
            self.proc.terminate()
            try:
                self.proc.wait(timeout=5)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()
                raise AssertionError(f"{self.label}: did not exit within 5 s of SIGTERM")

    def output(self):
        self.log.flush()
        with open(self.log_path) as f:
            return f.read()


def simulate(name, shape, truth, meters_per_count, seed):
    """A scan from the installed `tracer_calib simulate`, as (steps, counts)."""
    path = os.path.join(WORK, name + ".csv")
    cmd = [
        os.environ["TRACER_CALIB"], "simulate", f"--shape={shape}", f"--alpha0-deg={truth['alpha0_deg']}",
        f"--offset={truth['offset']}", f"--delta-l={truth['delta_l']}", "--noise=5e-6", f"--seed={seed}",
        f"--meters-per-count={meters_per_count}", f"--out={path}",
    ]
    if shape == "ellipse":
        e = h.ELLIPSE
        cmd += [f"--width={2 * e['a']}", f"--height={2 * e['b']}", f"--center-x={e['cx']}", f"--center-y={e['cy']}"]
    subprocess.run(cmd, check=True)
    with open(path) as f:
        next(f)
        rows = [tuple(int(v) for v in line.strip().split(",")) for line in f]
    return [s for s, _ in rows], [c for _, c in rows]


# ---------------------------------------------------------------------------------------
# Tests


def test_default_launch(peer):
    """tracer_calib.launch.xml with its defaults: one node at the root namespace, named
    tracer_calibrator, reading the installed config/tracer_calib.yaml."""
    nodes, warnings = launch_commands("tracer_calib.launch.xml")
    installed = os.path.join(SHARE, "config", "tracer_calib.yaml")
    want = [NODE, "--ros-args", "--params-file", installed, "--log-level", "warn",
            "--ros-args", "-r", "__node:=tracer_calibrator", "-r", "__ns:=/"]
    assert nodes == [want], nodes
    assert not warnings, warnings
    before = open(installed).read()
    node = Launched("default", nodes[0])
    try:
        r = peer.call("/calibrate", Calibrate.Request(dry_run=True))
        assert not r.success and r.message, r  # no plate scan yet: answered, not applied
        client = peer.param_client("/tracer_calibrator")
        got = peer.param(lambda: client.get_parameters(["plate.side", "params_file", "model"]))
        values = [v.double_value or v.string_value for v in got.values]
        assert values == [0.045, installed, "full"], values
    finally:
        node.stop()
    assert open(installed).read() == before, "the installed params file changed"


def test_edging_cell(peer):
    """edging_cell.launch.xml: /cell1/tracer and /cell2/tracer, each with its own params
    file (different encoder scales), each calibrating and correcting on its own topics."""
    files = {}
    for cell in ("cell1", "cell2"):
        files[cell] = os.path.join(WORK, f"{cell}_tracer.yaml")
        shutil.copy(os.path.join(SHARE, "config", f"{cell}_tracer.yaml"), files[cell])
    nodes, warnings = launch_commands(
        "edging_cell.launch.xml", f"cell1_params_file:={files['cell1']}", f"cell2_params_file:={files['cell2']}",
        "log_level:=info")
    assert not warnings, warnings
    want = [[NODE, "--ros-args", "--params-file", files[c], "--log-level", "info",
             "--ros-args", "-r", "__node:=tracer", "-r", f"__ns:=/{c}"] for c in ("cell1", "cell2")]
    assert nodes == want, nodes
    cells = {
        "cell1": dict(truth=dict(alpha0_deg=1.5, offset=0.004, delta_l=0.001), mpc=0.5e-6, first_id=100),
        "cell2": dict(truth=dict(alpha0_deg=-3.0, offset=-0.007, delta_l=0.0025), mpc=1.0e-6, first_id=200),
    }
    running = [Launched(c, cmd) for c, cmd in zip(cells, nodes)]
    try:
        pubs = {c: peer.publisher(f"/{c}/raw_scan") for c in cells}
        contours = {c: peer.subscribe(Contour, f"/{c}/contour") for c in cells}
        for i, (c, cell) in enumerate(cells.items()):
            plate = simulate(f"plate_{c}", "plate", cell["truth"], cell["mpc"], seed=20 + i)
            got = peer.send_scan(pubs[c], h.raw_scan(cell["first_id"], RawScan.TARGET_CALIBRATION_PLATE, *plate), contours[c])
            assert not got.calibrated
        for c, cell in cells.items():
            r = peer.call(f"/{c}/calibrate", Calibrate.Request())
            assert r.success, (c, r.message)
            t = cell["truth"]
            assert abs(r.alpha0 * 180 / 3.141592653589793 - t["alpha0_deg"]) < 0.1, (c, r)
            assert abs(r.offset - t["offset"]) < 5e-5 and abs(r.delta_l - t["delta_l"]) < 2e-5, (c, r)
        for i, (c, cell) in enumerate(cells.items()):
            lens = simulate(f"lens_{c}", "ellipse", cell["truth"], cell["mpc"], seed=30 + i)
            got = peer.send_scan(pubs[c], h.raw_scan(cell["first_id"] + 1, RawScan.TARGET_LENS, *lens), contours[c])
            assert got.calibrated and got.header.frame_id == f"{c}_tracer_axis", (c, got.header)
            worst = max(h.ellipse_distance(p.x, p.y) for p in got.points)
            assert worst < 1e-4, (c, worst)
        # Each cell's contours carry its own scans only.
        for c, cell in cells.items():
            ids = {m.scan_id for m in contours[c]}
            assert ids == {cell["first_id"], cell["first_id"] + 1}, (c, ids)
        # Each node persisted its calibration into its own params file; a stock rclpy node
        # reads it back under the node's fully qualified name.
        for c, cell in cells.items():
            back = h.read_back_with_rclpy(files[c], "tracer", f"/{c}")
            assert back["calibration.valid"] is True, (c, back)
            assert abs(back["encoder.meters_per_count"] - cell["mpc"]) < 1e-15, (c, back)
            assert abs(back["calibration.offset"] - cell["truth"]["offset"]) < 5e-5, (c, back)
    finally:
        for n in running:
            n.stop()


def test_missing_params_file():
    """params_file:=a missing file: the node stops at once with one line naming the file."""
    missing = os.path.join(WORK, "no_such_dir", "cell9_tracer.yaml")
    nodes, warnings = launch_commands("tracer_calib.launch.xml", "namespace:=/cell9", f"params_file:={missing}")
    assert not warnings, warnings  # given as ros_args, launch passes it on as it is
    assert len(nodes) == 1 and ["--params-file", missing] == nodes[0][2:4], nodes
    t0 = time.monotonic()
    out = subprocess.run(nodes[0], capture_output=True, text=True, timeout=20)
    assert out.returncode != 0, out
    lines = [ln for ln in (out.stdout + out.stderr).splitlines() if ln.strip()]
    assert len(lines) == 1 and missing in lines[0] and "cannot read" in lines[0], lines
    assert time.monotonic() - t0 < 10


def test_ros2_run(peer):
    """`ros2 run tracer_calib tracer_calib_node --ros-args ...` (ros2_run.py: the ament
    index finds the installed node and execs it) calibrates on its namespaced topics."""
    params = os.path.join(WORK, "run_tracer.yaml")
    with open(params, "w") as f:
        f.write("/run/tracer:\n  ros__parameters:\n    plate.side: 0.045\n")
    cmd = [sys.executable, os.path.join(HERE, "ros2_run.py"), "tracer_calib", "tracer_calib_node",
           "--ros-args", "-r", "__ns:=/run", "-r", "__node:=tracer", "--params-file", params]
    node = Launched("ros2_run", cmd)
    try:
        truth = dict(alpha0_deg=2.0, offset=0.005, delta_l=0.002)
        contours = peer.subscribe(Contour, "/run/contour")
        plate = simulate("plate_run", "plate", truth, 1e-6, seed=40)
        peer.send_scan(peer.publisher("/run/raw_scan"), h.raw_scan(7, RawScan.TARGET_CALIBRATION_PLATE, *plate), contours)
        r = peer.call("/run/calibrate", Calibrate.Request())
        assert r.success and abs(r.offset - truth["offset"]) < 5e-5, r
        # ros2_run.py exec'd the node: the process is the installed node itself.
        assert os.readlink(f"/proc/{node.proc.pid}/exe") == os.path.realpath(NODE)
    finally:
        node.stop()


def test_reader_refuses_what_it_does_not_know():
    """The reader is strict: an unknown element or substitution is an error, not skipped."""
    bad = os.path.join(WORK, "bad.launch.xml")
    for body, what in [
        ('<launch><executable cmd="x"/></launch>', "element not understood"),
        ('<launch><arg name="a" default="$(command ls)"/></launch>', "unsupported substitution"),
        ('<launch><node pkg="tracer_calib" exec="tracer_calib_node" respawn="true"/></launch>', "not understood"),
        ('<launch><arg name="a"/></launch>', "has no default"),
    ]:
        with open(bad, "w") as f:
            f.write(body)
        try:
            load_into(bad, Context({}), [])
        except LaunchError as e:
            assert what in str(e), (body, e)
        else:
            raise AssertionError(f"accepted: {body}")


def main():
    rclpy.init()
    peer = h.Peer("launch_peer")
    tests = [
        ("reader_refuses_what_it_does_not_know", test_reader_refuses_what_it_does_not_know),
        ("default_launch", lambda: test_default_launch(peer)),
        ("edging_cell", lambda: test_edging_cell(peer)),
        ("missing_params_file", test_missing_params_file),
        ("ros2_run", lambda: test_ros2_run(peer)),
    ]
    only = [a.removeprefix("test_") for a in sys.argv[1:]]
    failed = h.run_tests(tests, only, "launch::", "launch")
    if failed == 0:
        shutil.rmtree(WORK, ignore_errors=True)
    sys.stdout.flush()
    os._exit(0 if failed == 0 else 1)


if __name__ == "__main__":
    main()
