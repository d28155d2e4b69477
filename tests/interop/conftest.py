"""pytest's side of the interop suites (tests/interop/run.sh runs each suite as
`python -m pytest SUITE.py --name NAME...` inside the network namespace it made, with the
distribution's peer environment sourced):

- fixtures: `peer`, the stock rclpy node of the suite (one per process and name; rclpy
  initialised once, with `rclpy_args`, which a suite may override: test_security.py's
  enclave); `nodes_stopped`, every node a test started and left running, stopped after it
  (autouse: harness.RUNNING);
- a suite whose module sets OWN_PROCESS_ATTEMPTS (test_security.py) has each test run by a
  pytest of its own, run again if that process crashed (SIGSEGV), up to that many times;
- `--name NAME`: the tests run.sh's names select, exactly (a test's name is its function's
  without `test_`, then `_PARAM` for a parametrized one; the suite's own name, e.g.
  `graph` or `lossy`, selects all of it, and `SUITE_NAME` one of its tests); an unknown
  name is a usage error listing the names there are. `-k`, `-m` and node ids work as
  pytest's own;
- markers: `distro(NAME...)` (the test runs only on those ROS 2 distributions: skipped,
  and counted so, on others) and the middleware a test's peers use (`fastdds`, `cyclone`,
  `zenoh`, `security`), to choose with `-m`;
- a test that returns a string has it printed on its result line (`PASSED (1.2 s) WHAT
  IT MEASURED`, and as the JUnit property `detail`); one that returns "skipped: WHY"
  (what it needs is not on this machine) is a skip, counted and printed as one;
- after a failure, the tail of every node log (harness.WORK) written while the test ran;
- at the end, harness.WORK removed if all passed (kept with TRACER_INTEROP_KEEP), and the
  process leaves with pytest's exit status without rclpy's shutdown, which can hang
  (docs/ros2-peer.md).
"""

import inspect
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from xml.etree import ElementTree

import pytest

_EXIT = pytest.StashKey[int]()
_CHILD = "TRACER_PYTEST_CHILD"  # set in a test's own process (OWN_PROCESS_ATTEMPTS)
_STARTED = pytest.StashKey[float]()


def pytest_addoption(parser):
    parser.addoption(
        "--name", action="append", default=[], metavar="NAME",
        help="run the test of this name (run.sh's names; repeatable); the suite's name: all of it",
    )


def pytest_configure(config):
    config.addinivalue_line("markers", "distro(*names): runs only on these ROS 2 distributions (ROS_DISTRO)")
    for rmw in ("fastdds", "cyclone", "zenoh", "security"):
        config.addinivalue_line("markers", f"{rmw}: the test's peers are on {rmw}")


def suite_of(item):
    """The suite's name: its file's without `test_` (graph, lossy, first_scan, ...)."""
    return item.module.__name__.removeprefix("test_")


def own_name(item):
    """A test's own name: its function's without `test_`, then `_PARAM` if parametrized."""
    own = item.originalname.removeprefix("test_")
    return f"{own}_{item.callspec.id}" if hasattr(item, "callspec") else own


def names_of(item):
    """The names that select `item`: its own, the suite's, and the suite's joined to its own."""
    own, suite = own_name(item), suite_of(item)
    return {own, suite, f"{suite}_{own}"}


def pytest_collection_modifyitems(config, items):
    wanted = config.getoption("name")
    distro = os.environ.get("ROS_DISTRO", "")
    for item in items:
        marker = item.get_closest_marker("distro")
        if marker and distro not in marker.args:
            item.add_marker(pytest.mark.skip(reason=f"ROS 2 {'/'.join(marker.args)} only (this is {distro or 'none'})"))
    if not wanted:
        return
    have = {name: [] for name in wanted}
    for item in items:
        for name in names_of(item) & set(wanted):
            have[name].append(item)
    unknown = sorted(name for name, found in have.items() if not found)
    if unknown:
        there = ", ".join(sorted({own_name(i) for i in items}))
        raise pytest.UsageError(f"no such test: {', '.join(unknown)} (have: {there})")
    chosen = {id(i) for found in have.values() for i in found}
    deselected = [i for i in items if id(i) not in chosen]
    items[:] = [i for i in items if id(i) in chosen]
    config.hook.pytest_deselected(items=deselected)


@pytest.fixture(scope="session")
def rclpy_args():
    """rclpy.init's arguments (a suite overrides it: test_security.py's enclave)."""
    return None


_PEERS = {}


@pytest.fixture(scope="session")
def ros(rclpy_args):
    """rclpy, initialised once per process; never shut down (the process leaves by
    os._exit: rclpy's shutdown can hang)."""
    import rclpy

    rclpy.init(args=rclpy_args)


def in_parent(module):
    """Whether this process only runs `module`'s tests each in a process of its own
    (OWN_PROCESS_ATTEMPTS), and so has no rclpy of its own."""
    return bool(getattr(module, "OWN_PROCESS_ATTEMPTS", 0)) and not os.environ.get(_CHILD)


