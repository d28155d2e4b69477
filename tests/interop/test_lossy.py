#!/usr/bin/env python3
"""Nothing lost, nothing late on a lossy network.

Each scenario runs in a network namespace of its own (`unshare --net`, made here, inside the
private namespace run.sh gives the script), whose loopback drops a share of the UDP
datagrams it receives (nftables: `meta l4proto udp numgen random mod 100 < LOSS drop` on
the input hook of `lo`), from before the first participant starts: discovery, scans,
contours, service calls and their repairs all cross the same lossy loopback. Nothing leaves
the machine; the rule goes with the namespace.

In it, a server (tracer_calib_node, or, for reference, a stock rclpy node in its place that
answers each scan with a same-size Contour and each /calibrate call at once) and a driver
(rclpy, this script, on Fast DDS or on Cyclone DDS, as the server's peers):
  1. discovery: the driver's raw_scan publisher and contour subscription matched;
  2. a calibration-plate scan, republished until its contour comes back (the path works);
  3. SCANS lens scans (400 samples, reliable, keep last 50) at 20 Hz; the time from each
     publish to its contour; a scan whose contour has not come 10 s after the last publish
     is lost (the driver's contour subscription keeps SCANS + 50, so that what it counts
     lost was lost by the server or on the way, not by the driver's own queue; its rmw's
     count of sequence gaps is printed);
  4. 10 `/calibrate` calls (dry run, the plate scan), one after the other, each waited for
     15 s at most;
  5. 3 parameter requests (get `calibration.valid`), likewise;
  6. a late subscriber to the latched `calibration`: how long until it has the message.

Tests (each runs the stock node and tracer_calib_node under the same loss at the same
time, each in a namespace of its own, so that both meet the same load, and prints both side
by side): lossy_fastdds_10, lossy_fastdds_25, lossy_cyclone_10, lossy_cyclone_25 (the
Cyclone ones need target/ros/DISTRO/cyclone_env.sh, made by tests/interop/cyclone.sh, and
say they are skipped without it). Each asserts: the node loses no more contours than the
stock node (none at 10 %), every call and parameter request is answered, the latched
calibration reaches the late subscriber. Latency is printed, not asserted (a loaded CI
machine; BENCHMARKS.md has the figures). lossy_zenoh_10: the same on Zenoh
(target/ros/DISTRO/zenoh_env.sh, made by tests/interop/zenoh.sh; rmw_zenohd in the
scenario's namespace, TCP segments dropped as well as UDP datagrams: Zenoh's links are
TCP). lossy_fastdds_10_delay, lossy_cyclone_10_delay: 10 % loss, and every UDP datagram lo
sends delayed 10 ± 10 ms (uniformly), so that many arrive out of order (tests/interop/
netdelay.py, an NFQUEUE that iptables queues them to; TRACER_NETDELAY_PYTHON, a Python with
NetfilterQueue, which run.sh makes): asserted as at 10 %. lossy_fastdds_10_mtu1500,
lossy_cyclone_10_mtu1500: 10 % loss on a loopback whose MTU is Ethernet's, so that contours
travel as several DATA_FRAGs (RustDDS) or IP fragments (the stock peers), and the loss strikes
frames, as on an Ethernet link (a datagram larger than the MTU is lost with any of its
frames): asserted as at 10 %. lossy_ten_cells_fastdds_10,
lossy_ten_cells_cyclone_25: ten nodes and a planner (tests/interop/cell_graph.py, an rclpy
planner on Fast DDS, or on Cyclone DDS under 25 % loss) started at once; the planner matches
every cell, every call and scan is answered; lossy_ten_cells_fastdds_25 the same under 25 % loss
(a Fast DDS planner used to leave cells unmatched for good in 1 run of 4-12: RustDDS sent
discovery samples unstamped, and Fast DDS misfiled the late repairs of such a stream;
vendor/rustdds/PATCHES.md, "A sample written without a timestamp is stamped now").
lossy_zenoh_25_rtomax1s: Zenoh under 25 % loss with TCP's retransmission timeout capped at
1 s in the namespace (net.ipv4.tcp_rto_max_ms, as docs/zenoh.md advises a cell on a lossy
link): every contour and call through, asserted. Under the kernel's default backoff (up to
120 s) TCP itself stalls a link for longer than any wait a test can afford in about one run
in eight, for the stock node as for the node: no test asserts on that, scripts/bench_lossy.sh
with REPEAT=N tallies it (`LOSSY_RUN="node zenoh 25"` runs one).

Run by tests/interop/run.sh with pytest (conftest.py; names `lossy`, `lossy_fastdds_10`,
...); this file is also the scenarios' programs (`--cells`, `--stock-server`,
`--scenario`). Environment: LOSSY_SCANS (100), LOSSY_RUN="SERVER RMW LOSS [delay]" runs one scenario and
prints its figures (SERVER: node or stock, or cells for the ten-cell graph; RMW: fastdds, cyclone or zenoh; delay: delayed
and reordered too; mtu1500: lo's MTU 1500, loss per frame; keepall: keep all on both sides,
the driver's and the server's publishers and subscriptions, so that on Zenoh nothing is
dropped, only delayed (Block, not Drop; docs/zenoh.md, "On a lossy link"), stragglers
waited for 40 s; rtomax1s: TCP's retransmission timeout at most 1 s), as
scripts/bench_lossy.sh does for other losses. LOSSY_SEQUENTIAL=1: a test's stock node and
node one after the other (as before 2026-12-07).
"""

