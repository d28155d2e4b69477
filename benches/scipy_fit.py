#!/usr/bin/env python3
"""Fit time of scipy.optimize.least_squares on a plate scan, for comparison with ours.

    python3 benches/scipy_fit.py target/bench/plate.csv [--repeats 200] [--ours-json FILE]

Run by scripts/bench_scipy.sh, which writes the scan with `tracer_calib simulate` and
runs our criterion benchmark in the same run. The scan is a CSV `step,counts` (one
revolution, counts of --meters-per-count metres). The truth (mounting errors, plate
centre, plate size) comes on the command line with the same defaults as
`tracer_calib simulate`.

The two models are numpy ports of ours, vectorised over the samples:

- full (crates/tracer_calib_engine/src/model/full.rs): x = [alpha0, d, dL, cx, cy], every raw sample,
  rho = t + dL with t the exit distance of the rail ray d v + t u from the rounded
  square (flats, and corner arcs of radius r), and the analytic Jacobian
  d rho/d alpha0 = -N.(t v - d u)/(N.u), d rho/d d = -N.v/(N.u), d rho/d dL = 1,
  d rho/d c = N/(N.u).
- paper (crates/tracer_calib_engine/src/model/paper.rs): x = [alpha0, d], residuals
  (g(a_k) - g(a_{k+1})) - (s_k - s_{k+1}) over neighbouring pairs of opposite sums
  s_k = rho_k + rho_{k+N/2}, g = S/|cos a| + 2 d tan a (x-sides) or
  S/|sin a| - 2 d cot a (y-sides); the sums are selected as ours does (both samples on
  opposite flats of one axis, at least min(1 mm, 5 % of the flat) from the arcs, by the
  full model), here at the TRUE parameters.

Start points as in benches/fit.rs: truth + [1 deg, 0.5 mm, -0.5 mm, 0.2 mm, 0.2 mm]
(full), truth + [1 deg, 0.5 mm] (paper). Each fit is timed `--repeats` times
(median, p90); the script checks every solution lies within a few standard errors of
the truth and prints one JSON line (medians, 90th percentiles and minima in µs,
evaluation counts, solutions).
"""

import argparse
import json
import math
import platform
import sys
import time

import numpy as np
import scipy
from scipy.optimize import least_squares

np.seterr(all="ignore")  # corner formulas are evaluated for every sample, then masked


def read_scan(path, meters_per_count):
    steps, counts = [], []
    with open(path) as f:
        header_seen = False
        for line in f:
            line = line.strip()
            if not line or line.startswith("#"):
                continue
            fields = [s.strip() for s in line.split(",")]
            if not header_seen:
                if fields != ["step", "counts"]:
                    sys.exit(f"{path}: expected the header line 'step,counts', got '{line}'")
                header_seen = True
                continue
            steps.append(int(fields[0]))
            counts.append(int(fields[1]))
    return np.array(steps, dtype=np.int64), np.array(counts, dtype=np.float64) * meters_per_count


