#!/usr/bin/env python3
"""The table of scripts/bench_scipy.sh (step 5): medians and ratios of our fit, the
`levenberg-marquardt` crate and scipy, from what the earlier steps wrote to OUT.

    python benches/scipy_table.py OUT LOAD_BEFORE LOAD_AFTER

Reads OUT/criterion.txt (`cargo bench --bench fit`), OUT/ours_csv.json
(`examples/bench_scipy_ours.rs`) and OUT/scipy.json (`benches/scipy_fit.py`); prints
Markdown (the script keeps it as OUT/table.md). LOAD_BEFORE and LOAD_AFTER are the load
averages printed with it.
"""

import json
import re
import sys

out, load_before, load_after = sys.argv[1:4]
text = open(f"{out}/criterion.txt").read()
units = {"ps": 1e-6, "ns": 1e-3, "µs": 1.0, "us": 1.0, "ms": 1e3, "s": 1e6}
# criterion: "<name>  time:   [low unit median unit high unit]"; a long name stands on
# a line of its own, the times on the next.
medians, name = {}, None
for line in text.splitlines():
    if line and not line[0].isspace() and not line.startswith(("Benchmarking", "Found", "Warning", "ours:", "Gnuplot")):
        name = line.split("time:")[0].strip()
    t = re.search(r"time:\s*\[\s*\S+ \S+ (\S+) (\S+) \S+ \S+\]", line)
    if t and name:
        medians[name] = float(t.group(1)) * units[t.group(2)]
        name = None
bench_line = next((l for l in text.splitlines() if l.startswith("ours:")), "")
ours = json.load(open(f"{out}/ours_csv.json"))
s = json.load(open(f"{out}/scipy.json"))

def crit(prefix):
    for k, v in medians.items():
        if k.startswith(prefix):
            return v
    sys.exit(f"no criterion result for '{prefix}' in {out}/criterion.txt")

of, op = ours["full_us"], ours["paper_us"]
def cell(us, ref):
    return ("–", "") if us is None else (f"{us:.1f} µs", f"{us / ref:.1f}×")

rows = [
    ("ours, `lm::minimize`, on the CSV (median of 5000)",
     of, op, f"{ours['full_evaluations']} / {ours['paper_evaluations']} passes"),
    ("ours, criterion `fit/full_lm_400 (ours)` (bench's own scan)", crit("fit/full_lm_400 (ours)"), None, ""),
    ("`levenberg-marquardt` 0.15 crate, criterion (bench's own scan)",
     crit("fit/full_lm_400 (levenberg-marquardt crate)"), None, ""),
    ("scipy `least_squares(method='lm')` (MINPACK)", s["full_lm_median_us"], s["paper_lm_median_us"],
     f"{s['full_lm_nfev']} f + {s['full_lm_njev']} J / {s['paper_lm_nfev']} f + {s['paper_lm_njev']} J"),
    ("scipy `least_squares(method='trf')`", s["full_trf_median_us"], s["paper_trf_median_us"],
     f"{s['full_trf_nfev']} f + {s['full_trf_njev']} J / {s['paper_trf_nfev']} f + {s['paper_trf_njev']} J"),
]
print(f"Scan: {s['scan']} ({s['samples']} samples; paper model: {s['paper_samples_used']} samples, "
      f"{s['paper_pairs']} pairs). Python {s['python']}, numpy {s['numpy']}, scipy {s['scipy']}; "
      f"scipy: median of {s['repeats']} fits.")
print(f"Load average (1, 5, 15 min): {load_before} before criterion, {load_after} after scipy.")
print()
print("| fit from truth + (1°, 0.5 mm, ...) | full model | ratio | paper model | ratio | evaluations (full / paper) |")
print("|---|---|---|---|---|---|")
for label, f, p, ev in rows:
    fc, fr = cell(f, of)
    pc, pr = cell(p, op)
    print(f"| {label} | {fc} | {fr} | {pc} | {pr} | {ev} |")
mins = [("ours", ours["full_min_us"], ours["paper_min_us"])] + [
    (f"scipy {m}", s[f"full_{m}_min_us"], s[f"paper_{m}_min_us"]) for m in ("lm", "trf")]
print()
print("Fastest single fit (less sensitive to the load): " + "; ".join(
    f"{n} {f:.1f} µs full ({f / ours['full_min_us']:.1f}×), {p:.1f} µs paper ({p / ours['paper_min_us']:.1f}×)"
    for n, f, p in mins) + ".")
print()
print("| other | median |")
print("|---|---|")
print(f"| whole calibration, ours, full model (start search + fit + outlier test), criterion | {crit('calibrate/full_400'):.1f} µs |")
print(f"| whole calibration, ours, paper model, criterion | {crit('calibrate/paper_400'):.1f} µs |")
print(f"| one residual + normal-equations pass, ours (full model), criterion | {crit('fit/normal_equations_pass_400'):.1f} µs |")
print(f"| one residual + Jacobian evaluation, numpy (full model) | {s['full_eval_us']:.1f} µs |")
print()
print(f"Same data: the CSV is benches/fit.rs's scan rounded to 1 µm counts "
      f"({'checked' if ours['bench_scan_rounded_equals_csv'] and ours['bench_scan_same_steps'] else 'CHECK FAILED'}: "
      f"max |Δrho| {ours['bench_scan_max_abs_diff_m'] * 1e6:.2f} µm); our full fit on the bench's scan "
      f"{ours['full_us_on_bench_scan']:.1f} µs. Criterion: {bench_line}")
print(f"Solutions: scipy vs truth in standard errors, full lm {s['full_lm_z']}, paper lm {s['paper_lm_z']}; "
      f"scipy vs `tracer_calib calibrate` on the CSV: full {s['full_ours_vs_scipy_max_sigmas']:.1e} σ, "
      f"paper {s['paper_ours_vs_scipy_max_sigmas']:.1e} σ (max over parameters); "
      f"checks {'passed' if s['ok'] else 'FAILED'}.")
dist = lambda a, b, se: max(abs(x - y) / e for x, y, e in zip(a, b, se))
print(f"Our fits on the CSV vs scipy lm: full {dist(ours['full_x'], s['full_lm_x'], s['full_stderr']):.1e} σ, "
      f"paper {dist(ours['paper_x'], s['paper_lm_x'], s['paper_stderr']):.1e} σ (max over parameters).")