import atexit
import json
import os
import shutil
import subprocess
import sys
import time
from concurrent.futures import ThreadPoolExecutor

import pytest

HERE = os.path.dirname(os.path.abspath(__file__))
SCANS = int(os.environ.get("LOSSY_SCANS", "100"))
RATE_HZ = 20.0
CALLS = 10
PARAM_CALLS = 3
WAIT = 10.0  # for the stragglers after the last scan, and for the latched calibration
CALL_WAIT = 15.0  # for each call: generous, on a loaded CI machine
# For the stragglers in the "keepall" variant (Zenoh): nothing is dropped, and a TCP link
# under 25 % loss can stall for over 10 s while its retransmission timeout doubles.
KEEP_ALL_WAIT = 40.0
CAPTURE = None  # dumpcap, with LOSSY_PCAP or LOSSY_PCAP_SENT
CAPTURE_FILE = None  # its file: the servers' logs go beside it (FILE.log, FILE.cellK.log)
# Delay and reordering (the *_delay scenarios): every UDP datagram lo sends held 0-20 ms
# (uniformly: 10 ± 10 ms), so datagrams sent within a few ms of each other (a scan's
# DATA and its HEARTBEAT, a repair round) often arrive in another order.
DELAY_MS, JITTER_MS = 10, 10
# The "rtomax1s" variant (Zenoh): TCP's retransmission timeout, which doubles with each loss
# of the same segment (200 ms, 0.4, 0.8, 1.6 s, ... up to 120 s), capped at 1 s in the
# scenario's namespace (Linux >= 6.15: net.ipv4.tcp_rto_max_ms, per network namespace), as
# docs/zenoh.md ("On a lossy link") advises a cell whose Zenoh links cross a lossy network.
TCP_RTO_MAX_MS = 1000
TCP_RTO_MAX = "/proc/sys/net/ipv4/tcp_rto_max_ms"


def apply_loss(percent, protocols="udp", per_frame=False):
    """In this (fresh) network namespace: lo up, and `percent` % of the packets of
    `protocols` (nftables' set syntax: "udp", "{ udp, tcp }") that lo receives dropped.

    With LOSSY_PCAP=FILE (for a maintainer chasing a loss), the packets are dropped as they
    are sent instead, and a capture of what lo delivered is written to FILE: a capture on lo
    sees a packet before the input hook, so it would show the dropped ones too. The
    server's log is kept beside it (FILE.log). On TCP (Zenoh) a packet dropped on output is
    seen by the sender's own stack and sent again sooner than one lost on the way: such a
    run's latencies are not those of the test (losses on input); its capture still shows
    which messages a server never sent.

    `per_frame`: the packets are dropped as they arrive, before the kernel puts IP
    fragments back together (a prerouting chain ahead of defragmentation, priority -450),
    so that a datagram larger than the MTU is lost when any of its frames is, as on an
    Ethernet link. On the input hook a datagram is whole again and counts once, however
    many frames it took."""
    subprocess.run(["ip", "link", "set", "lo", "up"], check=True)
    pcap = os.environ.get("LOSSY_PCAP")
    # LOSSY_PCAP_SENT=FILE: the test's own loss (on input), and a capture of what was
    # sent, dropped ones included (a capture on lo sees a packet before the input hook):
    # it shows what each side sent and when, not what arrived.
    sent = os.environ.get("LOSSY_PCAP_SENT")
    if pcap or sent:
        global CAPTURE, CAPTURE_FILE
        CAPTURE_FILE = pcap or sent
        CAPTURE = subprocess.Popen(
            ["dumpcap", "-q", "-i", "lo", "-w", CAPTURE_FILE], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL
        )
        # A scenario that fails (an assertion) exits without reaching stop_capture.
        atexit.register(stop_capture)
        time.sleep(1.0)
    if percent <= 0:
        return
    hook, iface = ("output", "oifname") if pcap else ("input", "iifname")
    priority = 0
    if per_frame and not pcap:
        hook, priority = "prerouting", -450
        # The frames of a datagram that lost one wait for the rest (`ipfrag_time`, 30 s)
        # in reassembly memory, 4 MB a namespace (`ipfrag_high_thresh`); past it every
        # frame is dropped (ReasmFails) until some time out: all large datagrams lost, for
        # the node and the stock node alike (seen: 2812 frames dropped so in one run, 82
        # datagrams whole in it). On lo a frame is the sender's own buffer, a share of the
        # whole datagram's, where a NIC's is its own 2 kB; so much more room, as a host
        # receiving those frames from a NIC would have.
        with open("/proc/sys/net/ipv4/ipfrag_high_thresh", "w") as f:
            f.write(str(256 << 20))
        with open("/proc/sys/net/ipv4/ipfrag_low_thresh", "w") as f:
            f.write(str(192 << 20))
    rules = f"""
table inet tracer_loss {{
    chain {hook} {{
        type filter hook {hook} priority {priority}; policy accept;
        {iface} "lo" meta l4proto {protocols} counter
        {iface} "lo" meta l4proto {protocols} numgen random mod 100 < {percent} counter drop
    }}
}}
"""
    subprocess.run(["nft", "-f", "-"], input=rules, text=True, check=True)


