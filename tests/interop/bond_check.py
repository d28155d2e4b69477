#!/usr/bin/env python3
"""Sanity check of the stock bond built by tests/interop/bond.sh (not part of the suite).

    . target/ros/DISTRO/env.sh && . target/ros/DISTRO/bond_env.sh
    tests/interop/netns.sh python3 tests/interop/bond_check.py [--timeout-case]

Two rclpy nodes in one process (one MultiThreadedExecutor in a thread), each with a stock
bondpy.bondpy.Bond(node, "bond", "tracer"), heartbeat period 0.1 s, heartbeat timeout 4 s:
both start, both must be formed within 5 s; then side A shuts down (shutdown(): a DEAD
status, the way a node leaving cleanly breaks it) and side B's on_broken must be called
within 2 s. With --timeout-case, a second pair where A goes silent 1 s after forming (its
status publishing replaced by nothing, as if the process had frozen): B must break by
heartbeat timeout, after about 4 s; and a third where A goes silent at once (reported only:
stock bondpy never times that out, see case 2 in main()).

Also prints what the Rust side needs to match: bond/msg/Status's type hash from the type
description file rosidl installed (share/bond/msg/Status.json), the one rmw reports for
bondpy's publisher and the one the Fast DDS type support library returns; the ROS type
name and the DDS type name (from the rosidl_typesupport_fastrtps_c callbacks rclpy's
rmw_fastrtps_cpp uses); and the QoS of bondpy's publisher and subscription as rmw reports
them. Exit status 0 when every check holds.
"""

import ctypes
import json
import os
import sys
import threading
import time

import rclpy
from rclpy.duration import Duration
import rclpy.executors

from ament_index_python.packages import get_package_share_directory, get_package_prefix
from bond.msg import Constants
from bondpy.bondpy import Bond

TOPIC = "bond"
BOND_ID = "tracer"
PERIOD = 0.1
TIMEOUT = 4.0

failures = []


def check(ok, what):
    print(("ok   " if ok else "FAIL ") + what, flush=True)
    if not ok:
        failures.append(what)


def hash_from_json():
    path = os.path.join(get_package_share_directory("bond"), "msg", "Status.json")
    with open(path) as f:
        hashes = json.load(f)["type_hashes"]
    return path, {h["type_name"]: h["hash_string"] for h in hashes}


def from_typesupport():
    """(identifier, DDS type name, RIHS01 hash) from libbond__rosidl_typesupport_fastrtps_c.so."""
    lib = ctypes.CDLL(os.path.join(get_package_prefix("bond"), "lib",
                                   "libbond__rosidl_typesupport_fastrtps_c.so"))
    fn = lib.rosidl_typesupport_fastrtps_c__get_message_type_support_handle__bond__msg__Status
    fn.restype = ctypes.c_void_p

    class TypeSupport(ctypes.Structure):  # rosidl_message_type_support_t (Jazzy, Kilted)
        _fields_ = [("typesupport_identifier", ctypes.c_char_p), ("data", ctypes.c_void_p),
                    ("func", ctypes.c_void_p), ("get_type_hash_func", ctypes.c_void_p)]

    class Callbacks(ctypes.Structure):  # message_type_support_callbacks_t (its first fields)
        _fields_ = [("message_namespace_", ctypes.c_char_p), ("message_name_", ctypes.c_char_p)]

    class TypeHash(ctypes.Structure):  # rosidl_type_hash_t
        _fields_ = [("version", ctypes.c_uint8), ("value", ctypes.c_uint8 * 32)]

    ts = TypeSupport.from_address(fn())
    cb = Callbacks.from_address(ts.data)
    ns, name = cb.message_namespace_.decode(), cb.message_name_.decode()
    get_hash = ctypes.CFUNCTYPE(ctypes.POINTER(TypeHash), ctypes.c_void_p)(ts.get_type_hash_func)
    h = get_hash(ctypes.addressof(ts)).contents
    rihs = "RIHS%02d_%s" % (h.version, bytes(h.value).hex())
    # rmw_fastrtps_shared_cpp's _create_type_name: namespace "::dds_::" name "_"
    return ts.typesupport_identifier.decode(), f"{ns}::dds_::{name}_", rihs


