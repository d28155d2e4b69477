"""A peer that watches for SECONDS (argv[1]) as node NAME (argv[2]), in ENCLAVE (argv[3], if
given): the contours it got and the nodes it saw, as one JSON line. The insecure peer and
the peer of a foreign keystore.

Run by test_security.py as `python peers/security_watcher.py ARGS`.
"""
import json, sys, time, rclpy
from tracer_calib_msgs.msg import Contour
seconds, name, enclave = float(sys.argv[1]), sys.argv[2], sys.argv[3:]
rclpy.init(args=['--ros-args', '--enclave', enclave[0]] if enclave else None)
n = rclpy.create_node(name)
got = []
n.create_subscription(Contour, '/contour', got.append, 10)
seen = set()
t0 = time.time()
while time.time() - t0 < seconds:
    rclpy.spin_once(n, timeout_sec=0.1)
    seen.update(name for name, _ in n.get_node_names_and_namespaces())
print(json.dumps(dict(contours=len(got), nodes=sorted(seen))), flush=True)
import os; os._exit(0)