class FullModel:
    """crates/tracer_calib_engine/src/model/full.rs, vectorised."""

    def __init__(self, steps, rho, n, side, radius):
        phi = 2.0 * math.pi * steps.astype(np.float64) / n
        self.cphi, self.sphi = np.cos(phi), np.sin(phi)
        self.rho = rho
        self.h = side / 2.0
        self.r = radius
        self.inner = self.h - radius
        self._x = None
        self._jac = None

    def residuals_and_jacobian(self, x):
        alpha, d, dl, cx, cy = x
        c_a, s_a = math.cos(alpha), math.sin(alpha)
        # Rail directions: the step table rotated by alpha0 (geometry::rotate).
        ca = c_a * self.cphi - s_a * self.sphi
        sa = s_a * self.cphi + c_a * self.sphi
        # p = d v - c, v = (-sa, ca)
        px = -d * sa - cx
        py = d * ca - cy
        sx = np.copysign(1.0, ca)
        sy = np.copysign(1.0, sa)
        ax, ay = np.abs(ca), np.abs(sa)
        h, inner, r = self.h, self.inner, self.r
        wx = h - sx * px
        wy = h - sy * py
        on_x = wx * ay <= wy * ax
        # The wall the ray reaches first, and its normal N = (nx, ny).
        t = np.where(on_x, wx / ax, wy / ay)
        qx = px + t * ca
        qy = py + t * sa
        flat = np.where(on_x, np.abs(qy) <= inner, np.abs(qx) <= inner)
        nx = np.where(on_x, sx, 0.0)
        ny = np.where(on_x, 0.0, sy)
        if not flat.all():
            # Corner arcs (shape::RoundedRect::exit_local): the far intersection with the
            # circle of radius r about the corner centre k of the box exit's quadrant.
            kx = np.where(qx < 0.0, -inner, inner)
            ky = np.where(qy < 0.0, -inner, inner)
            wcx, wcy = px - kx, py - ky
            b = wcx * ca + wcy * sa
            disc = b * b - (wcx * wcx + wcy * wcy) + r * r
            tc = -b + np.sqrt(disc)
            corner = ~flat
            if (disc[corner] < 0.0).any():
                return None, None
            t = np.where(flat, t, tc)
            nx = np.where(flat, nx, (wcx + ca * tc) / r)
            ny = np.where(flat, ny, (wcy + sa * tc) / r)
        nu = nx * ca + ny * sa
        if (t <= 0.0).any() or (nu <= 1e-12).any():
            return None, None
        inv = 1.0 / nu
        # N.v with v = (-sa, ca); N.(t v - d u)
        nv = -nx * sa + ny * ca
        jac = np.empty((t.size, 5))
        jac[:, 0] = -(t * nv - d * nu) * inv
        jac[:, 1] = -nv * inv
        jac[:, 2] = 1.0
        jac[:, 3] = nx * inv
        jac[:, 4] = ny * inv
        return t + dl - self.rho, jac

    # scipy calls fun(x) and then jac(x) at the same x: the Jacobian of the last
    # residual evaluation is kept (as our crate adapter caches its hit).
    def fun(self, x):
        res, jac = self.residuals_and_jacobian(x)
        if res is None:
            return np.full(self.rho.size, 1e10)
        self._x = x.copy()
        self._jac = jac
        return res

    def jac(self, x):
        if self._x is not None and np.array_equal(x, self._x):
            return self._jac
        return self.residuals_and_jacobian(x)[1]

    def part_at(self, x, margin):
        """Per sample: 'X' or 'Y' if it lies on that axis's flats at least `margin`
        from the arcs (paper.rs PaperModel::select), else None."""
        alpha, d, _, cx, cy = x
        a = alpha + np.arctan2(self.sphi, self.cphi)
        ca, sa = np.cos(a), np.sin(a)
        px, py = -d * sa - cx, d * ca - cy
        with np.errstate(divide="ignore"):
            tx = np.where(ca > 0, (self.h - px) / ca, np.where(ca < 0, (-self.h - px) / ca, np.inf))
            ty = np.where(sa > 0, (self.h - py) / sa, np.where(sa < 0, (-self.h - py) / sa, np.inf))
        on_x = tx <= ty
        t = np.where(on_x, tx, ty)
        qx, qy = px + t * ca, py + t * sa
        limit = self.inner - margin
        axis = np.full(t.size, None, dtype=object)
        axis[on_x & (np.abs(qy) <= limit)] = "X"
        axis[~on_x & (np.abs(qx) <= limit)] = "Y"
        return axis


