"""A new tracer driver: a fresh participant, one RawScan publisher (reliable, volatile: the
node's subscription's QoS), one plate scan as soon as its subscription count is 1.

Run by test_first_scan.py as `python peers/first_scan_driver.py PLATE_CSV SCAN_ID`. Prints
{"published": monotonic seconds, "matched_after": seconds} and stays up (its writer must be
there to repair) until stdin closes.
"""

import json
import os
import sys
import time

import rclpy
from rclpy.node import Node
from rclpy.qos import QoSProfile

from tracer_calib_msgs.msg import RawScan


def main(plate_csv, scan_id):
    steps, counts = [], []
    with open(plate_csv) as f:
        next(f)
        for line in f:
            s, c = line.strip().split(",")
            steps.append(int(s))
            counts.append(int(c))
    msg = RawScan()
    msg.header.frame_id = "tracer"
    msg.header.stamp.sec = 1700000000 + scan_id
    msg.scan_id = scan_id
    msg.target = RawScan.TARGET_CALIBRATION_PLATE
    msg.steps_per_revolution = 400
    msg.step = steps
    msg.counts = counts

    rclpy.init()
    node = Node(f"first_scan_driver_{scan_id}")
    pub = node.create_publisher(RawScan, "/raw_scan", QoSProfile(depth=10))
    t0 = time.monotonic()
    while pub.get_subscription_count() < 1:
        if time.monotonic() - t0 > 20:
            print(json.dumps({"error": "no subscription within 20 s"}), flush=True)
            return
        time.sleep(0.0005)
    published = time.monotonic()
    pub.publish(msg)
    print(json.dumps({"published": published, "matched_after": published - t0}), flush=True)
    sys.stdin.read()
    node.destroy_node()
    rclpy.shutdown()


if __name__ == "__main__":
    main(sys.argv[1], int(sys.argv[2]))
    os._exit(0)
