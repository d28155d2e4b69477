"""A client that finds /calibrate, sends three requests and exits at once, without waiting
for an answer (a vanishing peer).

Run by test_node.py as `python peers/node_doomed_client.py`.
"""
import os, rclpy, time
from rclpy.node import Node
from tracer_calib_msgs.srv import Calibrate
rclpy.init()
n = Node('doomed_client')
c = n.create_client(Calibrate, '/calibrate')
deadline = time.monotonic() + 15
while not c.service_is_ready() and time.monotonic() < deadline:
    rclpy.spin_once(n, timeout_sec=0.05)
for _ in range(3):
    c.call_async(Calibrate.Request())
    rclpy.spin_once(n, timeout_sec=0.001)
os._exit(0)