class PaperModel:
    """crates/tracer_calib_engine/src/model/paper.rs, vectorised."""

    def __init__(self, steps, rho, n, side, axis_of):
        assert n % 2 == 0
        half = n // 2
        index_of = {int(s): i for i, s in enumerate(steps)}
        sums = {}  # step k < N/2 -> (phi, axis, sum, [i, j])
        for k in range(half):
            i, j = index_of.get(k), index_of.get(k + half)
            if i is None or j is None:
                continue
            if axis_of[i] is None or axis_of[i] != axis_of[j]:
                continue
            sums[k] = (2.0 * math.pi * k / n, axis_of[i], rho[i] + rho[j], (i, j))
        pairs = [(k, k + 1) for k in range(half - 1) if k in sums and k + 1 in sums and sums[k][1] == sums[k + 1][1]]
        if len(pairs) < 4:
            sys.exit(f"only {len(pairs)} usable neighbouring pairs of opposite samples")
        self.side = side
        self.n_samples = len(rho)
        self.sums = sums
        self.pairs = pairs
        p = [sums[a] for a, _ in pairs]
        q = [sums[b] for _, b in pairs]
        self.phi_p = np.array([s[0] for s in p])
        self.phi_q = np.array([s[0] for s in q])
        # Neighbouring sums are on the same axis.
        self.is_x = np.array([s[1] == "X" for s in p])
        self.y = np.array([s[2] for s in p]) - np.array([s[2] for s in q])
        self.samples_p = [s[3] for s in p]
        self.samples_q = [s[3] for s in q]
        self._x = None
        self._jac = None

    def _g(self, a, d):
        """sum_model: g(a) and (dg/da, dg/dd), both axes, selected per pair."""
        s, c = np.sin(a), np.cos(a)
        S = self.side
        sec, csc = 1.0 / c, 1.0 / s
        sgn_c = np.where(c < 0.0, -1.0, 1.0)  # f64::signum: +0 -> +1
        sgn_s = np.where(s < 0.0, -1.0, 1.0)
        gx = S * sgn_c * sec + 2.0 * d * s * sec
        gax = (S * sgn_c * s + 2.0 * d) * sec * sec
        gdx = 2.0 * s * sec
        gy = S * sgn_s * csc - 2.0 * d * c * csc
        gay = (-S * sgn_s * c + 2.0 * d) * csc * csc
        gdy = -2.0 * c * csc
        m = self.is_x
        return np.where(m, gx, gy), np.where(m, gax, gay), np.where(m, gdx, gdy)

    def residuals_and_jacobian(self, x):
        alpha, d = x
        gp, gap, gdp = self._g(alpha + self.phi_p, d)
        gq, gaq, gdq = self._g(alpha + self.phi_q, d)
        res = (gp - gq) - self.y
        jac = np.empty((res.size, 2))
        jac[:, 0] = gap - gaq
        jac[:, 1] = gdp - gdq
        return res, jac

    def fun(self, x):
        res, jac = self.residuals_and_jacobian(x)
        self._x = x.copy()
        self._jac = jac
        return res

    def jac(self, x):
        if self._x is not None and np.array_equal(x, self._x):
            return self._jac
        return self.residuals_and_jacobian(x)[1]

    def covariance(self, x, sigma2):
        """Covariance of [alpha0, d] by propagation from the raw samples (the pair
        residuals are correlated): G = (J'J)^-1 J' B, cov = sigma2 G G'."""
        _, jac = self.residuals_and_jacobian(x)
        b = np.zeros((len(self.pairs), self.n_samples))
        for row, (sp, sq) in enumerate(zip(self.samples_p, self.samples_q)):
            b[row, list(sp)] += 1.0
            b[row, list(sq)] -= 1.0
        g = np.linalg.solve(jac.T @ jac, jac.T @ b)
        return sigma2 * g @ g.T


