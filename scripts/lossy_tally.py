"""The tally of `REPEAT=N bash scripts/bench_lossy.sh ...` (BENCHMARKS.md, "A lossy
network"): reads the result lines of tests/interop/test_lossy.py (one JSON object per run,
with "rmw" and "variant" added) and prints, per scenario and server, in how many runs
everything went through (every contour, /calibrate call and parameter request, and the
latched calibration), what the other runs lost, the spread of the runs' p50 and slowest
contour, and the TCP retransmission timeouts (Zenoh).
    python3 scripts/lossy_tally.py RESULTS"""

import json
import statistics
import sys
from collections import defaultdict


def shortfall(run):
    """What a run lost, in words: empty when everything went through (every contour, call
    and parameter request, and the latched calibration)."""
    if run.get("failed"):
        return "the scenario failed (no figures)"
    said = []
    if run["contours"] < run["scans"]:
        said.append(f"{run['scans'] - run['contours']} contours")
    calls = sum(c is None for c in run["calls"]) + sum(c is None for c in run["param_calls"])
    if calls:
        said.append(f"{calls} calls")
    if run["latched_ms"] is None:
        said.append("the latched calibration")
    return ", ".join(said)


def main(path):
    groups = defaultdict(list)
    with open(path) as f:
        for line in f:
            run = json.loads(line)
            groups[(run["rmw"], run["loss"], run.get("variant", ""), run["server"])].append(run)
    for (rmw, loss, variant, server), runs in sorted(groups.items()):
        lost = [said for said in map(shortfall, runs) if said]
        through = len(runs) - len(lost)
        line = f"{server} {rmw} {loss} %{' ' + variant if variant else ''}: everything through in {through} of {len(runs)} runs"
        if lost:
            line += " (the others lost: " + "; ".join(lost) + ")"
        timed = [r for r in runs if not r.get("failed") and r["latency_ms"]]
        if timed:
            p50 = sorted(statistics.median(r["latency_ms"]) for r in timed)
            slowest = sorted(max(r["latency_ms"]) for r in timed)
            line += (
                f"; p50 over the runs {p50[0]:.0f}-{p50[-1]:.0f} ms (median {statistics.median(p50):.0f}),"
                f" slowest contour {slowest[0]:.0f}-{slowest[-1]:.0f} ms"
            )
        tcp = [r["tcp"]["TCPTimeouts"] for r in runs if r.get("tcp") and r["tcp"].get("TCPTimeouts") is not None]
        if rmw == "zenoh" and tcp:
            line += f"; TCP retransmission timeouts per run {min(tcp)}-{max(tcp)}"
        print(line)


if __name__ == "__main__":
    main(sys.argv[1])
