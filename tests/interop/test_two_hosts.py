#!/usr/bin/env python3
"""tracer_calib_node and a stock rclpy node (Kilted, Fast DDS) on two "hosts" without
multicast: two network namespaces joined by a veth pair with multicast off
(tests/interop/two_hosts.sh makes them; nothing routes off the machine). The node runs in
host A, the rclpy peer in host B, each with its own ROS_AUTOMATIC_DISCOVERY_RANGE and
ROS_STATIC_PEERS. Each scenario starts a node and a fresh peer process (the environment
is read when rclpy starts its participant), peers/two_hosts_peer.py MODE:

- full: plate scan, /calibrate, a lens scan corrected, its polygon, a parameter read;
- isolated: for 8 s, neither the node, its topics nor /calibrate show up.

Run by tests/interop/run.sh (`two_hosts` or a scenario's name selects it) with pytest
(conftest.py; no rclpy in this process) under `two_hosts.sh`.
"""

import os
import subprocess
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
import pytest  # noqa: E402
import processes  # noqa: E402

pytestmark = pytest.mark.fastdds

DOMAIN = "42"
PEER_TIMEOUT = 120


def peer_env(range_, peers):
    env = dict(os.environ)
    # The interop profile whitelists 127.0.0.1 only: a host on a network has none.
    env.pop("FASTDDS_DEFAULT_PROFILES_FILE", None)
    env.pop("ROS_STATIC_PEERS", None)
    env["ROS_AUTOMATIC_DISCOVERY_RANGE"] = range_
    env["ROS_DOMAIN_ID"] = DOMAIN
    if peers:
        env["ROS_STATIC_PEERS"] = peers
    return env


class Host:
    """A process in one of the two namespaces."""

    def __init__(self, ns, argv, env, log_path):
        self.log_path = log_path
        self.log = open(log_path, "w")
        self.proc = subprocess.Popen(
            ["ip", "netns", "exec", ns] + argv, env=env, stdout=self.log, stderr=subprocess.STDOUT
        )

    def output(self):
        self.log.flush()
        with open(self.log_path) as f:
            return f.read()

    def stop(self):
        processes.terminate(self.proc)


def scenario(work, name, node_range, node_peers, peer_range, peer_peers, mode, expect_warnings=()):
    a, b = os.environ["TRACER_HOST_A"], os.environ["TRACER_HOST_B"]
    node_env = peer_env(node_range, node_peers)
    node = Host(
        a,
        [os.environ["TRACER_CALIB_NODE"], "--ros-args", "--log-level", "info"],
        node_env,
        os.path.join(work, name + ".node.log"),
    )
    try:
        time.sleep(0.3)
        peer = subprocess.run(
            ["timeout", "-s", "KILL", str(PEER_TIMEOUT), "ip", "netns", "exec", b, sys.executable, processes.peer_program("two_hosts_peer"), mode],
            env=peer_env(peer_range, peer_peers),
            capture_output=True,
            text=True,
        )
        if node.proc.poll() is not None:
            raise AssertionError(f"the node exited with {node.proc.returncode}:\n{node.output()}")
        if peer.returncode != 0:
            raise AssertionError(
                f"peer ({mode}) failed with {peer.returncode}:\n{peer.stdout[-3000:]}{peer.stderr[-3000:]}\n"
                f"--- node:\n{node.output()[-3000:]}"
            )
    finally:
        node.stop()
    out = node.output()
    for w in expect_warnings:
        lines = [line for line in out.splitlines() if "WARN" in line and w in line]
        assert len(lines) == 1, f"expected one warning naming {w!r}, got {lines}:\n{out}"
    last = [line for line in peer.stdout.splitlines() if line.startswith("peer:")]
    return last[-1] if last else ""


@pytest.fixture(scope="module")
def work():
    """The scenarios' scratch folder (node logs), also the peers' TMPDIR."""
    import tempfile

    os.environ["TMPDIR"] = path = tempfile.mkdtemp(prefix="tracer_calib_two_hosts_")
    return path


# Each scenario: (name, node's range, node's static peers, peer's range, peer's static
# peers, mode, warnings the node must give once each); ADDR_A and ADDR_B stand for the
# hosts' addresses (TRACER_ADDR_A, TRACER_ADDR_B).
SCENARIOS = [
    # Static peers on the node only: the node announces itself to B by unicast. Bad
    # entries beside the good one: one warning each, the node still starts.
    pytest.param("node", "SUBNET", "no-such-host.invalid;10.0.0.300;ADDR_B", "SUBNET", None, "full",
                 ("'no-such-host.invalid'", "'10.0.0.300'"), id="peers_on_node"),
    pytest.param("peer", "SUBNET", None, "SUBNET", "ADDR_A", "full", (), id="peers_on_peer"),
    pytest.param("both", "SUBNET", "ADDR_B", "SUBNET", "ADDR_A", "full", (), id="peers_on_both"),
    # LOCALHOST with a static peer: no multicast, but the peer host is reached.
    pytest.param("localhost", "LOCALHOST", "ADDR_B", "SUBNET", None, "full", (), id="localhost_with_peer"),
    # Discovery OFF: not seen, not even by a peer that lists the node.
    pytest.param("off", "OFF", None, "SUBNET", "ADDR_A", "isolated", (), id="off"),
    # No static peers on either side and no multicast on the link: not seen.
    pytest.param("none", "SUBNET", None, "SUBNET", None, "isolated", (), id="no_peers"),
]


@pytest.mark.parametrize(("name", "node_range", "node_peers", "peer_range", "peer_peers", "mode", "warnings"),
                         SCENARIOS)
def test_two_hosts(work, name, node_range, node_peers, peer_range, peer_peers, mode, warnings):
    """two_hosts_peers_on_node, ..., two_hosts_no_peers (SCENARIOS)."""

    def addresses(peers):
        if peers is None:
            return None
        return peers.replace("ADDR_A", os.environ["TRACER_ADDR_A"]).replace("ADDR_B", os.environ["TRACER_ADDR_B"])

    return scenario(work, name, node_range, addresses(node_peers), peer_range, addresses(peer_peers), mode,
                    expect_warnings=warnings)
