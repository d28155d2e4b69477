"""FIRST_SCAN_NODE=rclpy: a stock rclpy node in tracer_calib_node's place, for reference.
It subscribes to /raw_scan with the node's QoS (reliable, keep last 100) and answers each
scan with a Contour carrying its scan_id (no correction).

Run by test_first_scan.py as `python peers/first_scan_stock_node.py`, until stopped.
"""

import rclpy
from rclpy.node import Node
from rclpy.qos import QoSProfile

from tracer_calib_msgs.msg import Contour, RawScan


def main():
    rclpy.init()
    node = Node("tracer_calibrator")
    pub = node.create_publisher(Contour, "/contour", QoSProfile(depth=10))

    def on_scan(scan):
        c = Contour()
        c.header = scan.header
        c.scan_id = scan.scan_id
        pub.publish(c)

    node.create_subscription(RawScan, "/raw_scan", on_scan, QoSProfile(depth=100))
    rclpy.spin(node)


if __name__ == "__main__":
    main()
