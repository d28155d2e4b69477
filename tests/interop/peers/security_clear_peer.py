"""A peer program of test_security.py.

Run by test_security.py as `python peers/security_clear_peer.py ARGS`.
"""
import json, sys, time, rclpy
from rclpy.qos import QoSProfile
from tracer_calib_msgs.msg import Contour, RawScan
rclpy.init()
n = rclpy.create_node('clear_peer')
got = []
n.create_subscription(Contour, '/contour', got.append, QoSProfile(depth=50))
pub = n.create_publisher(RawScan, '/raw_scan', QoSProfile(depth=50))
scan = json.loads(sys.stdin.read())
m = RawScan()
m.header.frame_id = scan['frame_id']
m.scan_id = scan['scan_id']
m.target = RawScan.TARGET_LENS
m.steps_per_revolution = 400
m.step = scan['step']
m.counts = scan['counts']
t0 = time.time()
while time.time() - t0 < 30 and not got:
    if pub.get_subscription_count() > 0:
        pub.publish(m)
    t1 = time.time()
    while time.time() - t1 < 0.5 and not got:
        rclpy.spin_once(n, timeout_sec=0.05)
print(json.dumps(dict(contours=len(got))), flush=True)
import os; os._exit(0)
