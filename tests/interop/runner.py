"""What every interop script shares and that needs no ROS: running a list of tests as
cargo test prints them, and stopping a process. (test_two_hosts.py's controller runs
outside the namespaces' ROS set-up and imports only this; harness.py, the helpers with
ROS, builds on it.)"""

import os
import shutil
import signal
import subprocess
import sys
import time
import traceback


def run_tests(tests, only, label, summary, after_each=None, log_dir=None):
    """Run the `(name, fn)` pairs (all, or those named in `only`), one line each as cargo
    test prints them (`test LABELname ... ok (1.2 s)`, with what `fn` returns if it is a
    string), a failure's traceback and, if `log_dir` is given, the tail of every `.log`
    file in it written while the test ran, and a closing `SUMMARY: N passed, K skipped, M
    failed`. A test that returns "skipped: WHY" (what it needs is not on this machine) is
    counted skipped, not passed, and printed `test LABELname ... skipped: WHY`.
    `after_each()` runs after every test. Returns M."""
    passed = skipped = failed = 0
    for name, fn in tests:
        if only and name not in only:
            continue
        t0 = time.monotonic()
        started = time.time()
        try:
            detail = fn()
            if isinstance(detail, str) and detail.startswith("skipped:"):
                skipped += 1
                print(f"test {label}{name} ... {detail}", flush=True)
            else:
                passed += 1
                extra = f" {detail}" if isinstance(detail, str) and detail else ""
                print(f"test {label}{name} ... ok ({time.monotonic() - t0:.1f} s){extra}", flush=True)
        except Exception:
            failed += 1
            print(f"test {label}{name} ... FAILED ({time.monotonic() - t0:.1f} s)", flush=True)
            traceback.print_exc()
            for log in sorted(os.listdir(log_dir)) if log_dir else []:
                path = os.path.join(log_dir, log)
                try:
                    if log.endswith(".log") and os.path.getmtime(path) >= started - 1.0:
                        print(f"--- {log}:\n" + open(path, errors="replace").read()[-3000:], flush=True)
                except OSError:
                    pass  # gone meanwhile
        if after_each:
            after_each()
    print(f"{summary}: {passed} passed, {skipped} skipped, {failed} failed", flush=True)
    return failed


def run_tests_and_exit(script, tests, argv, label, summary, work, log_dir=None, at_end=None):
    """A test script's end: the tests `argv` names (all if none; `summary` itself names all
    of them, a `test_` prefix is dropped), run as `run_tests` does; an unknown name exits 2
    listing the tests there are. `at_end()`, if given, runs after them (what the tests
    shared, stopped). `work` (the script's scratch folder) is removed when all passed, unless
    TRACER_INTEROP_KEEP is set (to read the node logs of a passing run).
    Exits 0 or 1 without rclpy's shutdown, which can hang (docs/ros2-peer.md)."""
    only = [a.removeprefix("test_") for a in argv if a != summary]
    unknown = sorted(set(only) - {name for name, _ in tests})
    if unknown:
        print(f"{script}: no such test: {', '.join(unknown)} (have: {', '.join(n for n, _ in tests)})", flush=True)
        os._exit(2)
    failed = run_tests(tests, only, label, summary, log_dir=log_dir)
    if at_end:
        at_end()
    if failed == 0 and not os.environ.get("TRACER_INTEROP_KEEP"):
        shutil.rmtree(work, ignore_errors=True)
    elif os.environ.get("TRACER_INTEROP_KEEP"):
        print(f"{script}: scratch folder kept (TRACER_INTEROP_KEEP): {work}", flush=True)
    sys.stdout.flush()
    os._exit(0 if failed == 0 else 1)


def terminate(proc, timeout=5):
    """SIGTERM to a running `proc`; if it has not exited within `timeout` seconds, SIGKILL.
    Returns the seconds it took to exit on SIGTERM (0.0 if it had exited already), or None
    if it had to be killed."""
    if proc.poll() is not None:
        return 0.0
    t0 = time.monotonic()
    proc.send_signal(signal.SIGTERM)
    try:
        proc.wait(timeout=timeout)
    except subprocess.TimeoutExpired:
        kill(proc)
        return None
    return time.monotonic() - t0


def kill(proc):
    """SIGKILL to a running `proc`, and to what it runs when it is a `timeout` wrapper:
    `timeout` puts itself and its command in a process group of their own and passes no
    SIGKILL on, so the command would live on (a stray peer, a run). Waits for it."""
    if proc.poll() is None:
        try:
            os.killpg(proc.pid, signal.SIGKILL)  # its group, if it leads one
        except (ProcessLookupError, PermissionError):
            proc.kill()
    proc.wait()
