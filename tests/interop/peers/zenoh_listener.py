"""A stock listener: takes MESSAGES messages, calls /zenoh_trigger once, prints one JSON
line, then waits for a line on stdin before leaving (so the CLI can see it).

Run by test_zenoh.py as `python peers/zenoh_listener.py ARGS`.
"""
import json, sys, time
import rclpy
from rclpy.node import Node
from std_msgs.msg import String
from std_srvs.srv import Trigger
from rclpy.utilities import get_rmw_implementation_identifier
want = int(sys.argv[1])
rclpy.init()
n = Node("zenoh_listener")
got = []
t0 = time.monotonic()
first = [None]
def on_msg(m):
    if first[0] is None:
        first[0] = time.monotonic() - t0
    got.append(m.data)
n.create_subscription(String, "/zenoh_chatter", on_msg, 10)
client = n.create_client(Trigger, "/zenoh_trigger")
def wait(cond, timeout):
    deadline = time.monotonic() + timeout
    while not cond() and time.monotonic() < deadline:
        rclpy.spin_once(n, timeout_sec=0.05)
    return cond()
wait(lambda: len(got) >= want, 30)
answer = None
if wait(client.service_is_ready, 10):
    f = client.call_async(Trigger.Request())
    if wait(f.done, 10):
        answer = [f.result().success, f.result().message]
print(json.dumps({"rmw": get_rmw_implementation_identifier(), "got": got[:want], "first": first[0],
                  "answer": answer}), flush=True)
sys.stdin.readline()
# rclpy's shutdown on rmw_zenoh sometimes fails after 10 s ("Failed to close the session",
# docs/ros2-peer.md): said, not fatal.
try:
    n.destroy_node()
    rclpy.shutdown()
except Exception as e:
    print(f"shutdown: {e}", flush=True)
print("bye", flush=True)
