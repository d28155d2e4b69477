"""What every interop script shares and that needs no ROS: running a list of tests as
cargo test prints them, and stopping a process. (test_two_hosts.py's controller runs
outside the namespaces' ROS set-up and imports only this; harness.py, the helpers with
ROS, builds on it.)"""

import os
import signal
import subprocess
import time
import traceback


def run_tests(tests, only, label, summary, after_each=None, log_dir=None):
    """Run the `(name, fn)` pairs (all, or those named in `only`), one line each as cargo
    test prints them (`test LABELname ... ok (1.2 s)`, with what `fn` returns if it is a
    string), a failure's traceback and, if `log_dir` is given, the tail of every `.log`
    file in it, and a closing `SUMMARY: N passed, M failed`. `after_each()` runs after
    every test. Returns M."""
    passed = failed = 0
    for name, fn in tests:
        if only and name not in only:
            continue
        t0 = time.monotonic()
        try:
            detail = fn()
            passed += 1
            extra = f" {detail}" if isinstance(detail, str) and detail else ""
            print(f"test {label}{name} ... ok ({time.monotonic() - t0:.1f} s){extra}", flush=True)
        except Exception:
            failed += 1
            print(f"test {label}{name} ... FAILED ({time.monotonic() - t0:.1f} s)", flush=True)
            traceback.print_exc()
            for log in sorted(os.listdir(log_dir)) if log_dir else []:
                if log.endswith(".log"):
                    print(f"--- {log}:\n" + open(os.path.join(log_dir, log)).read()[-3000:], flush=True)
        if after_each:
            after_each()
    print(f"{summary}: {passed} passed, {failed} failed", flush=True)
    return failed


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
        proc.kill()
        proc.wait()
        return None
    return time.monotonic() - t0
