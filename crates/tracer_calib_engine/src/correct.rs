//! Contour correction: every raw sample to the point the probe really touched, and the
//! contour resampled at equal angles about the rotation axis.
//!
//! A sample at step `k` with encoder length `rho` touched
//! `P = (k_s rho - dL) u + d v` (`k_s` the encoder scale) with `u, v` at rail angle
//! `alpha0 + φ + ε(φ)`, `φ = 2π k/N` (`ε` the turntable's angle error, [`super::angle`])
//! ([`super::geometry::probe_point`]). [`Corrector`] keeps the rotated table of rail
//! directions for one `N`, so a scan costs four multiply-adds a sample.
//!
//! **Resampling** ([`resample_radii`], or [`PolarContour`] fed point by point as the
//! points are computed): the corrected points, sorted by polar angle
//! `θ_i` about the axis, define a star-shaped closed contour `r(θ)`. `r` is
//! interpolated by a periodic cubic Hermite spline whose slopes are the three-point
//! (non-uniform) finite differences, `O(h³)` accurate for a smooth contour, and read at
//! `θ_k = 2π k / M`. If the largest angular gap between neighbouring points exceeds
//! `max_gap` the scan does not go all the way round and there are no radii. A point's
//! polar angle comes from its neighbour's when that is within 3.6° (`next_angle`:
//! the small angle between them, one division), else from a table and a short series
//! (`polar_angle`); both agree with `atan2` to a few 1e-15 rad.

use nalgebra::Vector2;
use std::f64::consts::TAU;

use super::angle::AngleError;
use super::geometry::{Mounting, rotate, step_angle};
use super::scan::{Scan, counts_to_samples};

/// Corrects scans of one `steps_per_rev` with one mounting.
#[derive(Debug, Clone)]
pub struct Corrector {
    mounting: Mounting,
    angle: AngleError,
    steps_per_rev: u32,
    /// `(cos, sin)` of `alpha0 + 2π k/N` for every step, when `N` is reasonable.
    table: Option<Vec<(f64, f64)>>,
}

/// Largest `N` for which a direction table is kept (8 MiB at 16 bytes a step).
const MAX_TABLE: u32 = 1 << 19;

impl Corrector {
    /// A corrector of a turntable with no angle error.
    pub fn new(mounting: Mounting, steps_per_rev: u32) -> Self {
        Self::with_angle(mounting, &AngleError::NONE, steps_per_rev)
    }

    /// A corrector of a turntable whose angle is off by `angle`.
    pub fn with_angle(mounting: Mounting, angle: &AngleError, steps_per_rev: u32) -> Self {
        let table = (steps_per_rev > 0 && steps_per_rev <= MAX_TABLE).then(|| {
            let cs_alpha = (mounting.alpha0.cos(), mounting.alpha0.sin());
            (0..steps_per_rev)
                .map(|k| {
                    let phi = step_angle(k, steps_per_rev);
                    let (s, c) = (phi + angle.at(phi)).sin_cos();
                    rotate((c, s), cs_alpha)
                })
                .collect()
        });
        Corrector { mounting, angle: angle.clone(), steps_per_rev, table }
    }

    pub fn mounting(&self) -> &Mounting {
        &self.mounting
    }

    pub fn angle(&self) -> &AngleError {
        &self.angle
    }

    pub fn steps_per_rev(&self) -> u32 {
        self.steps_per_rev
    }

    /// `(cos a, sin a)` of the rail angle at `step`.
    #[inline]
    fn rail(&self, step: u32) -> (f64, f64) {
        match &self.table {
            Some(t) => t[step as usize],
            None => {
                let phi = step_angle(step, self.steps_per_rev);
                let (s, c) = (self.mounting.alpha0 + phi + self.angle.at(phi)).sin_cos();
                (c, s)
            }
        }
    }

    /// The touched point of one sample: `P = (k rho - dL) u + d v`.
    #[inline]
    pub fn point(&self, step: u32, rho: f64) -> Vector2<f64> {
        let (c, s) = self.rail(step);
        let t = self.mounting.rail_length(rho);
        let d = self.mounting.offset;
        Vector2::new(t * c - d * s, t * s + d * c)
    }