@pytest.fixture(scope="module")
def peer(request):
    """The suite's stock rclpy node, `PEER_NAME` of the suite's module (default
    `SUITE_peer`); one per name in the process (test_node.py and test_records.py share
    theirs, as one graph participant). None where each test runs in a process of its own
    (the process the test runs in has it)."""
    if in_parent(request.module):
        return None
    request.getfixturevalue("ros")
    import harness

    name = getattr(request.module, "PEER_NAME", f"{request.module.__name__.removeprefix('test_')}_peer")
    if name not in _PEERS:
        _PEERS[name] = harness.Peer(name)
    return _PEERS[name]


@pytest.fixture(autouse=True)
def nodes_stopped():
    """After each test, every node it started and left running (harness.RUNNING) stopped."""
    yield
    harness = sys.modules.get("harness")
    for node in list(harness.RUNNING if harness else []):
        try:
            node.stop()
        except AssertionError as e:  # did not exit on SIGTERM: killed by stop's terminate
            print(f"conftest: {e}", flush=True)


@pytest.hookimpl(tryfirst=True)
def pytest_pyfunc_call(pyfuncitem):
    """The test called with its fixtures (or in a process of its own); what it returns
    kept (see the module doc)."""
    if in_parent(pyfuncitem.module):
        result = in_own_process(pyfuncitem, pyfuncitem.module.OWN_PROCESS_ATTEMPTS)
    else:
        fn = pyfuncitem.obj
        params = inspect.signature(fn).parameters
        result = fn(**{name: pyfuncitem.funcargs[name] for name in params if name in pyfuncitem.funcargs})
    if isinstance(result, str):
        if result.startswith("skipped:"):
            pytest.skip(result.removeprefix("skipped:").strip())
        if result:
            pyfuncitem.user_properties.append(("detail", result))
    return True


def in_own_process(item, attempts):
    """`item` run by a pytest of its own (its output streams through), in a process group
    of its own that is killed afterwards with whatever it left running; run again, up to
    `attempts` times in all, if it crashed (SIGSEGV). Its result as this process's: what
    it returned, its skip, or its failure."""
    report = os.path.join(tempfile.mkdtemp(prefix="tracer_calib_pytest_"), "report.xml")
    argv = [sys.executable, "-m", "pytest", "-c", str(item.config.inipath), "--rootdir", str(item.config.rootpath),
            "--no-header", "--junitxml", report, f"{item.path}::{item.name}"]
    for attempt in range(1, attempts + 1):
        proc = subprocess.Popen(argv, env=dict(os.environ, **{_CHILD: "1"}), start_new_session=True)
        try:
            rc = proc.wait()
        finally:
            try:
                os.killpg(proc.pid, signal.SIGKILL)
            except ProcessLookupError:
                pass
        if rc != -signal.SIGSEGV:
            break
        again = ": run again" if attempt < attempts else ""
        print(f"conftest: {item.name}: its process crashed (SIGSEGV){again}", flush=True)
    case = ElementTree.parse(report).find(".//testcase") if os.path.exists(report) else None
    shutil.rmtree(os.path.dirname(report), ignore_errors=True)
    if rc == 0 and case is not None and case.find("skipped") is not None:
        pytest.skip(case.find("skipped").get("message", ""))
    if rc != 0 or case is None:
        raise AssertionError(f"{item.name}: its process exited with {rc} (its output above)")
    details = [p.get("value") for p in case.iter("property") if p.get("name") == "detail"]
    return details[0] if details else None


def pytest_runtest_setup(item):
    item.stash[_STARTED] = time.time()


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_makereport(item, call):
    outcome = yield
    report = outcome.get_result()
    harness = sys.modules.get("harness")
    if report.when != "call" or not report.failed or harness is None:
        return
    started = item.stash.get(_STARTED, 0.0)
    for log in sorted(os.listdir(harness.WORK)) if os.path.isdir(harness.WORK) else []:
        path = os.path.join(harness.WORK, log)
        try:
            if log.endswith(".log") and os.path.getmtime(path) >= started - 1.0:
                with open(path, errors="replace") as f:
                    report.sections.append((f"node log {log} (its tail)", f.read()[-3000:]))
        except OSError:
            pass  # gone meanwhile


def pytest_report_teststatus(report, config):
    """`PASSED (1.2 s) WHAT IT MEASURED` on a test's line."""
    if report.when == "call" and report.passed:
        detail = dict(report.user_properties).get("detail", "")
        return "passed", ".", (f"PASSED ({report.duration:.1f} s) {detail}".rstrip(), {"green": True})
    return None


def pytest_sessionfinish(session, exitstatus):
    session.config.stash[_EXIT] = int(exitstatus)
    harness = sys.modules.get("harness")
    if harness is None:
        return
    if os.environ.get("TRACER_INTEROP_KEEP"):
        print(f"\nconftest: scratch folder kept (TRACER_INTEROP_KEEP): {harness.WORK}", flush=True)
    elif exitstatus == 0:
        shutil.rmtree(harness.WORK, ignore_errors=True)


@pytest.hookimpl(trylast=True)
def pytest_unconfigure(config):
    """Leave now, with pytest's status: rclpy's shutdown (at exit) can hang."""
    if _EXIT in config.stash:
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(config.stash[_EXIT])
