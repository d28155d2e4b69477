"""nav2's lifecycle manager's end of a secure cell, as a process of its own (enclave
/lifecycle_manager, node lifecycle_manager): configure and activate /tracer_calibrator
through change_state with a stock bondpy Bond started (heartbeat 0.1 s, timeout 4 s),
wait up to argv[1] s for it to form, hold 5 s, deactivate; one JSON line of what it saw.

Run by test_security.py as `python peers/security_bond_manager.py ARGS`.
"""
import json, os, sys, time, rclpy
from bondpy.bondpy import Bond
from lifecycle_msgs.msg import Transition
from lifecycle_msgs.srv import ChangeState
rclpy.init(args=['--ros-args', '--enclave', '/lifecycle_manager'])
n = rclpy.create_node('lifecycle_manager')
out, times = {}, {}

def spin(seconds, until=lambda: False):
    t0 = time.time()
    while time.time() - t0 < seconds and not until():
        rclpy.spin_once(n, timeout_sec=0.05)

change = n.create_client(ChangeState, '/tracer_calibrator/change_state')
spin(30, change.service_is_ready)

def transition(tid):
    fut = change.call_async(ChangeState.Request(transition=Transition(id=tid)))
    spin(15, fut.done)
    return fut.done() and fut.result().success

out['configured'] = transition(Transition.TRANSITION_CONFIGURE)
bond = Bond(n, '/bond', 'tracer_calibrator',
            on_formed=lambda: times.setdefault('formed', time.time()),
            on_broken=lambda: times.setdefault('broken', time.time()))
bond.heartbeat_period = 0.1
bond.heartbeat_timeout = 4.0
bond.start()
t_active = time.time()
out['activated'] = transition(Transition.TRANSITION_ACTIVATE)
spin(float(sys.argv[1]), lambda: 'formed' in times)
if 'formed' in times:
    out['formed_after'] = times['formed'] - t_active
    spin(5.0, lambda: 'broken' in times)
    out['broken_while_active'] = 'broken' in times
    t_off = time.time()
    out['deactivated'] = transition(Transition.TRANSITION_DEACTIVATE)
    spin(3.0, lambda: 'broken' in times)
    if 'broken' in times:
        out['broken_after_deactivation'] = times['broken'] - t_off
print(json.dumps(out), flush=True)
os._exit(0)
