"""A peer program of test_security.py.

Run by test_security.py as `python peers/security_hmi.py ARGS`.
"""
import json, sys, time, rclpy
from rclpy.parameter import Parameter
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from diagnostic_msgs.msg import DiagnosticArray
from tracer_calib_msgs.msg import Calibration, Contour
from tracer_calib_msgs.srv import Calibrate
rclpy.init(args=['--ros-args', '--enclave', '/hmi'])
n = rclpy.create_node('hmi')
got = dict(contours=0, calibration=[], diagnostics=0)
n.create_subscription(Contour, '/contour', lambda m: got.update(contours=got['contours'] + 1), 10)
latched = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL)
n.create_subscription(Calibration, '/calibration', lambda m: got['calibration'].append(m.scan_id), latched)
n.create_subscription(DiagnosticArray, '/diagnostics', lambda m: got.update(diagnostics=got['diagnostics'] + 1), 10)

def spin(seconds, until=lambda: False):
    t0 = time.time()
    while time.time() - t0 < seconds and not until():
        rclpy.spin_once(n, timeout_sec=0.1)

def attempt(make, call, wait):
    # What became of a call: 'refused: ...' (the HMI's own middleware would not make the
    # endpoint), 'not available', 'no answer', or 'ANSWERED ...'.
    try:
        client = make()
    except Exception as e:
        return 'refused: ' + str(e).splitlines()[0][:160]
    if not client.wait_for_service(timeout_sec=wait):
        fut = call(client)
        spin(2.0, fut.done)
        return 'ANSWERED ' + str(fut.result()) if fut.done() else 'not available'
    fut = call(client)
    spin(wait, fut.done)
    return 'ANSWERED ' + str(fut.result()) if fut.done() else 'no answer'

spin(float(sys.argv[1]), lambda: got['contours'] > 0 and got['calibration'] and got['diagnostics'] > 0)
calibrate = attempt(lambda: n.create_client(Calibrate, '/calibrate'),
                    lambda c: c.call_async(Calibrate.Request()), float(sys.argv[2]))
from rcl_interfaces.srv import SetParameters
def set_req():
    r = SetParameters.Request()
    r.parameters = [Parameter('resample_points', value=123).to_parameter_msg()]
    return r
set_param = attempt(lambda: n.create_client(SetParameters, '/tracer_calibrator/set_parameters'),
                    lambda c: c.call_async(set_req()), float(sys.argv[2]))
print(json.dumps(dict(got, calibrate=calibrate, set_param=set_param)), flush=True)
import os; os._exit(0)