    /// Correct encoder counts straight from the arrays, `rho = counts × meters_per_count`,
    /// handing each point to `emit` in sample order: for a caller that wants the points
    /// in a form of its own, without a [`Scan`] or an array of points in between. The
    /// arrays must pass [`Scan::check_counts`] for this corrector's `steps_per_rev` (a
    /// step outside the revolution panics).
    #[inline]
    pub fn correct_counts(
        &self,
        steps: &[u32],
        counts: &[i32],
        meters_per_count: f64,
        mut emit: impl FnMut(Vector2<f64>),
    ) {
        for s in counts_to_samples(steps, counts, meters_per_count) {
            emit(self.point(s.step, s.rho));
        }
    }

    /// Every sample of `scan` corrected, in sample order. The scan must have this
    /// corrector's `steps_per_rev`.
    pub fn correct(&self, scan: &Scan) -> Vec<Vector2<f64>> {
        assert_eq!(scan.steps_per_rev(), self.steps_per_rev, "corrector built for another steps_per_rev");
        scan.samples().iter().map(|s| self.point(s.step, s.rho)).collect()
    }
}

/// Correct a scan with a mounting (builds a [`Corrector`] for it).
pub fn correct(scan: &Scan, mounting: &Mounting) -> Vec<Vector2<f64>> {
    Corrector::new(*mounting, scan.steps_per_rev()).correct(scan)
}

/// The contour `points` resampled to `m` radii at angles `2π k/m` about the origin,
/// or `None` if it does not go all the way round (an angular gap above `max_gap`),
/// has fewer than 3 points, or `m` is 0. ([`PolarContour`] point by point, then
/// [`PolarContour::resample`].)
pub fn resample_radii(points: &[Vector2<f64>], m: usize, max_gap: f64) -> Option<Vec<f64>> {
    polar_of(points).resample(m, max_gap)
}

/// [`resample_radii`] with each radius' noise gain ([`PolarContour::resample_with_gain`]).
pub fn resample_radii_with_gain(points: &[Vector2<f64>], m: usize, max_gap: f64) -> Option<(Vec<f64>, Vec<f64>)> {
    polar_of(points).resample_with_gain(m, max_gap)
}

/// Values `v_i` known at angles `θ_i` (in `[0, 2π)`, any order; a contour's points' own)
/// at `m` equal angles `2π k/m`, by [`PolarContour::resample`]'s cubic, no gap checked and
/// none clamped (a value may be negative). `None` as there.
pub fn resample_values(knots: impl IntoIterator<Item = (f64, f64)>, m: usize) -> Option<Vec<f64>> {
    let mut polar = PolarContour::with_capacity(0);
    polar.knots.extend(knots);
    polar.resample_into(m, f64::INFINITY, None, false)
}

/// `points` as a [`PolarContour`].
fn polar_of(points: &[Vector2<f64>]) -> PolarContour {
    let mut polar = PolarContour::with_capacity(points.len());
    for p in points {
        polar.push(*p);
    }
    polar
}

/// Knots of padding on each side of the points in [`PolarContour`]: the last two
/// points one turn back before the first, the first two one turn on after the last.
const PAD: usize = 2;

/// A closed contour in polar form about the axis, `(θ_i, r_i)` with `θ` in `[0, 2π)`,
/// built point by point (so that a caller producing the points, as the node does while
/// correcting a scan, needs no array of them): the input of [`Self::resample`].
#[derive(Debug, Clone)]
pub struct PolarContour {
    /// `PAD` free slots, then the points in the order pushed.
    knots: Vec<(f64, f64)>,
    /// The last point pushed and its angle, for [`next_angle`].
    prev: Option<(Vector2<f64>, f64)>,
    /// Angles carried on from a neighbour's since the last one computed afresh.
    carried: u32,
}

impl PolarContour {
    /// Room for `n` points (and the padding: no regrowth).
    pub fn with_capacity(n: usize) -> Self {
        let mut knots = Vec::with_capacity(n + 2 * PAD);
        knots.extend([(0.0, 0.0); PAD]);
        PolarContour { knots, prev: None, carried: 0 }
    }

    /// Add the next point. A point at the axis (or not finite) has no direction and is
    /// left out.
    ///
    /// Always inlined: called for each point as it is computed, it would otherwise load
    /// the point from the two 8-byte stores the caller just made with one 16-byte load,
    /// which the CPU cannot forward from the stores (a stall for every point; the root
    /// package's BENCHMARKS.md, "Figures behind choices in the code", says how much).
    #[inline(always)]
    pub fn push(&mut self, p: Vector2<f64>) {
        let r2 = p.x * p.x + p.y * p.y;
        if !(r2 > 0.0 && r2.is_finite()) {
            return;
        }
        let theta = match self.prev.and_then(|(q, tq)| next_angle(q, tq, &p)) {
            Some(t) if self.carried < EXACT_ANGLE_EVERY => {
                self.carried += 1;
                t
            }
            _ => {
                self.carried = 0;
                polar_angle(p.y, p.x)
            }
        };
        self.prev = Some((p, theta));
        self.knots.push((theta, r2.sqrt()));
    }

