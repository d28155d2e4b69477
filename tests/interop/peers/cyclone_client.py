"""One client process of the mixed cell: a warm-up call (discovery both ways), "ready",
then on "go" CALLS calls at once, alternating between two plate scans; prints what each
call named and got, as JSON. Its reply queue holds CALLS replies (see below).

Run by test_cyclone.py as `python peers/cyclone_client.py ARGS`.
"""
import json, sys, time
import rclpy
from rclpy.qos import QoSProfile
from rclpy.node import Node
from rclpy.utilities import get_rmw_implementation_identifier
from tracer_calib_msgs.srv import Calibrate
calls, ids = int(sys.argv[1]), [int(a) for a in sys.argv[2:]]
rclpy.init()
n = Node("mixed_client")
# A reply queue as deep as the calls it has outstanding: with ROS's default (KEEP_LAST 10),
# 30 replies arriving within ms push some out before rclpy takes them on Cyclone DDS (a
# stock rclpy server on Cyclone DDS got 10 of 30 answers through, this node 20).
c = n.create_client(Calibrate, "/calibrate", qos_profile=QoSProfile(depth=calls))
def wait(cond, timeout):
    deadline = time.monotonic() + timeout
    while not cond() and time.monotonic() < deadline:
        rclpy.spin_once(n, timeout_sec=0.05)
    return cond()
assert wait(c.service_is_ready, 20), "service not ready"
for attempt in range(10):
    f = c.call_async(Calibrate.Request(scan_id=ids[0], dry_run=True))
    if wait(f.done, 3):
        break
else:
    raise SystemExit("no warm-up answer")
print("ready", flush=True)
sys.stdin.readline()
reqs = [ids[i % len(ids)] for i in range(calls)]
t0 = time.monotonic()
futures = [c.call_async(Calibrate.Request(scan_id=s, dry_run=True)) for s in reqs]
wait(lambda: all(f.done() for f in futures), 60)
took = time.monotonic() - t0
out = [[s, f.result().success, f.result().message, f.result().alpha0] if f.done() else [s, None, None, None]
       for s, f in zip(reqs, futures)]
print(json.dumps({"rmw": get_rmw_implementation_identifier(), "took": took, "calls": out}), flush=True)
import os; os._exit(0)
