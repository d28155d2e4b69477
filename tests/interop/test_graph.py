"""tracer_calib_node in the ROS graph, seen by a stock rclpy node (Kilted, Fast DDS):

- clean_leave: stopped with SIGINT or SIGTERM, the node leaves the peer's node and
  service lists within 1 s; restarted, it is listed once;
- polygon_at_once: a new contour_polygon subscriber gets the polygon of the first scan
  sent after it matched;
- qos_best_effort_driver: a best-effort RawScan publisher (the sensor-data QoS) is
  reported once (WARN naming topic, node and policy; /diagnostics), and its scans are
  corrected once `qos_overrides./raw_scan.subscription.reliability: best_effort` is set
  in the params file;
- cells_started_at_once: ten nodes and a new planner started together; the planner sees
  every cell, every call and scan is answered (tests/interop/cell_graph.py).

Run by tests/interop/run.sh inside a private network namespace, with the helpers of
harness.py, with pytest (conftest.py).
"""

import os
import signal
import sys
import time

import rclpy
from rclpy.qos import QoSProfile

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import harness as h  # noqa: E402
from geometry_msgs.msg import PolygonStamped  # noqa: E402
from tracer_calib_msgs.msg import Contour, RawScan  # noqa: E402


def graph_has_node(peer, name="tracer_calibrator", ns="/"):
    return sum(1 for n, s in peer.node.get_node_names_and_namespaces() if n == name and s == ns)


def graph_has_service(peer, service="/calibrate"):
    return any(n == service for n, _ in peer.node.get_service_names_and_types())


def test_clean_leave(peer):
    """SIGINT and SIGTERM: gone from the peer's node and service lists within 1 s;
    SIGKILL: gone when its lease runs out (10 s); a restarted node is listed once."""
    for sig in (signal.SIGINT, signal.SIGTERM):
        node = h.NodeProcess(f"leave_{sig.name}", [])
        try:
            peer.spin_until(lambda: graph_has_node(peer) == 1 and graph_has_service(peer), 20, "the node in the graph")
        except Exception:
            node.stop()
            raise
        h.RUNNING.remove(node)
        t0 = time.monotonic()
        node.proc.send_signal(sig)
        deadline = t0 + 5
        while (graph_has_node(peer) or graph_has_service(peer)) and time.monotonic() < deadline:
            peer.executor.spin_once(timeout_sec=0.01)
        gone = time.monotonic() - t0
        node.proc.wait(timeout=5)
        assert gone < 1.0, f"{sig.name}: still in the graph {gone:.2f} s after the signal"
        print(f"  {sig.name}: gone from the node and service lists in {gone:.3f} s", flush=True)
    # Killed (SIGKILL): nothing is said; peers drop the node when its lease (10 s)
    # runs out without an announcement.
    node = h.NodeProcess("leave_SIGKILL", [])
    peer.spin_until(lambda: graph_has_node(peer) == 1 and graph_has_service(peer), 20, "the node in the graph")
    h.RUNNING.remove(node)
    t0 = time.monotonic()
    node.proc.kill()
    node.proc.wait(timeout=5)
    while (graph_has_node(peer) or graph_has_service(peer)) and time.monotonic() < t0 + 30:
        peer.executor.spin_once(timeout_sec=0.05)
    gone = time.monotonic() - t0
    assert gone < 15, f"SIGKILL: still in the graph {gone:.1f} s after"
    print(f"  SIGKILL: gone from the node and service lists in {gone:.1f} s (the lease)", flush=True)
    # Restarted: listed once, and stays so.
    node = h.NodeProcess("leave_restart", [])
    try:
        peer.spin_until(lambda: graph_has_node(peer) >= 1, 20, "the restarted node")
        end = time.monotonic() + 2
        while time.monotonic() < end:
            peer.executor.spin_once(timeout_sec=0.05)
            assert graph_has_node(peer) == 1, f"listed {graph_has_node(peer)} times"
    finally:
        node.stop()


def test_polygon_at_once(peer):
    """Five times: a new contour_polygon subscriber, then one scan (no resend) once it
    has matched: its polygon arrives."""
    node = h.NodeProcess("polygon", [])
    try:
        pub = peer.publisher("/raw_scan")
        contours = peer.subscribe(Contour, "/contour")
        lens = h.simulate("lens_poly", "ellipse", seed=3)
        peer.send_scan(pub, h.raw_scan(1, RawScan.TARGET_LENS, *lens), contours)
        for k in range(5):
            box = []
            matched = []
            from rclpy.event_handler import SubscriptionEventCallbacks

            cb = SubscriptionEventCallbacks(matched=lambda e: matched.append(e.current_count))
            sub = peer.node.create_subscription(
                PolygonStamped, "/contour_polygon", box.append, QoSProfile(depth=10), event_callbacks=cb
            )
            peer.spin_until(lambda: matched and matched[-1] > 0, 10, "the polygon subscription matched")
            # The node hears of the subscriber at about the time the subscriber hears of
            # the node's publisher; give its discovery the moment it takes.
            end = time.monotonic() + 0.2
            while time.monotonic() < end:
                peer.executor.spin_once(timeout_sec=0.02)
            scan_id = 100 + k
            pub.publish(h.raw_scan(scan_id, RawScan.TARGET_LENS, *lens))
            peer.spin_until(
                lambda: any(p.header.stamp.sec == 1700000000 + scan_id for p in box), 5, f"the polygon of scan {scan_id}"
            )
            peer.node.destroy_subscription(sub)
            end = time.monotonic() + 0.3
            while time.monotonic() < end:
                peer.executor.spin_once(timeout_sec=0.02)
    finally:
        node.stop()


