#!/usr/bin/env python3
"""Delay, and so reorder, the packets of NFQUEUE queue 0 (this kernel has no
netem): each is held for a delay drawn uniformly from [DELAY - JITTER, DELAY + JITTER] ms,
then accepted; packets closer together than the jitter's spread leave in another order
than they came. test_lossy.py queues to it the UDP datagrams lo sends in a scenario's
network namespace (iptables' NFQUEUE target: this kernel's nftables has no queue
expression). Needs the NetfilterQueue package (run.sh makes a venv with it).

    netdelay.py DELAY_MS JITTER_MS [SEED]

Prints "netdelay: ready" once bound; runs until SIGTERM, then lets what it holds go and
prints how many packets it delayed and how many left out of order."""
import heapq
import random
import select
import signal
import sys
import time

from netfilterqueue import NetfilterQueue


def main():
    delay, jitter = float(sys.argv[1]) / 1e3, float(sys.argv[2]) / 1e3
    rng = random.Random(int(sys.argv[3]) if len(sys.argv) > 3 else 29)
    held = []  # (release time, arrival number, packet)
    counts = {"held": 0, "reordered": 0, "last_released": -1}

    def on_packet(pkt):
        due = time.monotonic() + max(0.0, rng.uniform(delay - jitter, delay + jitter))
        heapq.heappush(held, (due, counts["held"], pkt))
        counts["held"] += 1

    nfq = NetfilterQueue()
    nfq.bind(0, on_packet, max_len=65536)
    stop = []
    signal.signal(signal.SIGTERM, lambda *_: stop.append(1))
    fd = nfq.get_fd()
    print("netdelay: ready", flush=True)
    while not stop:
        timeout = max(0.0, held[0][0] - time.monotonic()) if held else 0.1
        try:
            readable, _, _ = select.select([fd], [], [], timeout)
        except InterruptedError:
            continue
        if readable:
            nfq.run(block=False)
        now = time.monotonic()
        while held and held[0][0] <= now:
            _, number, pkt = heapq.heappop(held)
            if number < counts["last_released"]:
                counts["reordered"] += 1
            counts["last_released"] = max(counts["last_released"], number)
            pkt.accept()
    for _, _, pkt in held:
        pkt.accept()
    nfq.unbind()
    print(f"netdelay: {counts['held']} packets delayed, {counts['reordered']} out of order", flush=True)


main()