def stop_capture():
    """End the LOSSY_PCAP capture, if there is one."""
    if CAPTURE:
        CAPTURE.terminate()
        CAPTURE.wait()


def apply_delay():
    """In this namespace: tests/interop/netdelay.py (NFQUEUE queue 0, run by
    TRACER_NETDELAY_PYTHON) holds every UDP datagram lo sends for DELAY_MS ± JITTER_MS.
    Returns the netdelay process (stop_delay ends it)."""
    python = os.environ.get("TRACER_NETDELAY_PYTHON")
    assert python, "TRACER_NETDELAY_PYTHON: a Python with NetfilterQueue (run.sh makes it)"
    proc = subprocess.Popen(
        [python, os.path.join(HERE, "netdelay.py"), str(DELAY_MS), str(JITTER_MS)],
        stdout=subprocess.PIPE,
        text=True,
    )
    assert proc.stdout.readline().strip() == "netdelay: ready", "netdelay.py did not start"
    subprocess.run(
        ["iptables", "-A", "OUTPUT", "-o", "lo", "-p", "udp", "-j", "NFQUEUE", "--queue-num", "0"], check=True
    )
    return proc


def stop_delay(proc):
    """Ends netdelay.py: (datagrams delayed, of which left out of order)."""
    subprocess.run(["iptables", "-F", "OUTPUT"], check=True)
    proc.terminate()
    out, _ = proc.communicate(timeout=10)
    words = out.split()
    return int(words[1]), int(words[4])


def loss_counters():
    """(UDP datagrams lo received, of which dropped) so far, from the rules' counters."""
    out = subprocess.run(["nft", "-j", "list", "table", "inet", "tracer_loss"], capture_output=True, text=True)
    if out.returncode != 0:
        return (None, None)
    counts = [
        e["counter"]["packets"]
        for item in json.loads(out.stdout)["nftables"]
        if "rule" in item
        for e in item["rule"]["expr"]
        if "counter" in e
    ]
    return tuple(counts[:2]) if len(counts) >= 2 else (None, None)


def proc_net_counters(path, section, keys):
    """Counters of this namespace from a /proc/net table (`path`: snmp, netstat), a dict of
    `keys`: the `section` ("Ip:", "TcpExt:") has a line of names, then one of values."""
    with open(path) as f:
        rows = [ln.split() for ln in f if ln.startswith(section)]
    counters = dict(zip(rows[0][1:], (int(v) for v in rows[1][1:])))
    return {k: counters.get(k) for k in keys}


def reassembly_counters():
    """This namespace's IP reassembly counters (/proc/net/snmp: ReasmReqds, ReasmOKs,
    ReasmFails, ReasmTimeout), a dict; per-frame loss leaves the frames of a datagram
    that lost one waiting for the rest (`ipfrag_time`, 30 s) in memory of its own."""
    return proc_net_counters("/proc/net/snmp", "Ip:", ("ReasmReqds", "ReasmOKs", "ReasmFails", "ReasmTimeout"))


def tcp_counters():
    """This namespace's TCP retransmission counters (/proc/net/netstat, TcpExt), a dict:
    on Zenoh a sample waits for TCP, and a segment lost again after a retransmission
    timeout waits twice as long each time (TCPTimeouts: retransmission timeouts;
    TCPLostRetransmit: retransmissions lost again; TCPSynRetrans: connection attempts
    sent again, after which Linux starts the connection's timeout at 3 s)."""
    return proc_net_counters("/proc/net/netstat", "TcpExt:", ("TCPTimeouts", "TCPLostRetransmit", "TCPSynRetrans"))


