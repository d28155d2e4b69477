#!/usr/bin/env python3
"""A second reader of VCA/OMA trace files, written apart from tracer_calib's code.

It follows the standard's record rules as docs/cli.md states them (records LABEL=VALUE,
one a line; every dataset opens with its own ...FMT record and the data records R=, A=,
Z= after it are its; TRCFMT=format;N;E|U;eye;type; radii and angles whole numbers in
1/100 mm and 1/100 degree; chiral size records right;left, one with no ";" both eyes', the first of a label) and computes each trace's
figures by the plainest means: the circumference of the polygon through its points, the
box of its points, the FED as twice the farthest point from the box centre. Prints one
JSON object: {"traces": [{"eye", "type", "n", "circumference", "box_width",
"box_height", "effective_diameter", "records": {...}}]}, lengths in metres.

Usage: second_reader.py FILE
"""

import json
import math
import sys

LABELS = {"CIRC": "circumference", "HBOX": "box_width", "VBOX": "box_height", "FED": "effective_diameter"}


def read(text):
    records = []
    for line in text.replace("\r", "").split("\n"):
        line = line.strip()
        if not line:
            continue
        label, _, value = line.partition("=")
        records.append((label.strip().upper(), value.strip()))
    traces, sizes = [], {}
    current = None  # the trace whose data records come now, or None for another dataset
    for label, value in records:
        if label.endswith("FMT") and len(label) > 3:
            current = None
            fields = value.split(";")
            if label == "TRCFMT" and fields[0].strip() == "1":
                current = {
                    "eye": fields[3].strip().upper(),
                    "type": fields[4].strip().upper(),
                    "n": int(fields[1]),
                    "equiangular": fields[2].strip().upper() == "E",
                    "radii": [],
                    "angles": [],
                }
                traces.append(current)
        elif label == "R" and current is not None:
            current["radii"] += [int(v) for v in value.split(";") if v.strip()]
        elif label == "A" and current is not None:
            current["angles"] += [int(v) for v in value.split(";") if v.strip()]
        elif label in LABELS and label not in sizes:
            sizes[label] = value.split(";")
    out = []
    for t in traces:
        n = t["n"]
        assert len(t["radii"]) == n, "radii count"
        if t["equiangular"]:
            angles = [2.0 * math.pi * i / n for i in range(n)]
        else:
            assert len(t["angles"]) == n, "angle count"
            angles = [math.radians(a / 100.0) for a in t["angles"]]
        pts = [(r * 1e-5 * math.cos(a), r * 1e-5 * math.sin(a)) for r, a in zip(t["radii"], angles)]
        pts.sort(key=lambda p: math.atan2(p[1], p[0]))
        circ = sum(math.dist(pts[i], pts[(i + 1) % n]) for i in range(n))
        xs, ys = [p[0] for p in pts], [p[1] for p in pts]
        cx, cy = (max(xs) + min(xs)) / 2.0, (max(ys) + min(ys)) / 2.0
        fed = 2.0 * max(math.hypot(x - cx, y - cy) for x, y in pts)
        side = {"R": 0, "L": 1}.get(t["eye"], 0)
        recs = {}
        for label, name in LABELS.items():
            fields = sizes.get(label)
            if fields and len(fields) == 1:
                fields = fields * 2  # no ';': both eyes' value
            if fields and len(fields) > side and fields[side].strip():
                recs[name] = float(fields[side]) * 1e-3
        out.append({
            "eye": t["eye"], "type": t["type"], "n": n,
            "circumference": circ, "box_width": max(xs) - min(xs), "box_height": max(ys) - min(ys),
            "effective_diameter": fed, "records": recs,
        })
    return {"traces": out}


if __name__ == "__main__":
    with open(sys.argv[1], "rb") as f:
        print(json.dumps(read(f.read().decode("latin-1"))))
