"""Host B's stock rclpy peer in one scenario of test_two_hosts.py (its environment sets the
discovery range and static peers):

- full: plate scan, /calibrate, a lens scan corrected, its polygon, a parameter read;
- isolated: for 8 s, neither the node, its topics nor /calibrate show up.

Run by test_two_hosts.py as `ip netns exec HOST_B python peers/two_hosts_peer.py MODE`;
prints what it found and exits 0, or the failure's traceback and exits 1.
"""

import os
import sys
import time
import traceback

import rclpy

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
import harness as h  # noqa: E402
from geometry_msgs.msg import PolygonStamped  # noqa: E402
from tracer_calib_msgs.msg import Contour, RawScan  # noqa: E402
from tracer_calib_msgs.srv import Calibrate  # noqa: E402


def main(mode):
    rclpy.init()
    peer = h.Peer("host_b_peer")
    if mode == "isolated":
        deadline = time.monotonic() + 8
        while time.monotonic() < deadline:
            peer.executor.spin_once(timeout_sec=0.1)
            names = peer.node.get_node_names()
            services = [n for n, _ in peer.node.get_service_names_and_types()]
            assert "tracer_calibrator" not in names, f"the node is seen: {names}"
            assert "/calibrate" not in services, f"/calibrate is seen: {services}"
            assert peer.node.count_subscribers("/raw_scan") == 0, "a /raw_scan subscriber is seen"
        print("peer: isolated for 8 s", flush=True)
        os._exit(0)

    t0 = time.monotonic()
    pub = peer.publisher("/raw_scan")
    contours = peer.subscribe(Contour, "/contour")
    polygons = peer.subscribe(PolygonStamped, "/contour_polygon")
    peer.wait_matched(pub, timeout=60)
    found = time.monotonic() - t0
    plate = h.simulate("plate_b", "plate", seed=2)
    peer.send_scan(pub, h.raw_scan(10, RawScan.TARGET_CALIBRATION_PLATE, *plate), contours, timeout=40)
    r = peer.call("/calibrate", Calibrate.Request(), timeout=40)
    assert r.success, r.message
    lens = h.simulate("lens_b", "ellipse", seed=3)
    c = peer.send_scan(pub, h.raw_scan(11, RawScan.TARGET_LENS, *lens), contours, timeout=40)
    assert c.calibrated and len(c.points) == 400, c
    worst = max(h.ellipse_distance(p.x, p.y) for p in c.points)
    assert worst < 40e-6, f"corrected points up to {worst * 1e3:.4f} mm off the ellipse"
    deadline = time.monotonic() + 20
    while not any(p.header.stamp.sec == 1700000011 for p in polygons):
        assert time.monotonic() < deadline, "no PolygonStamped for the lens scan"
        pub.publish(h.raw_scan(11, RawScan.TARGET_LENS, *lens))
        try:
            peer.spin_until(lambda: any(p.header.stamp.sec == 1700000011 for p in polygons), 1.0, "a polygon")
        except AssertionError:
            pass
    client = peer.param_client("/tracer_calibrator", timeout=40)
    got = peer.param(lambda: client.get_parameters(["plate.side", "calibration.valid"]))
    assert abs(got.values[0].double_value - 0.045) < 1e-15 and got.values[1].bool_value is True, got
    # The node's name comes with its ros_discovery_info, which may come after its
    # endpoints (the exchange above can be over within a second).
    peer.spin_until(lambda: "tracer_calibrator" in peer.node.get_node_names(), 10, "the node's name")
    named = time.monotonic() - t0
    print(
        f"peer: node found in {found:.1f} s, named in {named:.1f} s; calibrate, contour, polygon, parameters ok",
        flush=True,
    )
    os._exit(0)


if __name__ == "__main__":
    try:
        main(sys.argv[1])
    except Exception:
        traceback.print_exc()
        sys.stdout.flush()
        os._exit(1)