def stock_server_main():
    """A stock rclpy node in the node's place, with its QoS: raw_scan (reliable, keep last
    100) answered by a Contour as large as the node's (400 points, 360 radii and their
    U95, the size figures) on contour
    (reliable, keep last 10); /calibrate answered at once; `calibration` latched
    (reliable, transient local, depth 1); a parameter `calibration.valid`."""
    import rclpy
    from geometry_msgs.msg import Point
    from rclpy.node import Node
    from rclpy.qos import DurabilityPolicy, QoSProfile

    from tracer_calib_msgs.msg import Calibration, Contour, RawScan
    from tracer_calib_msgs.srv import Calibrate

    rclpy.init()
    node = Node("tracer_calibrator")
    node.declare_parameter("calibration.valid", False)
    pub = node.create_publisher(Contour, "/contour", qos(10))
    latched = node.create_publisher(
        Calibration, "/calibration", QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL)
    )
    cal = Calibration()
    cal.model = "full"
    latched.publish(cal)

    def on_scan(scan):
        c = Contour()
        c.header = scan.header
        c.scan_id = scan.scan_id
        c.target = scan.target
        c.points = [Point(x=1e-6 * n, y=1e-6 * n) for n in scan.counts]
        c.radii = [0.02] * 360
        c.radii_u95 = [2e-6] * 360
        c.circumference, c.box_width, c.box_height, c.effective_diameter = 0.1276, 0.05, 0.03, 0.05
        c.size_u95 = [4e-6] * 4
        try:
            pub.publish(c)
        except Exception as e:  # noqa: BLE001 (rclpy's RCLError)
            # Fast DDS (Kilted) under 25 % loss: "cannot publish data" once the reliable
            # writer's history stays full; a stock node would die of it. Counted as lost.
            print(f"stock node: contour {scan.scan_id} not published: {e}", file=sys.stderr, flush=True)

    def on_calibrate(request, response):
        response.success = True
        response.message = f"scan {request.scan_id}: dry run"
        return response

    node.create_subscription(RawScan, "/raw_scan", on_scan, qos(100))
    node.create_service(Calibrate, "/calibrate", on_calibrate)
    rclpy.spin(node)


def qos(depth):
    """Reliable, volatile, keep last `depth`; keep all in the "keepall" variant
    (LOSSY_KEEP_ALL, which scenario_main sets for the stock node too)."""
    from rclpy.qos import HistoryPolicy, QoSProfile

    if os.environ.get("LOSSY_KEEP_ALL"):
        return QoSProfile(history=HistoryPolicy.KEEP_ALL)
    return QoSProfile(depth=depth)


