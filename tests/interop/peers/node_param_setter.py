"""Sets output_frame_id and resample_points of /tracer_calibrator over and over, as fast as
the node answers, until it is killed.

Run by test_node.py as `python peers/node_param_setter.py`.
"""
import time, rclpy
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.parameter_client import AsyncParameterClient
rclpy.init()
n = Node('setter')
pc = AsyncParameterClient(n, '/tracer_calibrator')
deadline = time.monotonic() + 20
while not pc.services_are_ready() and time.monotonic() < deadline:
    rclpy.spin_once(n, timeout_sec=0.05)
i = 1
while True:
    fut = pc.set_parameters([Parameter('output_frame_id', value=f'frame_{i}'), Parameter('resample_points', value=i % 1000)])
    t = time.monotonic()
    while not fut.done() and time.monotonic() - t < 2:
        rclpy.spin_once(n, timeout_sec=0.01)
    i += 1
