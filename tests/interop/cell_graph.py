#!/usr/bin/env python3
"""A cell graph: N tracer_calib_node processes in /cell1 ... /cellN and one planner (a
stock rclpy node, Kilted, Fast DDS) that subscribes to every /cellK/contour, publishes to
every /cellK/raw_scan and calls every /cellK/calibrate. Measures, on this machine:

- discovery: from starting the N nodes (all at once, or CELL_STAGGER seconds apart; the
  planner CELL_PLANNER_HEAD_START seconds before them, default 1) until
  the planner has matched every raw_scan subscription and sees every calibrate service
  (given up after CELL_DISCOVERY_TIMEOUT, default 120 s);
- every scan answered and every call answered (nothing lost): per cell, a plate scan,
  /calibrate, then SCANS lens scans at RATE Hz per cell, all cells at once;
- CPU (utime + stime from /proc) and RSS of each node, idle (5 s after discovery) and
  under that load.

  python cell_graph.py N [SCANS] [RATE]      (run by scripts/cell_graph.sh)

Prints a JSON line with the figures last; exit status 0 only if nothing was lost.
"""

import json
import os
import sys
import time

import rclpy
from rclpy.qos import QoSProfile

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import harness as h  # noqa: E402
from tracer_calib_msgs.msg import Contour, RawScan  # noqa: E402
from tracer_calib_msgs.srv import Calibrate  # noqa: E402

HZ = os.sysconf("SC_CLK_TCK")


def cpu_s(pid):
    with open(f"/proc/{pid}/stat") as f:
        fields = f.read().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / HZ


def rss_mb(pid):
    with open(f"/proc/{pid}/status") as f:
        for line in f:
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) / 1024
    return 0.0


