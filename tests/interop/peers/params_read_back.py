"""Loads a params file into a stock rclpy node with --params-file (as `ros2 run ...
--ros-args --params-file PATH` would) and prints its parameters as one JSON line.

Run by harness.read_back_with_rclpy as `python peers/params_read_back.py PATH NODE NAMESPACE`.
"""
import json
import sys

import rclpy
from rclpy.node import Node

path, node_name, namespace = sys.argv[1:4]
rclpy.init(args=["--ros-args", "--params-file", path])
n = Node(node_name, namespace=namespace, automatically_declare_parameters_from_overrides=True)
print(json.dumps({p.name: p.value for p in n._parameters.values()}, default=list))
n.destroy_node()
rclpy.shutdown()
