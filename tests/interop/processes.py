"""Stopping a process, what every interop script shares and that needs no ROS
(test_two_hosts.py's controller runs outside the namespaces' ROS set-up and imports only
this; harness.py, the helpers with ROS, builds on it). pytest runs the tests
(conftest.py)."""

import os
import signal
import subprocess
import time


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


PEERS = os.path.join(os.path.dirname(os.path.abspath(__file__)), "peers")


def peer_program(name):
    """The path of a peer program, peers/NAME.py (run as `python PATH ARGS`)."""
    path = os.path.join(PEERS, name + ".py")
    if not os.path.isfile(path):
        raise FileNotFoundError(f"no peer program {path}")
    return path