def cell_graph(peer, n, scans=50, rate=5.0, stagger=0.0, head_start=1.0, discovery_timeout=120.0):
    """The cell graph with `peer` as the planner (up `head_start` seconds before the nodes,
    which start `stagger` seconds apart); the figures as a dict. Raises AssertionError if
    the planner does not see every cell within `discovery_timeout`; the nodes are stopped
    in any case."""
    cells = [f"/cell{k}" for k in range(1, n + 1)]
    pubs, boxes, clients = {}, {}, {}
    for c in cells:
        pubs[c] = peer.node.create_publisher(RawScan, f"{c}/raw_scan", QoSProfile(depth=100))
        box = []
        peer.node.create_subscription(Contour, f"{c}/contour", box.append, QoSProfile(depth=100))
        boxes[c] = box
        clients[c] = peer.node.create_client(Calibrate, f"{c}/calibrate")
    plate = h.simulate("cell_plate", "plate", seed=2)
    lens = h.simulate("cell_lens", "ellipse", seed=3)

    end = time.monotonic() + head_start
    while time.monotonic() < end:
        peer.executor.spin_once(timeout_sec=0.02)
    t0 = time.monotonic()
    nodes = []
    for k in range(1, n + 1):
        nodes.append(h.NodeProcess(f"cell{k}", ["-r", f"__ns:=/cell{k}", "-r", "__node:=tracer"]))
        end = time.monotonic() + stagger
        while time.monotonic() < end:
            peer.executor.spin_once(timeout_sec=0.02)
    last_start = time.monotonic() - stagger
    try:
        peer.spin_until(
            lambda: all(pubs[c].get_subscription_count() > 0 for c in cells)
            and all(clients[c].service_is_ready() for c in cells),
            discovery_timeout,
            lambda: "the cells (raw_scan matched: {}; calibrate ready: {}; in the graph: {})".format(
                [c for c in cells if pubs[c].get_subscription_count() > 0],
                [c for c in cells if clients[c].service_is_ready()],
                sorted(ns for _, ns in peer.node.get_node_names_and_namespaces()),
            ),
        )
        discovery = time.monotonic() - t0
        after_last = time.monotonic() - last_start
        # Idle: 5 s with the graph up.
        idle0 = {x.proc.pid: cpu_s(x.proc.pid) for x in nodes}
        end = time.monotonic() + 5
        while time.monotonic() < end:
            peer.executor.spin_once(timeout_sec=0.05)
        idle = {pid: (cpu_s(pid) - c0) / 5 * 100 for pid, c0 in idle0.items()}
        rss_idle = [rss_mb(x.proc.pid) for x in nodes]

        # Load: a plate scan and /calibrate per cell, then lens scans at `rate` per cell.
        load0 = {x.proc.pid: cpu_s(x.proc.pid) for x in nodes}
        tl = time.monotonic()
        for c in cells:
            peer.send_scan(pubs[c], h.raw_scan(1, RawScan.TARGET_CALIBRATION_PLATE, *plate), boxes[c], timeout=60)
        futures = {c: clients[c].call_async(Calibrate.Request()) for c in cells}
        peer.spin_until(lambda: all(f.done() for f in futures.values()), 60, "every calibrate answered")
        calls_ok = sum(1 for f in futures.values() if f.result().success)
        sent = 0
        next_at = time.monotonic()
        for i in range(scans):
            for c in cells:
                pubs[c].publish(h.raw_scan(1000 + i, RawScan.TARGET_LENS, *lens))
            sent += n
            next_at += 1.0 / rate
            while time.monotonic() < next_at:
                peer.executor.spin_once(timeout_sec=max(0.0, next_at - time.monotonic()))

        def answered():
            return sum(len({m.scan_id for m in boxes[c] if m.scan_id >= 1000}) for c in cells)

        try:
            peer.spin_until(lambda: answered() == sent, 60, lambda: f"every scan answered ({answered()} of {sent})")
        except AssertionError as e:
            print(f"cell_graph: {e}", flush=True)
        load_s = time.monotonic() - tl
        load = {pid: (cpu_s(pid) - c0) / load_s * 100 for pid, c0 in load0.items()}
        rss_load = [rss_mb(x.proc.pid) for x in nodes]
        got = answered()
        corrected = all(m.calibrated for c in cells for m in boxes[c] if m.scan_id >= 1000)
    finally:
        for x in nodes:
            x.stop()
    mean = lambda v: sum(v) / len(v)  # noqa: E731
    out = {
        "nodes": n,
        "discovery_s": round(discovery, 2),
        "discovery_after_last_start_s": round(after_last, 2),
        "start_stagger_s": stagger,
        "cpu_idle_pct_per_node": round(mean(list(idle.values())), 2),
        "cpu_load_pct_per_node": round(mean(list(load.values())), 1),
        "cpu_load_pct_max": round(max(load.values()), 1),
        "rss_idle_mb_per_node": round(mean(rss_idle), 1),
        "rss_load_mb_per_node": round(mean(rss_load), 1),
        "rss_load_mb_max": round(max(rss_load), 1),
        "scans_sent": sent,
        "scans_answered": got,
        "scan_rate_hz_per_cell": rate,
        "calls": n,
        "calls_answered_ok": calls_ok,
        "all_corrected": corrected,
    }
    return out


def main():
    n = int(sys.argv[1])
    scans = int(sys.argv[2]) if len(sys.argv) > 2 else 50
    rate = float(sys.argv[3]) if len(sys.argv) > 3 else 5.0
    rclpy.init()
    out = cell_graph(
        h.Peer("planner"),
        n,
        scans,
        rate,
        stagger=float(os.environ.get("CELL_STAGGER", "0")),
        head_start=float(os.environ.get("CELL_PLANNER_HEAD_START", "1")),
        discovery_timeout=float(os.environ.get("CELL_DISCOVERY_TIMEOUT", "120")),
    )
    print(json.dumps(out), flush=True)
    ok = out["scans_answered"] == out["scans_sent"] and out["calls_answered_ok"] == n and out["all_corrected"]
    os._exit(0 if ok else 1)


if __name__ == "__main__":
    main()