    /// How many points it has (those left out not counted).
    pub fn len(&self) -> usize {
        self.knots.len() - PAD
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The radii at `θ_k = 2π k / m`, k = 0..m, or `None` if there are fewer than 3
    /// points, `m` is 0, or the largest angular gap between neighbours exceeds `max_gap`.
    ///
    /// Points at the same angle (within 1e-12 rad) are merged, their radii averaged.
    /// Between knots `i` and `i + 1` (widths `h_i = θ_{i+1} - θ_i`, secants
    /// `d_i = (r_{i+1} - r_i) / h_i`) `r` is the cubic Hermite
    /// `r(θ_i + s h_i) = r_i + s m_0 + s² (3Δ - 2m_0 - m_1) + s³ (m_0 + m_1 - 2Δ)`,
    /// `Δ = r_{i+1} - r_i`, `m_0 = S_i h_i`, `m_1 = S_{i+1} h_i`, with the three-point
    /// slopes `S_i = (h_i d_{i-1} + h_{i-1} d_i) / (h_{i-1} + h_i)`. The walk keeps the
    /// secants of three segments as it goes: two divisions a knot.
    pub fn resample(self, m: usize, max_gap: f64) -> Option<Vec<f64>> {
        self.resample_into(m, max_gap, None, true)
    }

    /// [`Self::resample`], and each radius' noise gain: the variance it gets per unit
    /// variance of the points' radii (independent), `Σ w²` over its interpolation weights.
    /// With equal knot widths the cubic's slopes are `m_0 = (r_{i+1} - r_{i-1})/2`,
    /// `m_1 = (r_{i+2} - r_i)/2`, so with the Hermite basis `h_00, h_10, h_01, h_11` at `s`
    /// the weights on `r_{i-1}, r_i, r_{i+1}, r_{i+2}` are `-h_10/2`, `h_00 - h_11/2`,
    /// `h_01 + h_10/2`, `h_11/2`: a gain of 1 at a knot, 0.64 half-way (a scan's knots are
    /// equal to within the mounting's small distortion; that is the gain taken).
    pub fn resample_with_gain(self, m: usize, max_gap: f64) -> Option<(Vec<f64>, Vec<f64>)> {
        let mut gain = Vec::with_capacity(m);
        let radii = self.resample_into(m, max_gap, Some(&mut gain), true)?;
        Some((radii, gain))
    }

    /// `clamp`: a radius is a distance, never below 0 (false for other values).
    fn resample_into(self, m: usize, max_gap: f64, mut gain: Option<&mut Vec<f64>>, clamp: bool) -> Option<Vec<f64>> {
        if m == 0 || self.len() < 3 {
            return None;
        }
        let mut knots = self.knots;
        let n = order_and_merge(&mut knots[PAD..]);
        if n < 3 {
            return None;
        }
        knots.truncate(PAD + n);
        let (first, second, last, before_last) = (knots[PAD], knots[PAD + 1], knots[PAD + n - 1], knots[PAD + n - 2]);
        knots[0] = (before_last.0 - TAU, before_last.1);
        knots[1] = (last.0 - TAU, last.1);
        knots.push((first.0 + TAU, first.1));
        knots.push((second.0 + TAU, second.1));
        // Every gap, the one across angle 0 included (knots 1..=n+2).
        let widest = knots[1..PAD + n + 1].windows(2).map(|w| w[1].0 - w[0].0).fold(0.0, f64::max);
        if widest > max_gap {
            return None;
        }

        // Segment j runs from knot j to knot j + 1: its width, 1/width and secant.
        let segment = |j: usize| {
            let ((t0, r0), (t1, r1)) = (knots[j], knots[j + 1]);
            let h = t1 - t0;
            let inv = 1.0 / h;
            (h, inv, (r1 - r0) * inv)
        };
        let slope = |(h0, _, d0): (f64, f64, f64), (h1, _, d1): (f64, f64, f64)| (h1 * d0 + h0 * d1) / (h0 + h1);
        // Targets and segments are both sorted by angle: walk them together. Knot 1 (the
        // last point one turn back) starts the segment that holds angle 0.
        let mut seg = 1;
        let (mut this, mut next) = (segment(1), segment(2));
        let (mut s0, mut s1) = (slope(segment(0), this), slope(this, next));
        let mut out = Vec::with_capacity(m);
        let dphi = TAU / m as f64;
        for k in 0..m {
            let phi = k as f64 * dphi;
            while knots[seg + 1].0 < phi {
                seg += 1;
                (this, next) = (next, segment(seg + 1));
                (s0, s1) = (s1, slope(this, next));
            }
            let ((t0, r0), (_, r1)) = (knots[seg], knots[seg + 1]);
            let (h, inv, _) = this;
            let s = ((phi - t0) * inv).clamp(0.0, 1.0);
            let (m0, m1, delta) = (s0 * h, s1 * h, r1 - r0);
            let r = r0 + s * (m0 + s * ((3.0 * delta - 2.0 * m0 - m1) + s * (m0 + m1 - 2.0 * delta)));
            // Between a point near the axis and a far one the cubic can dip below zero; a
            // radius is a distance, and the contour there is at the axis.
            out.push(if clamp && r < 0.0 { 0.0 } else { r });
            if let Some(gain) = gain.as_deref_mut() {
                gain.push(noise_gain(s));
            }
        }
        Some(out)
    }
}

/// [`PolarContour::resample_with_gain`]'s gain at `s` between two knots.
fn noise_gain(s: f64) -> f64 {
    let (s2, s3) = (s * s, s * s * s);
    let (h00, h10, h01, h11) = (2.0 * s3 - 3.0 * s2 + 1.0, s3 - 2.0 * s2 + s, 3.0 * s2 - 2.0 * s3, s3 - s2);
    [-h10 / 2.0, h00 - h11 / 2.0, h01 + h10 / 2.0, h11 / 2.0].iter().map(|w| w * w).sum()
}

/// Sort `(angle, radius)` pairs by angle and merge those at the same angle (within
/// 1e-12 rad, across 2π too), averaging their radii, in place; returns how many are
/// left (at the front).
///
/// A scan traced in step order is sorted already but for where it crosses angle 0: one
/// pass finds that, a rotation mends it; anything else is sorted.
fn order_and_merge(polar: &mut [(f64, f64)]) -> usize {
    let mut descents = polar.windows(2).enumerate().filter(|(_, w)| w[1].0 < w[0].0).map(|(i, _)| i + 1);
    match (descents.next(), descents.next()) {
        (None, _) => {}
        (Some(cut), None) if polar[polar.len() - 1].0 <= polar[0].0 => polar.rotate_left(cut),
        _ => polar.sort_by(|a, b| a.0.total_cmp(&b.0)),
    }
    let mut kept = 0;
    for i in 1..polar.len() {
        if polar[i].0 - polar[kept].0 < 1e-12 {
            polar[kept].1 = 0.5 * (polar[kept].1 + polar[i].1);
        } else {
            kept += 1;
            polar[kept] = polar[i];
        }
    }
    let mut n = kept + 1;
    // Across the wrap: a tiny negative angle shifted by 2π is `TAU` itself, the same
    // direction as angle 0 (else a zero-width segment: infinite slopes).
    if n > 1 && polar[0].0 + TAU - polar[n - 1].0 < 1e-12 {
        polar[0].1 = 0.5 * (polar[0].1 + polar[n - 1].1);
        n -= 1;
    }
    n
}

/// How many polar angles in a row [`next_angle`] may carry on from its neighbour's
/// before one is computed afresh (the drift over a run stays under 4e-15 rad, tested).
const EXACT_ANGLE_EVERY: u32 = 16;

/// The polar angle of `p` in `[0, 2π)` from that of a close neighbour `q` (angle `tq`):
/// `tq + atan u`, `u = (q × p) / (q · p)`, the tangent of the angle from `q` to `p`,
/// or `None` if `p` is not within `atan(1/16)` ≈ 3.6° of `q`'s direction.
///
/// Neighbouring samples of a scan are about one step (0.9° at 400 steps) apart, so this
/// is the common case: one division and the series `u - u³/3 + … - u¹³/13`, which leaves
/// out less than `u¹⁵/15 < 1e-19`, where [`polar_angle`] takes two divisions and a
/// table. The series is evaluated by Estrin's scheme (`u⁴`, `u⁸` and the pairs of terms
/// at once) rather than Horner's six dependent steps, which wait on each other
/// (BENCHMARKS.md, "Figures behind choices in the code").
#[inline]
fn next_angle(q: Vector2<f64>, tq: f64, p: &Vector2<f64>) -> Option<f64> {
    let (cross, dot) = (q.x * p.y - q.y * p.x, q.x * p.x + q.y * p.y);
    if !(dot > 0.0 && cross.abs() <= dot * (1.0 / 16.0)) {
        return None;
    }
    let u = cross / dot;
    let u2 = u * u;
    let u4 = u2 * u2;
    let u8 = u4 * u4;
    let low = (1.0 - u2 * (1.0 / 3.0)) + u4 * (1.0 / 5.0 - u2 * (1.0 / 7.0));
    let high = (1.0 / 9.0 - u2 * (1.0 / 11.0)) + u4 * (1.0 / 13.0);
    let t = tq + u * (low + u8 * high);
    Some(wrap_angle(t))
}

/// An angle a little outside `[0, 2π)` brought in (an angle just below 0 whose `+ 2π`
/// rounds to `2π` is 0).
#[inline]
fn wrap_angle(t: f64) -> f64 {
    if t >= TAU {
        t - TAU
    } else if t < 0.0 {
        let w = t + TAU;
        if w < TAU { w } else { 0.0 }
    } else {
        t
    }
}

/// `atan(k/8)`, k = 0..=8: the table of [`polar_angle`].
const ATAN_EIGHTHS: [f64; 9] = [
    0.0,
    0.12435499454676144,
    0.24497866312686414,
    0.35877067027057225,
    0.4636476090008061,
    0.5585993153435624,
    0.6435011087932844,
    0.7188299996216245,
    std::f64::consts::FRAC_PI_4,
];

/// The polar angle of `(x, y)` in `[0, 2π)`: `atan2(y, x)` to within a few ulp
/// (≤ 1e-15 rad, tested against `f64::atan2`), with a small table and no library call.
///
/// By symmetry it is enough to know `atan t` for `t = min(|x|,|y|) / max(|x|,|y|)` in
/// `[0, 1]`. With `c = k/8` the nearest eighth, `atan t = atan c + atan u`,
/// `u = (t - c) / (1 + t c)`, `|u| ≤ 1/16`, and the series
/// `atan u = u - u³/3 + u⁵/5 - … - u¹⁵/15` leaves out less than `u¹⁷/17 < 1e-21`.
/// Then `π/2 - a` if `|y| > |x|`, `π - a` if `x < 0`, `2π - a` if `y < 0`.
///
/// Why not `f64::atan2`: the resampler calls this for every sample of every scan, and
/// in the node, where other processes evict the caches between scans, libm's atan2 and
/// its tables cost more than this small function (BENCHMARKS.md, "Figures behind choices
/// in the code").
pub(crate) fn polar_angle(y: f64, x: f64) -> f64 {
    let (ax, ay) = (x.abs(), y.abs());
    let (num, den) = if ay > ax { (ax, ay) } else { (ay, ax) };
    if !(den > 0.0 && den.is_finite()) {
        // (0, 0), infinities, NaN: the library's conventions.
        return wrap_angle(y.atan2(x));
    }
    // u = (t - c) / (1 + t c) = (num - c den) / (den + c num).
    // The nearest eighth (t ≥ 0: truncation of t·8 + ½; `round` is a library call on
    // baseline x86-64).
    let k = (num / den * 8.0 + 0.5) as usize;
    let c = k as f64 * 0.125;
    let u = (num - c * den) / (den + c * num);
    let u2 = u * u;
    let series = u
        * (1.0
            - u2 * (1.0 / 3.0
                - u2 * (1.0 / 5.0
                    - u2 * (1.0 / 7.0
                        - u2 * (1.0 / 9.0 - u2 * (1.0 / 11.0 - u2 * (1.0 / 13.0 - u2 * (1.0 / 15.0))))))));
    let mut a = ATAN_EIGHTHS[k] + series;
    if ay > ax {
        a = std::f64::consts::FRAC_PI_2 - a;
    }
    if x < 0.0 {
        a = std::f64::consts::PI - a;
    }
    if y < 0.0 && a > 0.0 { wrap_angle(-a) } else { a }
}

/// The default largest angular gap for [`resample_radii`]: ten steps of the scan's
/// revolution, never less than 5° and never more than 90° (with very coarse steps, ten
/// of them would be more than a turn: a scan missing most of its contour would still
/// get radii).
pub fn default_max_gap(steps_per_rev: u32) -> f64 {
    (10.0 * TAU / f64::from(steps_per_rev.max(1))).clamp(5f64.to_radians(), TAU / 4.0)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::probe_point;
    use crate::shape::{Ellipse, Shape};
    use approx::assert_relative_eq;

    /// The reference: libm's `atan2`, shifted from (-π, π] to [0, 2π].
    fn std_angle(y: f64, x: f64) -> f64 {
        let a = y.atan2(x);
        if a < 0.0 { a + TAU } else { a }
    }

    #[test]
    fn a_radius_noise_gain_is_its_weights_squares() {
        // At a knot the radius is the sample; half-way the cubic averages four of them.
        assert!((noise_gain(0.0) - 1.0).abs() < 1e-15 && (noise_gain(1.0) - 1.0).abs() < 1e-15);
        assert!((noise_gain(0.5) - 0.640625).abs() < 1e-15, "{}", noise_gain(0.5));
        // What the resampler reports: the gain of each radius by its place between samples.
        let pts: Vec<Vector2<f64>> =
            (0..8).map(|k| Vector2::new((TAU * k as f64 / 8.0).cos(), (TAU * k as f64 / 8.0).sin())).collect();
        let (_, gain) = resample_radii_with_gain(&pts, 16, 1.0).unwrap();
        for (k, g) in gain.iter().enumerate() {
            let want = if k % 2 == 0 { 1.0 } else { 0.640625 };
            assert!((g - want).abs() < 1e-9, "radius {k}: {g}");
        }
    }

    #[test]
    fn polar_angle_is_atan2_in_zero_to_two_pi() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand::rngs::StdRng::seed_from_u64(7);
        let mut worst = 0.0f64;
        for _ in 0..200_000 {
            let (x, y) = (rng.random_range(-1.0..1.0) * 0.05, rng.random_range(-1.0..1.0) * 0.05);
            let (ours, lib) = (polar_angle(y, x), std_angle(y, x));
            assert!((0.0..TAU).contains(&ours), "({x}, {y}): {ours}");
            // Across the cut at angle 0 the two may land on either side of 2π.
            let diff = (ours - lib).abs();
            worst = worst.max(diff.min(TAU - diff));
        }
        assert!(worst <= 1e-15, "largest difference from atan2: {worst:e} rad");
        // The axes, the diagonals, the table's eighths, and the special values.
        for (y, x) in [(0.0, 1.0), (1.0, 0.0), (0.0, -1.0), (-1.0, 0.0), (1.0, 1.0), (-1.0, -1.0), (0.375, 1.0)] {
            assert!((polar_angle(y, x) - std_angle(y, x)).abs() <= 1e-15, "({x}, {y})");
        }
        // Tiny and huge magnitudes.
        for scale in [1e-300, 1e-40, 1e40, 1e300] {
            for (y, x) in [(0.3, 1.0), (-1.0, 0.7), (0.9, -0.2)] {
                let (y, x) = (y * scale, x * scale);
                assert!((polar_angle(y, x) - std_angle(y, x)).abs() <= 1e-15, "({x:e}, {y:e})");
            }
        }
        assert_eq!(polar_angle(0.0, 0.0), 0.0);
        assert!(polar_angle(f64::NAN, 1.0).is_nan());
        assert_eq!(polar_angle(1.0, f64::INFINITY), 0.0);
    }

