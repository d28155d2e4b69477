"""Lists the services of the nodes named `tracer` in /cell1 and /cell2 (waiting up to 10 s
for both calibrate services) and prints them as one JSON line.

Run by test_node.py as `python peers/node_graph_probe.py`.
"""
import json, time, rclpy
from rclpy.node import Node
rclpy.init()
n = Node('graph_probe')
deadline = time.monotonic() + 10
got = {}
while time.monotonic() < deadline:
    rclpy.spin_once(n, timeout_sec=0.1)
    try:
        got = {ns: sorted(s for s, _ in n.get_service_names_and_types_by_node('tracer', ns)) for ns in ('/cell1', '/cell2')}
    except Exception:
        continue
    if all(f'{ns}/calibrate' in v for ns, v in got.items()):
        break
print(json.dumps(got))
import os; os._exit(0)
