"""A stock rclpy node on rmw_zenoh_cpp: each RawScan on /relay_in out again on /relay_out
as a Contour of the size the node sends (its scan id, as many points as samples, no
correction computed), until stdin closes.

Run by test_zenoh.py as `python peers/zenoh_relay.py ARGS`.
"""
import sys, threading
import rclpy
from rclpy.node import Node
from rclpy.qos import QoSProfile
from geometry_msgs.msg import Point
from tracer_calib_msgs.msg import Contour, RawScan
rclpy.init()
n = Node("stock_relay")
pub = n.create_publisher(Contour, "/relay_out", QoSProfile(depth=10))
c = Contour()
c.points = [Point(x=0.001 * i, y=0.0, z=0.0) for i in range(400)]
c.radii = [0.02] * 400
def on_scan(m):
    c.header = m.header
    c.scan_id = m.scan_id
    c.target = m.target
    pub.publish(c)
n.create_subscription(RawScan, "/relay_in", on_scan, QoSProfile(depth=100))
stop = threading.Event()
threading.Thread(target=lambda: (sys.stdin.readline(), stop.set()), daemon=True).start()
print("ready", flush=True)
while not stop.is_set():
    rclpy.spin_once(n, timeout_sec=0.05)