def scenario_main(server, loss, variant=""):
    """One scenario in this fresh namespace (see the module doc): prints one JSON line. On
    Zenoh (RMW_IMPLEMENTATION=rmw_zenoh_cpp) everything goes by TCP through the router,
    and TCP segments are dropped too. `variant` "delay": UDP datagrams delayed and
    reordered too (apply_delay); "mtu1500": lo's MTU that of an Ethernet link, so that
    large samples travel as several datagrams (RustDDS: DATA_FRAG) or IP fragments, and
    the loss strikes frames, as it would on that link (apply_loss's `per_frame`);
    "keepall": keep all on both sides (the driver's, and the server's by
    LOSSY_KEEP_ALL or by the node's qos_overrides); "rtomax1s": TCP's retransmission
    timeout capped at 1 s (TCP_RTO_MAX_MS) in this namespace."""
    zenoh = os.environ.get("RMW_IMPLEMENTATION") == "rmw_zenoh_cpp"
    apply_loss(loss, "{ udp, tcp }" if zenoh else "udp", per_frame=variant == "mtu1500")
    if variant == "mtu1500":
        subprocess.run(["ip", "link", "set", "lo", "mtu", "1500"], check=True)
    if variant == "rtomax1s":
        with open(TCP_RTO_MAX, "w") as f:
            f.write(str(TCP_RTO_MAX_MS))
    delay = apply_delay() if variant == "delay" else None
    node_args = []
    if variant == "keepall":
        # Keep all on both sides: the driver's publisher and subscription, the server's
        # (the stock node's by LOSSY_KEEP_ALL, the node's by its qos_overrides).
        os.environ["LOSSY_KEEP_ALL"] = "1"
        node_args = [a for topic, side in (("/contour", "publisher"), ("/raw_scan", "subscription"))
                     for a in ("-p", f"qos_overrides.{topic}.{side}.history:=keep_all")]
    if zenoh:
        # A lost SYN fails a connection attempt to the router (TCP tries again after 1 s,
        # then 2, 4, 8 s): a cell on a lossy network lets rmw_zenoh (and the node) wait for
        # its router (0: until it answers; with 10 checks the node gave up in 1 start of 16
        # under 25 % loss; the scenario's own waits bound it).
        os.environ["ZENOH_ROUTER_CHECK_ATTEMPTS"] = "0"
    sys.path.insert(0, HERE)
    import rclpy
    from rcl_interfaces.srv import GetParameters
    from rclpy.qos import DurabilityPolicy, QoSProfile

    import harness as h
    from tracer_calib_msgs.msg import Calibration, Contour, RawScan
    from tracer_calib_msgs.srv import Calibrate

    plate = h.simulate("lossy_plate", "plate", seed=3)
    lens = h.simulate("lossy_lens", "ellipse", seed=4)
    # 30 s: under loss a lost SYN of the listening check costs a second.
    router = h.ZenohRouter(h.WORK, wait=30.0) if zenoh else None
    t_start = time.monotonic()
    if server == "stock":
        node = h.NodeProcess("lossy_stock", argv=[sys.executable, os.path.abspath(__file__), "--stock-server"], peer=True)
    else:
        node = h.NodeProcess("lossy_node", node_args)
    result = {"server": server, "loss": loss}
    try:
        rclpy.init()
        peer = h.Peer("lossy_driver")
        arrivals = {}
        # The driver stands for an edger that wants every contour: its own queue keeps every
        # contour the scenario can send (keep last SCANS + 50), so that a contour counted
        # lost was lost by the server or on the way, never dropped by the driver's rmw when
        # a stalled link hands over a backlog at once (rmw_zenoh's subscription queue drops
        # its oldest message past the depth, and rclpy takes one message per callback:
        # after a 3 s TCP stall under 25 % loss, 60 contours arrive within milliseconds).
        # The rmw's own count of messages lost on the way (sequence gaps: dropped by the
        # server's transport, or by a reliable writer's keep-last history), where it has
        # one, tells those apart in the figures.
        lost_on_way = [0]
        contour_qos = qos(SCANS + 50)
        try:
            from rclpy.event_handler import SubscriptionEventCallbacks

            events = SubscriptionEventCallbacks(message_lost=lambda e: lost_on_way.__setitem__(0, e.total_count))
            contour_sub = peer.node.create_subscription(
                Contour, "/contour", lambda c: arrivals.setdefault(c.scan_id, time.monotonic()), contour_qos,
                event_callbacks=events,
            )
        except Exception:  # noqa: BLE001 (an rmw without the message-lost event)
            lost_on_way[0] = None
            contour_sub = peer.node.create_subscription(
                Contour, "/contour", lambda c: arrivals.setdefault(c.scan_id, time.monotonic()), contour_qos
            )
        pub = peer.node.create_publisher(RawScan, "/raw_scan", qos(50))
        # The node's own counts (its /diagnostics, once a second), to tell a scan lost on
        # the way in from a contour lost on the way back.
        counts = {}
        if server == "node":
            from diagnostic_msgs.msg import DiagnosticArray

            wanted = ("scans_received", "contours_published")
            peer.node.create_subscription(
                DiagnosticArray,
                "/diagnostics",
                lambda d: counts.update((kv.key, int(kv.value)) for s in d.status for kv in s.values if kv.key in wanted),
                qos(10),
            )
        peer.spin_until(
            lambda: pub.get_subscription_count() > 0 and contour_sub.get_publisher_count() > 0,
            60,
            "the node's raw_scan subscription and contour publisher",
        )
        result["matched_s"] = time.monotonic() - t_start

        # The path works: a plate scan, republished until its contour is back.
        deadline = time.monotonic() + 60
        while 1 not in arrivals:
            assert time.monotonic() < deadline, "no contour for the plate scan within 60 s"
            pub.publish(h.raw_scan(1, RawScan.TARGET_CALIBRATION_PLATE, *plate))
            end = time.monotonic() + 1.0
            while 1 not in arrivals and time.monotonic() < end:
                peer.executor.spin_once(timeout_sec=0.01)
        result["first_contour_s"] = time.monotonic() - t_start

        # SCANS lens scans at RATE_HZ.
        published = {}
        period = 1.0 / RATE_HZ
        t_next = time.monotonic()
        for k in range(SCANS):
            scan_id = 100 + k
            while time.monotonic() < t_next:
                peer.executor.spin_once(timeout_sec=max(0.0, t_next - time.monotonic()))
            published[scan_id] = time.monotonic()
            pub.publish(h.raw_scan(scan_id, RawScan.TARGET_LENS, *lens))
            t_next += period
        end = time.monotonic() + (KEEP_ALL_WAIT if variant == "keepall" else WAIT)
        while time.monotonic() < end and not all(s in arrivals for s in published):
            peer.executor.spin_once(timeout_sec=0.01)
        lat = [(arrivals[s] - t) * 1e3 for s, t in published.items() if s in arrivals]
        result["scans"] = SCANS
        result["contours"] = len(lat)
        result["latency_ms"] = lat
        result["missing"] = sorted(s for s in published if s not in arrivals)
        result["lost_on_way"] = lost_on_way[0]
        if result["missing"] and counts:
            # A second for the node's next diagnostics to come.
            end = time.monotonic() + 1.5
            while time.monotonic() < end:
                peer.executor.spin_once(timeout_sec=0.05)
            result["node_counts"] = dict(counts)

        # /calibrate calls, one after the other.
        client = peer.node.create_client(Calibrate, "/calibrate")
        peer.spin_until(client.service_is_ready, 60, "the /calibrate service")
        result["calls"] = timed_calls(peer, lambda: client.call_async(Calibrate.Request(scan_id=1, dry_run=True)), CALLS)

        # Parameter requests.
        params = peer.node.create_client(GetParameters, "/tracer_calibrator/get_parameters")
        peer.spin_until(params.service_is_ready, 60, "the parameter services")
        request = GetParameters.Request(names=["calibration.valid"])
        result["param_calls"] = timed_calls(peer, lambda: params.call_async(request), PARAM_CALLS)

        # A late subscriber to the latched calibration.
        got = []
        t0 = time.monotonic()
        peer.node.create_subscription(
            Calibration,
            "/calibration",
            lambda m: got.append(time.monotonic()),
            QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL),
        )
        end = time.monotonic() + WAIT
        while not got and time.monotonic() < end:
            peer.executor.spin_once(timeout_sec=0.01)
        result["latched_ms"] = (got[0] - t0) * 1e3 if got else None
        node.check_alive()
    except BaseException:
        print(f"--- {node.label}'s log:\n{node.output()[-4000:]}", flush=True)
        raise
    finally:
        try:
            if server == "stock":
                # The reference, not under test: rclpy on rmw_zenoh_cpp may not exit on
                # SIGTERM within the harness' 5 s (its session's close under loss).
                h.RUNNING.remove(node)
                node.proc.kill()
                node.proc.wait()
            else:
                node.stop()
        finally:
            if router:
                router.stop()
    if CAPTURE:
        shutil.copy(node.log_path, CAPTURE_FILE + ".log")
    shutil.rmtree(h.WORK, ignore_errors=True)
    result["udp_received"], result["udp_dropped"] = loss_counters()
    result["reassembly"] = reassembly_counters()
    result["tcp"] = tcp_counters()
    if delay:
        result["udp_delayed"], result["udp_reordered"] = stop_delay(delay)
    stop_capture()
    print(json.dumps(result), flush=True)