def test_qos_best_effort_driver(peer):
    """A driver publishing RawScan with the sensor-data QoS (best effort): the node warns
    once, naming topic, node and policy, and counts it on /diagnostics; its scans are not
    corrected. With `qos_overrides./raw_scan.subscription.reliability: best_effort` in the
    params file they are, and the override is read-only."""
    from diagnostic_msgs.msg import DiagnosticArray
    from rclpy.parameter import Parameter
    from rclpy.qos import qos_profile_sensor_data

    lens = h.simulate("lens_qos", "ellipse", seed=3)
    contours = peer.subscribe(Contour, "/contour")
    diags = peer.subscribe(DiagnosticArray, "/diagnostics")
    node = h.NodeProcess("qos_default", [])
    driver = peer.node.create_publisher(RawScan, "/raw_scan", qos_profile_sensor_data)
    try:
        peer.spin_until(lambda: peer.node.count_subscribers("/raw_scan") > 0, 20, "the node's raw_scan subscription")

        def diag_count():
            for d in reversed(diags):
                for s in d.status:
                    values = {kv.key: kv.value for kv in s.values}
                    if "qos_incompatible" in values:
                        return int(values["qos_incompatible"]), s.message
            return 0, ""

        peer.spin_until(lambda: diag_count()[0] >= 1, 10, lambda: f"qos_incompatible on /diagnostics ({diag_count()})")
        for k in range(3):
            driver.publish(h.raw_scan(200 + k, RawScan.TARGET_LENS, *lens))
            end = time.monotonic() + 0.5
            while time.monotonic() < end:
                peer.executor.spin_once(timeout_sec=0.05)
        assert not any(c.scan_id >= 200 for c in contours), "a best-effort scan was corrected without the override"
        count, message = diag_count()
        assert count == 1 and "incompatible QoS" in message, (count, message)

        def warns():
            return [line for line in node.output().splitlines() if "WARN" in line and "incompatible QoS" in line]

        peer.spin_until(lambda: warns(), 10, "the node's warning")
    finally:
        node.stop()
    warns = warns()
    assert len(warns) == 1, "expected one warning:\n" + node.output()
    w = warns[0]
    for part in ("'/raw_scan'", "/graph_peer", "publisher", "RELIABILITY"):
        assert part in w, f"{part!r} not in {w!r}"
    print(f"  {w.split('] ', 1)[-1]}", flush=True)

    pf = h.params_file(
        "qos_override.yaml",
        "tracer_calibrator:\n  ros__parameters:\n    qos_overrides./raw_scan.subscription.reliability: best_effort\n",
    )
    node = h.NodeProcess("qos_override", ["--params-file", pf])
    try:
        c = peer.send_scan(driver, h.raw_scan(300, RawScan.TARGET_LENS, *lens), contours)
        assert c.scan_id == 300 and len(c.points) == 400
        client = peer.param_client("/tracer_calibrator")
        name = "qos_overrides./raw_scan.subscription.reliability"
        got = peer.param(lambda: client.get_parameters([name]))
        assert got.values[0].string_value == "best_effort", got
        r = peer.param(lambda: client.set_parameters([Parameter(name, value="reliable")]))
        assert not r.results[0].successful and "read-only" in r.results[0].reason, r
    finally:
        node.stop()
    assert not [line for line in node.output().splitlines() if "incompatible QoS" in line], node.output()
    peer.node.destroy_publisher(driver)


def test_cells_started_at_once():
    """Ten nodes (/cell1 ... /cell10) started at once, with a planner whose participant
    is as new as they are: it sees every cell within 30 s, every calibrate is answered and
    every scan comes back corrected. (Before the in-order discovery patch of the vendored
    rustdds, Fast DDS missed some cells' endpoints for good in most such runs.)"""
    import cell_graph

    ctx = rclpy.Context()
    rclpy.init(context=ctx)
    planner = h.Peer("planner", context=ctx)
    try:
        out = cell_graph.cell_graph(planner, 10, scans=3, head_start=0.0, discovery_timeout=30.0)
    finally:
        planner.node.destroy_node()
        ctx.try_shutdown()
    assert out["calls_answered_ok"] == 10, out
    assert out["scans_answered"] == out["scans_sent"] == 30 and out["all_corrected"], out
    return f"discovery {out['discovery_s']} s"
