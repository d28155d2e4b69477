"""A stock talker: publishes "hello N" every 50 ms and serves /zenoh_trigger, until stdin
closes or says anything.

Run by test_zenoh.py as `python peers/zenoh_talker.py ARGS`.
"""
import sys, threading
import rclpy
from rclpy.node import Node
from std_msgs.msg import String
from std_srvs.srv import Trigger
rclpy.init()
n = Node("zenoh_talker")
pub = n.create_publisher(String, "/zenoh_chatter", 10)
count = [0]
def tick():
    count[0] += 1
    pub.publish(String(data=f"hello {count[0]}"))
n.create_timer(0.05, tick)
def trigger(req, resp):
    resp.success, resp.message = True, f"talker at {count[0]}"
    return resp
n.create_service(Trigger, "/zenoh_trigger", trigger)
stop = threading.Event()
threading.Thread(target=lambda: (sys.stdin.readline(), stop.set()), daemon=True).start()
print("ready", flush=True)
while not stop.is_set():
    rclpy.spin_once(n, timeout_sec=0.05)
# rclpy's shutdown on rmw_zenoh sometimes fails after 10 s ("Failed to close the session",
# docs/ros2-peer.md): said, not fatal.
try:
    n.destroy_node()
    rclpy.shutdown()
except Exception as e:
    print(f"shutdown: {e}", flush=True)
print("bye", flush=True)
