"""nav2's lifecycle manager's end of the bond (stock bondpy), in a process of its own as
nav2's is: prints "started INSTANCE_ID", then "formed" when the bond forms, and any error
its executor raises ("error: ..."), until killed.

Run by test_zenoh.py as `python peers/zenoh_bond_manager.py ARGS`.
"""
import time
import rclpy
from bondpy.bondpy import Bond
rclpy.init()
n = rclpy.create_node("zenoh_lifecycle_manager")
bond = Bond(n, "/bond", "tracer_calibrator", on_formed=lambda: print("formed", flush=True))
bond.heartbeat_period = 0.1
bond.heartbeat_timeout = 4.0
bond.connect_timeout = 60.0
bond.start()
print("started", bond.instance_id, flush=True)
said = set()
while True:
    try:
        rclpy.spin_once(n, timeout_sec=0.1)
    except Exception as e:
        if str(e) not in said:
            said.add(str(e))
            print(f"error: {e}", flush=True)
        time.sleep(0.1)
