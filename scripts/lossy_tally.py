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


def whole(run):
    """Everything through: contours, calls, parameter requests, the latched calibration."""
    return (
        not run.get("failed")
        and run["contours"] == run["scans"]
        and all(c is not None for c in run["calls"])
        and all(c is not None for c in run["param_calls"])
        and run["latched_ms"] is not None
    )


def shortfall(run):
    """What a run that did not get everything through lost, in words."""
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
        ok = [r for r in runs if whole(r)]
        line = f"{server} {rmw} {loss} %{' ' + variant if variant else ''}: everything through in {len(ok)} of {len(runs)} runs"
        lost = [shortfall(r) for r in runs if not whole(r)]
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