def cells_main(loss):
    """Ten nodes (/cell1 ... /cell10) and a planner (rclpy, this process) started at once in
    this fresh namespace under `loss` % UDP loss (tests/interop/cell_graph.py): prints one
    JSON line with how long until the planner had matched every cell, and what came back."""
    apply_loss(loss)
    sys.path.insert(0, HERE)
    import rclpy

    import cell_graph
    import harness as h

    rclpy.init()
    planner = h.Peer("planner")
    try:
        out = cell_graph.cell_graph(planner, 10, scans=3, head_start=0.0, discovery_timeout=60.0)
    finally:
        for n in list(h.RUNNING):
            n.stop()
        if CAPTURE:
            # The cells' logs beside the capture (FILE.cellK.log), as for a scenario.
            for name in os.listdir(h.WORK):
                if name.startswith("cell") and name.endswith(".log"):
                    shutil.copy(os.path.join(h.WORK, name), CAPTURE_FILE + "." + name)
            stop_capture()
    shutil.rmtree(h.WORK, ignore_errors=True)
    out["udp_received"], out["udp_dropped"] = loss_counters()
    print(json.dumps(out), flush=True)


def timed_calls(peer, start, count):
    """`count` requests, one after the other: each one's answer time in ms, or None when
    none came within CALL_WAIT."""
    out = []
    for _ in range(count):
        t0 = time.monotonic()
        future = start()
        end = t0 + CALL_WAIT
        while not future.done() and time.monotonic() < end:
            peer.executor.spin_once(timeout_sec=0.005)
        out.append((time.monotonic() - t0) * 1e3 if future.done() else None)
    return out


NO_DATA_SHARING = """
    <data_writer profile_name="tracer_lossy_writer" is_default_profile="true">
      <qos><data_sharing><kind>OFF</kind></data_sharing></qos>
    </data_writer>
    <data_reader profile_name="tracer_lossy_reader" is_default_profile="true">
      <qos><data_sharing><kind>OFF</kind></data_sharing></qos>
    </data_reader>
  </profiles>"""