def qos_text(q):
    return (f"reliability={q.reliability.name} durability={q.durability.name} "
            f"history={q.history.name} depth={q.depth} liveliness={q.liveliness.name} "
            f"deadline={q.deadline.nanoseconds}ns lifespan={q.lifespan.nanoseconds}ns")


def make_pair(tag):
    """Two nodes with a started Bond each; returns (nodes, bonds, events)."""
    nodes, bonds, ev = [], [], {}
    for side in "AB":
        node = rclpy.create_node(f"bond_check_{tag}_{side.lower()}")
        ev[side] = {"formed": threading.Event(), "broken": threading.Event(), "t_broken": None}

        def on_broken(side=side):
            ev[side]["t_broken"] = time.monotonic()
            ev[side]["broken"].set()

        bond = Bond(node, TOPIC, BOND_ID + tag, on_broken=on_broken,
                    on_formed=ev[side]["formed"].set)
        bond.heartbeat_period = PERIOD
        bond.heartbeat_timeout = TIMEOUT  # a float: it goes into Status.heartbeat_timeout
        nodes.append(node)
        bonds.append(bond)
    return nodes, bonds, ev


def spin_alone(node, errors):
    """node in its own SingleThreadedExecutor, in a thread; what stops it goes to errors."""
    ex = rclpy.executors.SingleThreadedExecutor()
    ex.add_node(node)

    def run():
        try:
            ex.spin()
        except Exception as e:  # noqa: BLE001 (recorded and reported)
            errors[node.get_name()] = f"{type(e).__name__}: {e}"

    t = threading.Thread(target=run, daemon=True, name="spin-" + node.get_name())
    t.start()
    return ex, t


def form(tag, errors):
    nodes, bonds, ev = make_pair(tag)
    spinners = [spin_alone(n, errors) for n in nodes]
    t0 = time.monotonic()
    for b in bonds:
        b.start()
    # wait_until_formed wants an rclpy Duration (a float fails inside bondpy's Timeout)
    formed = [b.wait_until_formed(Duration(seconds=5.0)) for b in bonds]
    t_formed = time.monotonic() - t0
    check(all(formed), f"[{tag or 'shutdown'}] both bonds formed after {t_formed:.3f} s (limit 5 s); "
                       f"on_formed called: A={ev['A']['formed'].wait(1.0)} B={ev['B']['formed'].wait(1.0)}")
    return nodes, bonds, ev, spinners


def stop(nodes, bonds, spinners):
    """Executors first, then bondpy's shutdown() (which, while a node spins, breaks its
    executor: see the report of case 1), then the nodes."""
    for ex, t in spinners:
        ex.shutdown()
        t.join(5.0)
    for b in bonds:
        b.shutdown()
    for n in nodes:
        n.destroy_node()