    #[test]
    fn next_angle_follows_atan2_along_a_contour() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand::rngs::StdRng::seed_from_u64(8);
        let mut worst = 0.0f64;
        for _ in 0..2000 {
            // A run of EXACT_ANGLE_EVERY steps of about 0.9° on a noisy contour, from an
            // exact start, in either direction, across angle 0 too.
            let mut phi = rng.random_range(0.0..TAU);
            let step = if rng.random_bool(0.5) { TAU / 400.0 } else { -TAU / 400.0 };
            let at = |phi: f64, rng: &mut rand::rngs::StdRng| {
                let r = 0.025 + rng.random_range(-1e-3..1e-3);
                Vector2::new(r * phi.cos(), r * phi.sin())
            };
            let mut q = at(phi, &mut rng);
            let mut tq = polar_angle(q.y, q.x);
            for _ in 0..EXACT_ANGLE_EVERY {
                phi += step;
                let p = at(phi, &mut rng);
                tq = next_angle(q, tq, &p).expect("a neighbour 0.9° away");
                assert!((0.0..TAU).contains(&tq));
                let diff = (tq - std_angle(p.y, p.x)).abs();
                worst = worst.max(diff.min(TAU - diff));
                q = p;
            }
        }
        assert!(worst <= 4e-15, "largest drift from atan2 over a run: {worst:e} rad");
        // Not a neighbour: too far, or the opposite way.
        let q = Vector2::new(1.0, 0.0);
        assert!(next_angle(q, 0.0, &Vector2::new(1.0, 0.07)).is_none());
        assert!(next_angle(q, 0.0, &Vector2::new(-1.0, 0.0)).is_none());
        assert_eq!(wrap_angle(-1e-300), 0.0);
        assert_eq!(wrap_angle(TAU), 0.0);
    }

    #[test]
    fn corrector_matches_the_geometry() {
        let m = Mounting::new(0.3, -0.004, 0.0015);
        let scan = Scan::new(400, &[7, 123, 399], &[0.02, 0.025, 0.03]).unwrap();
        let pts = correct(&scan, &m);
        for (p, s) in pts.iter().zip(scan.samples()) {
            let want = probe_point(s.rho, m.alpha0 + step_angle(s.step, 400), &m);
            assert_relative_eq!(*p, want, epsilon = 1e-15);
        }
        // Without a table (huge N) the same formula.
        let big = Corrector::new(m, u32::MAX);
        assert_relative_eq!(
            big.point(5, 0.02),
            probe_point(0.02, m.alpha0 + step_angle(5, u32::MAX), &m),
            epsilon = 1e-15
        );
    }

    fn ellipse_points(n: usize, skip: impl Fn(usize) -> bool) -> (Ellipse, Vec<Vector2<f64>>) {
        let e = Ellipse { center: Vector2::new(0.001, -0.0005), a: 0.025, b: 0.015, angle: 0.2 };
        let pts = (0..n)
            .filter(|&i| !skip(i))
            .map(|i| {
                let a = TAU * i as f64 / n as f64 + 0.37;
                let u = Vector2::new(a.cos(), a.sin());
                u * e.exit(Vector2::zeros(), u).unwrap().t
            })
            .collect();
        (e, pts)
    }

    #[test]
    fn resampled_ellipse_is_accurate_with_gaps() {
        let (e, pts) = ellipse_points(400, |i| i % 7 == 3 || (100..104).contains(&i));
        let radii = resample_radii(&pts, 360, default_max_gap(400)).unwrap();
        for (k, r) in radii.iter().enumerate() {
            let phi = TAU * k as f64 / 360.0;
            let u = Vector2::new(phi.cos(), phi.sin());
            let want = e.exit(Vector2::zeros(), u).unwrap().t;
            assert!((r - want).abs() < 2e-7, "k={k} {r} {want}");
        }
    }

    /// The resampler as a textbook states it: `atan2`, a sort, the merge, the padding,
    /// and for every target the segment found afresh and the Hermite basis functions.
    fn textbook_resample(points: &[Vector2<f64>], m: usize, max_gap: f64) -> Option<Vec<f64>> {
        let mut polar: Vec<(f64, f64)> =
            points.iter().filter(|p| p.norm() > 0.0).map(|p| (std_angle(p.y, p.x) % TAU, p.norm())).collect();
        polar.sort_by(|a, b| a.0.total_cmp(&b.0));
        polar.dedup_by(|b, a| {
            let same = b.0 - a.0 < 1e-12;
            if same {
                a.1 = 0.5 * (a.1 + b.1);
            }
            same
        });
        if polar.len() > 1 && polar[0].0 + TAU - polar[polar.len() - 1].0 < 1e-12 {
            let last = polar.pop().unwrap();
            polar[0].1 = 0.5 * (polar[0].1 + last.1);
        }
        let n = polar.len();
        if m == 0 || n < 3 {
            return None;
        }
        let knot = |i: isize| {
            let (t, r) = polar[i.rem_euclid(n as isize) as usize];
            (t + TAU * i.div_euclid(n as isize) as f64, r)
        };
        if (0..n as isize).any(|i| knot(i + 1).0 - knot(i).0 > max_gap) {
            return None;
        }
        let slope = |i: isize| {
            let ((t0, r0), (t1, r1), (t2, r2)) = (knot(i - 1), knot(i), knot(i + 1));
            let (h0, h1) = (t1 - t0, t2 - t1);
            (h1 * (r1 - r0) / h0 + h0 * (r2 - r1) / h1) / (h0 + h1)
        };
        let radii = (0..m).map(|k| {
            let phi = TAU * k as f64 / m as f64;
            let i = (-1..n as isize).rev().find(|&i| knot(i).0 <= phi).unwrap();
            let ((t0, r0), (t1, r1)) = (knot(i), knot(i + 1));
            let h = t1 - t0;
            let s = (phi - t0) / h;
            let (m0, m1) = (slope(i) * h, slope(i + 1) * h);
            let r = (2.0 * s.powi(3) - 3.0 * s * s + 1.0) * r0
                + (s.powi(3) - 2.0 * s * s + s) * m0
                + (-2.0 * s.powi(3) + 3.0 * s * s) * r1
                + (s.powi(3) - s * s) * m1;
            r.max(0.0)
        });
        Some(radii.collect())
    }

    #[test]
    fn resampling_agrees_with_the_textbook() {
        use rand::seq::SliceRandom;
        use rand::{Rng, SeedableRng};
        let mut rng = rand::rngs::StdRng::seed_from_u64(9);
        let mut worst = 0.0f64;
        for case in 0..300 {
            let n = rng.random_range(3..600);
            let start = rng.random_range(0.0..TAU);
            let e = Ellipse {
                center: Vector2::new(rng.random_range(-3e-3..3e-3), rng.random_range(-3e-3..3e-3)),
                a: rng.random_range(0.01..0.03),
                b: rng.random_range(0.005..0.01),
                angle: rng.random_range(0.0..TAU),
            };
            let mut pts: Vec<Vector2<f64>> = (0..n)
                .map(|i| {
                    let a = start + TAU * i as f64 / n as f64 + rng.random_range(-0.2..0.2) / n as f64;
                    let u = Vector2::new(a.cos(), a.sin());
                    u * e.exit(Vector2::zeros(), u).unwrap().t
                })
                .collect();
            match case % 4 {
                // Traced the other way round, or in no order at all.
                1 => pts.reverse(),
                2 => pts.shuffle(&mut rng),
                // A point twice, and one at the axis.
                3 => {
                    let i = rng.random_range(0..n);
                    pts.insert(i, pts[i]);
                    pts.insert(rng.random_range(0..n), Vector2::zeros());
                }
                _ => {}
            }
            let m = rng.random_range(1..500);
            let (ours, book) = (resample_radii(&pts, m, 1.0), textbook_resample(&pts, m, 1.0));
            assert_eq!(ours.is_some(), book.is_some(), "case {case}");
            for (a, b) in ours.unwrap_or_default().iter().zip(book.unwrap_or_default()) {
                worst = worst.max((a - b).abs());
            }
        }
        assert!(worst < 1e-13, "largest difference: {worst:e} m");
    }

    #[test]
    fn the_default_gap_is_ten_steps_within_5_and_90_degrees() {
        assert!((default_max_gap(400) - 10.0 * TAU / 400.0).abs() < 1e-15);
        assert_eq!(default_max_gap(100_000), 5f64.to_radians());
        assert_eq!(default_max_gap(4), TAU / 4.0);
        assert_eq!(default_max_gap(0), TAU / 4.0);
        // A coarse 8-step tracer: one missing step still goes round, two do not.
        let ring = |skip: &[usize]| -> Vec<Vector2<f64>> {
            (0..8)
                .filter(|k| !skip.contains(k))
                .map(|k| {
                    let a = TAU * k as f64 / 8.0;
                    Vector2::new(0.02 * a.cos(), 0.02 * a.sin())
                })
                .collect()
        };
        assert!(resample_radii(&ring(&[3]), 16, default_max_gap(8)).is_some());
        assert!(resample_radii(&ring(&[3, 4]), 16, default_max_gap(8)).is_none());
    }

    #[test]
    fn an_incomplete_revolution_has_no_radii() {
        let (_, pts) = ellipse_points(400, |i| (50..80).contains(&i));
        assert!(resample_radii(&pts, 400, default_max_gap(400)).is_none());
        assert!(resample_radii(&pts[..2], 400, 10.0).is_none());
        assert!(resample_radii(&pts, 0, 10.0).is_none());
    }
}