def over_the_network(env, work):
    """`env` with Fast DDS' shared memory off: two rclpy processes on one host otherwise
    pass their samples through it (rmw_fastrtps adds the shared-memory transport under
    ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST whatever the profile says, and data sharing is
    on by default), which no packet loss touches, and the stock node would not be compared
    with the node over the network. So: FASTDDS_BUILTIN_TRANSPORTS=UDPv4, the discovery
    range SUBNET (the scenario's namespace has no interface but lo), and the peers' loopback
    profile with default writer and reader profiles that turn data sharing off. Measured:
    with these, every scan and contour crosses lo as a UDP datagram; without them, none."""
    src = env.get("FASTDDS_DEFAULT_PROFILES_FILE")
    if not src or env.get("RMW_IMPLEMENTATION") != "rmw_fastrtps_cpp":
        return env
    with open(src) as f:
        xml = f.read()
    assert "</profiles>" in xml, f"{src}: no </profiles>"
    path = os.path.join(work, "fastdds_no_data_sharing.xml")
    with open(path, "w") as f:
        f.write(xml.replace("</profiles>", NO_DATA_SHARING.lstrip("\n"), 1))
    return dict(
        env,
        FASTDDS_DEFAULT_PROFILES_FILE=path,
        FASTDDS_BUILTIN_TRANSPORTS="UDPv4",
        ROS_AUTOMATIC_DISCOVERY_RANGE="SUBNET",
    )


def run_scenario(env, server, loss, variant=""):
    """One scenario in a network namespace of its own (SERVER "cells": the ten-cell graph;
    `variant`: see scenario_main): its figures (a dict)."""
    args = ["--cells", str(loss)] if server == "cells" else ["--scenario", server, str(loss)]
    args += [variant] if variant else []
    out = subprocess.run(
        ["unshare", "--net", "--", "timeout", "-s", "KILL", "300", sys.executable, os.path.abspath(__file__), *args],
        env=env,
        capture_output=True,
        text=True,
    )
    lines = [ln for ln in out.stdout.splitlines() if ln.startswith("{")]
    if out.returncode != 0 or not lines:
        raise AssertionError(
            f"{server} under {loss} % loss: exit {out.returncode}\n{out.stdout[-3000:]}\n{out.stderr[-3000:]}"
        )
    return json.loads(lines[-1])


def describe(r):
    from harness import percentile

    lat = r["latency_ms"]
    calls = [c for c in r["calls"] if c is not None]
    text = f"{r['contours']}/{r['scans']} contours"
    if lat:
        text += f", p50 {percentile(lat, 50):.1f} ms, p99 {percentile(lat, 99):.1f} ms, max {max(lat):.0f} ms"
    if r.get("missing"):
        text += f" (missing: scans {', '.join(map(str, r['missing']))}"
        if r.get("node_counts"):
            # Scans sent: the plate's (at least once) and the lenses.
            text += ", the node's diagnostics: " + ", ".join(f"{k} {v}" for k, v in r["node_counts"].items())
        if r.get("lost_on_way") is not None:
            text += f", the driver's rmw counted {r['lost_on_way']} lost on the way"
        text += ")"
    text += f"; calls {len(calls)}/{len(r['calls'])}"
    if calls:
        text += f" (max {max(calls):.1f} ms)"
    params = [c for c in r["param_calls"] if c is not None]
    text += f"; params {len(params)}/{len(r['param_calls'])}"
    latched = r["latched_ms"]
    text += "; latched " + ("never" if latched is None else f"{latched:.0f} ms")
    text += f"; matched after {r['matched_s']:.2f} s"
    if r.get("udp_received"):
        text += f"; {r['udp_dropped']} of {r['udp_received']} packets dropped"
    if r.get("udp_delayed"):
        text += f"; {r['udp_delayed']} delayed {DELAY_MS} ± {JITTER_MS} ms, {r['udp_reordered']} out of order"
    reasm = r.get("reassembly") or {}
    if reasm.get("ReasmReqds"):
        text += (f"; IP reassembly: {reasm['ReasmOKs']} datagrams whole, {reasm['ReasmFails']} failures"
                 f" (frames), {reasm['ReasmTimeout']} timed out")
    return text


VARIANTS = {"": "", "delay": f", delayed {DELAY_MS} ± {JITTER_MS} ms", "mtu1500": ", MTU 1500",
            "keepall": ", keep all", "rtomax1s": f", TCP RTO at most {TCP_RTO_MAX_MS} ms"}


@pytest.fixture(scope="module")
def envs():
    """This environment on each middleware, made to cross the network namespace's lossy
    link (over_the_network)."""
    import harness as h

    return {rmw: env and over_the_network(env, h.WORK) for rmw, env in h.peer_envs().items()}


def by_rmw(rmw, *rest):
    return pytest.param(rmw, *rest, id="_".join(str(x) for x in (rmw, *rest) if x), marks=getattr(pytest.mark, rmw))