def time_fit(fit, repeats):
    for _ in range(min(10, repeats)):  # warm-up
        fit()
    times = np.empty(repeats)
    for i in range(repeats):
        t0 = time.perf_counter_ns()
        fit()
        times[i] = time.perf_counter_ns() - t0
    return float(np.median(times)) / 1e3, float(np.percentile(times, 90)) / 1e3, float(times.min()) / 1e3


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("csv")
    ap.add_argument("--repeats", type=int, default=200)
    ap.add_argument("--alpha0-deg", type=float, default=2.0)
    ap.add_argument("--offset", type=float, default=0.005)
    ap.add_argument("--delta-l", type=float, default=0.002)
    ap.add_argument("--center-x", type=float, default=0.0008)
    ap.add_argument("--center-y", type=float, default=-0.0005)
    ap.add_argument("--plate-side", type=float, default=0.045)
    ap.add_argument("--corner-radius", type=float, default=0.003)
    ap.add_argument("--meters-per-count", type=float, default=1e-6)
    ap.add_argument("--steps-per-rev", type=int, default=400)
    ap.add_argument("--max-sigmas", type=float, default=4.0, help="allowed |solution - truth| in standard errors")
    ap.add_argument("--ours-json", help="output of `tracer_calib calibrate --json` on the same CSV, to compare")
    a = ap.parse_args()

    steps, rho = read_scan(a.csv, a.meters_per_count)
    n = a.steps_per_rev
    truth = np.array([math.radians(a.alpha0_deg), a.offset, a.delta_l, a.center_x, a.center_y])
    full = FullModel(steps, rho, n, a.plate_side, a.corner_radius)
    margin = min(1e-3, 0.05 * (a.plate_side / 2.0 - a.corner_radius))  # calibrate.rs fit_paper
    paper = PaperModel(steps, rho, n, a.plate_side, full.part_at(truth, margin))

    x0_full = truth + np.array([math.radians(1.0), 0.5e-3, -0.5e-3, 0.2e-3, 0.2e-3])
    x0_paper = x0_full[:2].copy()

    # Sanity: the Jacobians against central differences at the start.
    for model, x0, scale in ((full, x0_full, 1e-3), (paper, x0_paper, 1e-3)):
        _, jac = model.residuals_and_jacobian(x0)
        num = np.empty_like(jac)
        for j in range(x0.size):
            hstep = 1e-6 * max(abs(x0[j]), scale)
            xp, xm = x0.copy(), x0.copy()
            xp[j] += hstep
            xm[j] -= hstep
            num[:, j] = (model.residuals_and_jacobian(xp)[0] - model.residuals_and_jacobian(xm)[0]) / (2 * hstep)
        bad = int((np.abs(jac - num).max(axis=1) > 1e-6).sum())
        if bad > 2:
            sys.exit(f"{type(model).__name__}: analytic Jacobian differs from finite differences in {bad} rows")

    out = {
        "scan": a.csv,
        "samples": int(rho.size),
        "paper_pairs": len(paper.pairs),
        "paper_samples_used": 2 * len(paper.sums),
        "python": platform.python_version(),
        "numpy": np.__version__,
        "scipy": scipy.__version__,
        "repeats": a.repeats,
    }
    ok = True

    # One residual + Jacobian evaluation (the counterpart of our normal-equations pass).
    out["full_eval_us"] = time_fit(lambda: full.residuals_and_jacobian(x0_full), a.repeats * 5)[0]

    for name, model, x0 in (("full", full, x0_full), ("paper", paper, x0_paper)):
        for method in ("lm", "trf"):
            def fit(model=model, x0=x0, method=method):
                return least_squares(model.fun, x0, jac=model.jac, method=method, x_scale="jac")

            sol = fit()
            med, p90, fastest = time_fit(fit, a.repeats)
            key = f"{name}_{method}"
            out[f"{key}_median_us"] = round(med, 1)
            out[f"{key}_p90_us"] = round(p90, 1)
            out[f"{key}_min_us"] = round(fastest, 1)
            out[f"{key}_nfev"] = int(sol.nfev)
            out[f"{key}_njev"] = int(sol.njev) if sol.njev is not None else None
            out[f"{key}_status"] = int(sol.status)
            # Standard errors at the solution.
            res, jac = model.residuals_and_jacobian(sol.x)
            if name == "full":
                sigma2 = float(res @ res) / (res.size - 5)
                cov = sigma2 * np.linalg.inv(jac.T @ jac)
                out["sigma_hat_m"] = math.sqrt(sigma2)
            else:
                cov = paper.covariance(sol.x, out["sigma_hat_m"] ** 2)
            se = np.sqrt(np.diag(cov))
            z = (sol.x - truth[: sol.x.size]) / se
            out[f"{key}_x"] = [float(v) for v in sol.x]
            out[f"{key}_z"] = [round(float(v), 3) for v in z]
            if not sol.success or np.abs(z).max() > a.max_sigmas:
                ok = False
            if method == "lm":
                out[f"{name}_stderr"] = [float(v) for v in se]

    # The two scipy methods must agree with each other (same minimum).
    for name in ("full", "paper"):
        lm_x, trf_x = np.array(out[f"{name}_lm_x"]), np.array(out[f"{name}_trf_x"])
        out[f"{name}_lm_vs_trf_max_sigmas"] = float((np.abs(lm_x - trf_x) / np.array(out[f"{name}_stderr"])).max())

    if a.ours_json:
        for name, path in zip(("full", "paper"), a.ours_json.split(",")):
            with open(path) as f:
                ours = json.load(f)
            ox = np.array([ours["alpha0"], ours["offset"], ours["delta_l"]])[: 2 if name == "paper" else 3]
            sx = np.array(out[f"{name}_lm_x"])[: ox.size]
            dist = np.abs(ox - sx) / np.array(out[f"{name}_stderr"])[: ox.size]
            out[f"{name}_ours_vs_scipy_max_sigmas"] = float(dist.max())

    out["ok"] = ok
    print(json.dumps(out))
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