def main():
    timeout_case = "--timeout-case" in sys.argv[1:]
    print(f"rmw: {rclpy.utilities.get_rmw_implementation_identifier()}  "
          f"ROS_AUTOMATIC_DISCOVERY_RANGE={os.environ.get('ROS_AUTOMATIC_DISCOVERY_RANGE')}  "
          f"netns={os.environ.get('TRACER_NETNS', '0')}  distro={os.environ.get('TRACER_ROS_DIR', '?')}")
    json_path, json_hashes = hash_from_json()
    print(f"type description file: {json_path}")
    for name, h in json_hashes.items():
        print(f"  type_hashes: {name} {h}")
    ident, dds_name, ts_hash = from_typesupport()
    print(f"ROS type name: bond/msg/Status   DDS type name ({ident}): {dds_name}")
    print(f"type hash from the type support library: {ts_hash}")
    check(ts_hash == json_hashes["bond/msg/Status"], "type support hash == Status.json hash")
    print(f"Constants: DEFAULT_HEARTBEAT_PERIOD={Constants.DEFAULT_HEARTBEAT_PERIOD} "
          f"DEFAULT_HEARTBEAT_TIMEOUT={Constants.DEFAULT_HEARTBEAT_TIMEOUT} "
          f"DEFAULT_CONNECT_TIMEOUT={Constants.DEFAULT_CONNECT_TIMEOUT} "
          f"DEFAULT_DISCONNECT_TIMEOUT={Constants.DEFAULT_DISCONNECT_TIMEOUT} "
          f"DEAD_PUBLISH_PERIOD={Constants.DEAD_PUBLISH_PERIOD} "
          f"DISABLE_HEARTBEAT_TIMEOUT_PARAM={Constants.DISABLE_HEARTBEAT_TIMEOUT_PARAM!r}")

    rclpy.init()
    errors = {}
    try:
        # 1. formed, then A shuts down (stock shutdown(), its node still spinning): B breaks
        #    on A's DEAD status.
        nodes, bonds, ev, spinners = form("", errors)
        a, b = bonds
        infos = nodes[1].get_publishers_info_by_topic("/" + TOPIC)
        subs = nodes[1].get_subscriptions_info_by_topic("/" + TOPIC)
        for kind, lst in (("publisher", infos), ("subscription", subs)):
            for i in lst[:1]:
                print(f"bondpy {kind} ({i.node_name}) as rmw reports it: type {i.topic_type}, "
                      f"QoS {qos_text(i.qos_profile)}")
        for i in infos[:1]:
            h = getattr(i, "topic_type_hash", None)
            print(f"type hash rmw reports for bondpy's publisher: {h}")
            if h is not None:
                check(str(h) == json_hashes["bond/msg/Status"], "rmw's topic_type_hash == Status.json hash")
        time.sleep(1.0)  # ten heartbeats in the formed state
        check(not ev["B"]["broken"].is_set() and not ev["A"]["broken"].is_set(),
              "no bond broke during 1 s of 0.1 s heartbeats")
        t0 = time.monotonic()
        a.shutdown()
        got = ev["B"]["broken"].wait(2.0)
        tb = (ev["B"]["t_broken"] if got else time.monotonic()) - t0
        check(got, f"after A.shutdown(), B's on_broken called after {tb:.3f} s (limit 2 s)"
                   + ("" if got else ": not called"))
        got_a = ev["A"]["broken"].wait(3.0)
        ta = (ev["A"]["t_broken"] if got_a else time.monotonic()) - t0
        print(f"  A's own on_broken: {'called after %.3f s' % ta if got_a else 'not called within 3 s'} "
              f"(A: {a!r}; B: {b!r})")
        time.sleep(0.3)
        name_a = nodes[0].get_name()
        print(f"  A's executor after A.shutdown(): "
              f"{'stopped by ' + errors[name_a] if name_a in errors else 'still spinning'}")
        stop(nodes, bonds, spinners)

        # 2. (optional) A goes silent: B breaks by heartbeat timeout. bondpy starts B's
        #    heartbeat timer at the second status it gets from A (Alive + SisterAlive ->
        #    Heartbeat(); the one that forms the bond does not start it): a sister silent
        #    from the moment of forming is never timed out (2b, reported, not checked).
        if timeout_case:
            for tag, settle in (("_t", 1.0), ("_t0", 0.0)):
                nodes, bonds, ev, spinners = form(tag, errors)
                a, b = bonds
                time.sleep(settle)
                t0 = time.monotonic()
                a._publish = lambda active: None  # frozen: no more heartbeats, no DEAD status
                got = ev["B"]["broken"].wait(TIMEOUT + 2.0)
                tb = (ev["B"]["t_broken"] if got else time.monotonic()) - t0
                what = (f"[{tag}] A silent {settle:.0f} s after forming: B's on_broken after {tb:.3f} s"
                        + ("" if got else ": not called") + f" (heartbeat timeout {TIMEOUT} s; B: {b!r})")
                if settle:
                    check(got and TIMEOUT - 0.5 <= tb <= TIMEOUT + 1.0, what)
                else:
                    print("info " + what, flush=True)
                stop(nodes, bonds, spinners)
        other = {k: v for k, v in errors.items() if k != name_a}
        check(not other, f"no other executor stopped by an error {other or ''}")
    finally:
        rclpy.try_shutdown()
    print("bond_check: " + ("OK" if not failures else f"{len(failures)} FAILED"))
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