# Zenoh at 25 % only with TCP's backoff capped: under the kernel's default, TCP stalls a
# link past any wait a test can afford in about one run in eight, the stock node's as the
# node's (docs/zenoh.md, "On a lossy link"); REPEAT=N bash scripts/bench_lossy.sh jazzy
# 100 zenoh 25 tallies them over N runs.
@pytest.mark.parametrize(("rmw", "loss", "variant"), [
    by_rmw(rmw, loss, "") for rmw in ("fastdds", "cyclone", "zenoh") for loss in (10, 25) if (rmw, loss) != ("zenoh", 25)
] + [
    by_rmw(rmw, 10, variant) for variant in ("delay", "mtu1500") for rmw in ("fastdds", "cyclone")
] + [by_rmw("zenoh", 25, "rtomax1s")])
def test_lossy(envs, rmw, loss, variant):
    """lossy_fastdds_10, ..., lossy_zenoh_25_rtomax1s."""
    env = envs[rmw]
    if env is None:
        return f"skipped: no {rmw}_env.sh (tests/interop/{rmw}.sh builds it)"
    if variant == "rtomax1s" and not os.path.exists(TCP_RTO_MAX):
        return f"skipped: this kernel ({os.uname().release}) has no {TCP_RTO_MAX} (Linux 6.15 on)"
    label = f"{rmw} {loss} %{VARIANTS[variant]}"
    # The stock node in the node's place is the reference, not the subject: one that never
    # gets a first contour through (Fast DDS' 64 kB datagrams, 44 frames each at MTU 1500,
    # under 10 % frame loss) is said so and counted as having lost every scan.
    # Both at once: a scenario waits on the network far more than it computes (its 100
    # scans at 20 Hz, repairs, 10-15 s waits), and their namespaces share nothing.
    with ThreadPoolExecutor(max_workers=1 if os.environ.get("LOSSY_SEQUENTIAL") else 2) as pool:
        stock_run = pool.submit(run_scenario, env, "stock", loss, variant)
        node_run = pool.submit(run_scenario, env, "node", loss, variant)
        try:
            stock = stock_run.result()
            stock_text = describe(stock)
        except AssertionError as e:
            stock = None
            stock_text = "never got through: " + str(e).strip().splitlines()[-1]
        print(f"  {label}: stock rclpy node: {stock_text}", flush=True)
        node = node_run.result()
    print(f"  {label}: tracer_calib_node: {describe(node)}", flush=True)
    lost_node = node["scans"] - node["contours"]
    lost_stock = node["scans"] if stock is None else stock["scans"] - stock["contours"]
    # Zenoh with TCP's backoff capped: every scan and call through.
    allowed = 0 if loss <= 10 or variant == "rtomax1s" else lost_stock
    assert lost_node <= allowed, f"the node lost {lost_node} contours, the stock node {lost_stock}"
    assert None not in node["calls"] + node["param_calls"], (
        f"calls unanswered within {CALL_WAIT} s: /calibrate {node['calls']}, parameters {node['param_calls']}"
    )
    assert node["latched_ms"] is not None, f"the latched calibration did not reach a late subscriber in {WAIT} s"
    return f"node {describe(node)} | stock {stock_text}"


@pytest.mark.parametrize(("rmw", "loss"), [by_rmw("fastdds", 10), by_rmw("fastdds", 25), by_rmw("cyclone", 25)])
def test_ten_cells(envs, rmw, loss):
    """Ten nodes and a planner started at once under `loss` % UDP loss: the planner matches
    every cell (generously within 20 s; BENCHMARKS.md has the figures), every call is
    answered and every scan comes back corrected."""
    env = envs[rmw]
    if env is None:
        return "skipped: no cyclone_env.sh (tests/interop/cyclone.sh builds it)"
    out = run_scenario(env, "cells", loss)
    text = (
        f"discovery {out['discovery_s']} s; calls {out['calls_answered_ok']}/{out['calls']}; "
        f"scans {out['scans_answered']}/{out['scans_sent']}; {out['udp_dropped']} of {out['udp_received']} "
        "packets dropped"
    )
    assert out["discovery_s"] <= 20.0, text
    assert out["calls_answered_ok"] == out["calls"], text
    assert out["scans_answered"] == out["scans_sent"] and out["all_corrected"], text
    return text


def main():
    if sys.argv[1:2] == ["--cells"]:
        cells_main(int(sys.argv[2]))
        os._exit(0)
    if sys.argv[1:2] == ["--stock-server"]:
        stock_server_main()
        os._exit(0)
    if sys.argv[1:2] == ["--scenario"]:
        scenario_main(sys.argv[2], int(sys.argv[3]), "".join(sys.argv[4:5]))
        os._exit(0)
    sys.path.insert(0, HERE)
    import harness as h

    envs = {rmw: env and over_the_network(env, h.WORK) for rmw, env in h.peer_envs().items()}
    if os.environ.get("LOSSY_RUN"):
        server, rmw, loss, *variant = os.environ["LOSSY_RUN"].split()
        variant = "".join(variant)
        r = run_scenario(envs[rmw], server, int(loss), variant)
        if server != "cells":
            print(f"{server} {rmw} {loss} %{VARIANTS[variant]}: {describe(r)}", flush=True)
        print(json.dumps(r), flush=True)
        os._exit(0)
    print("test_lossy.py: run the tests with pytest (tests/interop/run.sh lossy)", file=sys.stderr)
    os._exit(2)


if __name__ == "__main__":
    main()
