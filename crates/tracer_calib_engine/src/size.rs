//! The size of a traced shape, as an edger uses it, and how sure it is: circumference,
//! boxed width `A` and height `B`, effective diameter (FED), each with its expanded
//! uncertainty, from a smooth fit of the corrected contour (never the raw polygon).
//!
//! The contour's equal-angle radii `r_m` (`M` of them, [`super::correct`](mod@super::correct))
//! are cut to their first `K` harmonics (a truncated DFT, which for equal-angle samples is
//! the least-squares Fourier fit; computed by FFT, `realfft`):
//!
//! ```text
//! r(θ) = a_0 + Σ_{k=1..K} (a_k cos kθ + b_k sin kθ),     K = 40 (60, 80, 100, 127 if need be, < M/2, < GRID/2)
//! ```
//!
//! The raw polygon's circumference is biased by the noise (a zig-zag is longer than the
//! line: +111 µm at σ = 10 µm on a lens); the fit's far less, by the noise its `2K + 1`
//! coefficients keep (+1.7 µm at 40 harmonics, +5.5 µm at 60, more under correlated
//! noise), and that mean lengthening is taken off ([`noise_lengthening`]). A lens is smooth
//! enough for 40 harmonics; a frame with sharp corners (3 mm) is not, and gets more, until
//! the samples' scatter about the fit is their noise ([`sample_noise`]).
//!
//! The circumference has a series of its own, of twice those harmonics (127 for a shape
//! with corners), fitted to the points at their own angles (`series_at_own_angles`: the
//! resampling's cubic misses a frame's corners by microns), so that its coefficients carry
//! the samples' noise whole; the lengthening taken off follows the noise as the tracer
//! makes it, along its rail and at its samples' own spacing (`circumference`), with the
//! noise read clear of the corners' shape ([`sample_noise_clear_of_shape`]). Its noise part
//! is the smooth's response to the noise (the finer series' curvature is mostly noise) and
//! the spread of the lengthening the noise makes in one trace beside that of `σ̂`.
//!
//! **The figures** ([`Sizes`]), on a grid of [`GRID`] angles: the circumference
//! `C = ∮ √(r² + r'²) dθ` (trapezoid, spectrally accurate on a periodic function); the box
//! `A = max x - min x`, `B = max y - min y` (`x = r cos θ`, `y = r sin θ`, each extreme
//! refined by a parabola through its grid neighbours; a frame's flat sides from the raw
//! points, `raw_extreme`); the FED, twice the largest distance from the box centre: each
//! far crest (a frame's corner) a circle fitted to its raw points (`raw_far`), the largest
//! of near-equal crests corrected for the bias of a maximum (`largest_of`).
//!
//! **Their response to a small radial change `δr(θ)`** ([`Sizes::response`]): first order,
//! `δC = ∮ (r δr + r' δr')/√(r² + r'²) dθ`; an extreme moves with the point it is at
//! (`δA = δr(θ_xmax) cos θ_xmax - δr(θ_xmin) cos θ_xmin`, the envelope theorem); the FED
//! with its point and the box centre. Everything below is linear propagation through it
//! (a numerical study found it within 1.6-3.5 % of a Monte Carlo).
//!
//! **Uncertainty** ([`uncertainty`]), two independent parts:
//!
//! - *the calibration*: a tracer parameter `x_j` moves a surface point `P` by `∂P/∂x_j`
//!   (the point was measured at rail angle `a`, length `t = k rho - dL`, so
//!   `∂P/∂alpha0 = t v - d u`, `∂P/∂d = v`, `∂P/∂dL = -u`, `∂P/∂k = rho u`, and the tip
//!   `∂P/∂ρ = -s c N`, `c = 1/sin(γ/2)` in a groove traced from inside, else 1,
//!   [`super::stylus`]; an angle coefficient `∂P/∂c_h = cos hφ ∂P/∂alpha0`, `∂P/∂s_h = sin hφ ∂P/∂alpha0`,
//!   [`super::angle`]); radially, `δr = δP·N/(N·e_r)`. With the response
//!   `g_j` of a figure to each, its variance is `gᵀ Σ g` over the whole named covariance
//!   (tracer and certificates, [`super::calibrate`](mod@super::calibrate)); the groove
//!   angle assumed for a frame (`frame.groove_angle_uncertainty`, `u_γ`) moves the contour
//!   along its normal by `∂o/∂γ u_γ`, `δr = √(r² + r'²)/r` of it;
//! - *this scan's noise*: `σ_r²` from the raw radii's scatter about the fit (`N - 2K - 1`
//!   degrees of freedom); a Fourier coefficient of `N` equal-angle samples has variance
//!   `σ_r²/N` (`a_0`) or `2σ_r²/N`, so a figure's is `σ_r²/N (g_0² + 2 Σ_k g_k²)` over the
//!   responses `g_k` to `cos kθ` and `sin kθ`.
//!   The noise as the calibration measured it ([`TraceNoise`]): with a lag-1 correlation `φ`
//!   (AR(1), `calibration.noise_lag1`) the fourth differences see `(70 - 112φ + 56φ² -
//!   16φ³ + 2φ⁴)/70` of the noise's variance and the scatter above `K` the mean of its
//!   density there, both turned back into the marginal `σ_r`; each `g_k²` is weighted by the
//!   density at `ω = 2πk/N`, `(1 - φ²)/(1 - 2φ cos ω + φ²)`, and a side from the raw points
//!   sums its weights with `φ^|i-j|`. Never below one count's `q/√12`; what repeated traces
//!   show beyond it (`size.reproducibility`, `u_R`) adds `(g_uniform u_R)²`, the response
//!   to a uniform radial change.
//!
//! `U95 = 2 √(var_calibration + var_noise)` (k = 2). A resampled radius' own: the
//! calibration's part at its angle, and the samples' own noise ([`sample_noise`], not the
//! scatter about the fit, which a frame's corners swell) times its interpolation's noise
//! gain (a radius between two samples averages their noise: 0.64-1 of a sample's variance).

use nalgebra::Vector2;
use std::f64::consts::TAU;

use nalgebra::DMatrix;

use super::angle::HarmonicOrders;
use super::correct::{polar_angle, resample_values};
use super::geometry::Mounting;
pub use super::smooth::{GRID, Smooth};
use super::smooth::{between_grid_angles, forward_dft, grid_place, grid_unit, read_fine};
use super::stylus::{Groove, Traced, contact_offset_per_groove_angle};

/// Harmonics of the smooth fit at most.
pub const HARMONICS: usize = 40;
/// An extreme of a function sampled on the grid, refined by a parabola: its angle and value.
fn refine(values: &[f64], i: usize) -> (f64, f64) {
    let n = values.len();
    let (a, b, c) = (values[(i + n - 1) % n], values[i], values[(i + 1) % n]);
    let den = a - 2.0 * b + c;
    let h = TAU / n as f64;
    if den.abs() < f64::MIN_POSITIVE {
        return (i as f64 * h, b);
    }
    let off = (0.5 * (a - c) / den).clamp(-0.5, 0.5);
    (((i as f64 + off) * h).rem_euclid(TAU), b - 0.25 * (a - c) * off)
}

/// How much longer the noise makes a smooth's circumference, on average: the smooth's
/// coefficients carry the noise (`δr = Σ_k α_k cos kθ + β_k sin kθ`, independent, each of
/// variance `v_k`), and `C = ∮ s dθ`, `s = √(r² + r'²)`, is convex in them. To second order
/// `δC = ∮ (r δr + r' δr')/s dθ + ½ ∮ [(δr² + δr'²)/s - (r δr + r' δr')²/s³] dθ`; the first
/// term has mean 0, and with `E[δr²] = S₀ = Σ_k v_k`, `E[δr'²] = S₂ = Σ_k k² v_k`,
/// `E[δr δr'] = 0`:
///
/// ```text
/// E[δC] = ½ ∮ (S₀ r'² + S₂ r²) / s³ dθ          (a circle of radius R: π S₂ / R)
/// ```
///
/// `grid`: `r`, `r'` at the [`GRID`] angles. White noise of `σ` on `n` samples gives
/// `v_k = 2σ²/n` (`σ²/n` for `k = 0`): 1.7 µm on a 21 mm radius at σ = 10 µm, 400 samples
/// and 40 harmonics, 5.5 µm with 60; the noise's density at each harmonic scales it.
pub fn noise_lengthening(grid: &[(f64, f64)], s0: f64, s2: f64) -> f64 {
    noise_lengthening_along(grid, |_| (s0, s2))
}

/// [`noise_lengthening`] where `S₀` and `S₂` vary slowly along the contour, `spectrum(i)`
/// at grid angle `i`: a tracer's noise comes along its rail, not along the radius, and
/// its samples are not at equal angles (`circumference`).
pub fn noise_lengthening_along(grid: &[(f64, f64)], spectrum: impl Fn(usize) -> (f64, f64)) -> f64 {
    let h = TAU / grid.len().max(1) as f64;
    0.5 * h
        * grid
            .iter()
            .enumerate()
            .map(|(i, &(r, rp))| {
                let s2_here = r * r + rp * rp;
                let (s0, s2) = spectrum(i);
                (s0 * rp * rp + s2 * r * r) / (s2_here * s2_here.sqrt())
            })
            .sum::<f64>()
}

/// The circumference's harmonics: twice the smooth's `K` for a smooth shape (`K` =
/// [`HARMONICS`], 40: 80 harmonics). A frame's sharp corners keep harmonics well above the `K` at which
/// the other figures stop (their noise would cost more than the shape gains): a 52×32 mm
/// frame with 5 mm corners is 6.3 µm short at 40 harmonics, 1.1 µm at 80. The
/// circumference's response to a harmonic falls with its order (a circle's is 0 but for
/// `k = 0`), so the finer series costs it little noise, and its lengthening is taken off.
pub const CIRCUMFERENCE_HARMONICS_FACTOR: usize = 2;

/// The circumference's harmonics for a contour whose other figures need `k`:
/// [`CIRCUMFERENCE_HARMONICS_FACTOR`]` × k` for a smooth shape (`k` = [`HARMONICS`]), all
/// the grid holds (`GRID/2 - 1`, fewer if the radii are fewer) for one with corners. Not
/// twice `k` there: `k` is chosen against the noise the trace shows ([`uncertainty`]), so
/// on a frame near the choice between 60 and 80 harmonics the traces that stop at 60 are
/// those whose noise reads high; their lengthening, taken off with it, is too long and the
/// others' too short, and the two do not cancel (-0.9 µm of C on a 52 × 32 mm frame).
fn circumference_harmonics(k: usize) -> usize {
    if k > HARMONICS { usize::MAX } else { CIRCUMFERENCE_HARMONICS_FACTOR * k }
}

/// Rounds of [`series_at_own_angles`]: each leaves `|1 - H(ω)|` of the last one's
/// shortfall at `ω`, `H` the cubic's transfer there: 0.27 at 127 harmonics of 400 samples
/// half-way between them (the worst), 0.05 at a lens's 80. Three leave 2 % of the first
/// shortfall at the top harmonics (a frame's C moves 0.001 µm from three rounds to six).
const SERIES_ROUNDS: usize = 3;

/// The Fourier series of `kc` harmonics through the points at their own angles, from the
/// one through `radii` (the points resampled to equal angles): the resampling's cubic
/// misses a contour's corners by up to 3-5 µm a radius where the curvature changes (a
/// polynomial of any order does, across a jump in `r''`; on a 52 × 32 mm frame with 5 mm
/// corners that made its circumference 0.6-1.3 µm short), and it filters the noise. A
/// fixed point: the series' shortfall at the points' own angles, resampled, is fitted and
/// added, [`SERIES_ROUNDS`] times. At its end the series' coefficients are the points' own
/// (`P R E c = P R p`: the resampling `R` of the series `E c` at the points' angles matches
/// that of the points, harmonic by harmonic), so they carry the samples' noise whole.
fn series_at_own_angles(polar: &[(f64, f64)], radii: &[f64], kc: usize) -> Option<Smooth> {
    let own: Vec<(f64, f64)> = polar.iter().copied().filter(|&(_, r)| r > 0.0 && r.is_finite()).collect();
    let mut radii = radii.to_vec();
    let mut series = Smooth::fit(&radii, kc)?;
    for _ in 0..SERIES_ROUNDS {
        let fine = series.on_fine_grid();
        let shortfall = resample_values(own.iter().map(|&(t, r)| (t, r - read_fine(&fine, t))), radii.len())?;
        radii.iter_mut().zip(&shortfall).for_each(|(r, s)| *r += s);
        series = Smooth::fit(&radii, kc)?;
    }
    Some(series)
}

/// The circumference of the series of `kc` harmonics through the points at their own
/// angles ([`series_at_own_angles`], [`circumference_harmonics`]), less the noise's mean
/// lengthening ([`noise_lengthening_along`]), and its variance: the noise through its
/// response to each harmonic, and what the lengthening taken off misses of the one the
/// noise made ([`lengthening_relative_variance`]).
///
/// The response is the shape's, taken from `shape` (`r`, `r'` on the grid of the smooth
/// whose harmonics leave only noise), not from the series' own 127 harmonics: to first
/// order `δC = ∮ κ δn ds`, the curvature times the normal displacement, and the finer
/// series' curvature is mostly its noise (at σ = 10 µm on 400 samples about 300 m⁻¹ on a
/// 20 mm radius, a 5 mm corner's own 200 m⁻¹), which squared into the response made a
/// frame's stated noise part of C 29 % too large (9.5 µm against 7.4 measured by
/// antithetic traces; 6.9 from the smooth; docs/engine.md).
///
/// `noise.per_sample` = `σ̂²/n`, `σ̂` the noise in the points' distances from the axis
/// ([`sample_noise`]); a coefficient of harmonic `j` has `density(ω_j)` times that, twice
/// for `j > 0`, at `ω_j = 2π j/N` a sample. Along the contour that varies in two ways, both
/// taken into the lengthening at each grid angle: the rail's share, `(u·N)²/(N·e_r)²` of the
/// noise in the radius at a fixed angle where the points' distances see `(u·e_r)²`
/// ([`Correction::noise_share`]; on a frame traced with the rail 5 mm off the axis the
/// points' distances show 0.97-0.985 of the encoder's noise variance); and the samples'
/// spacing, `h` times the mean where they are farther apart in angle (a rail off the axis
/// spaces them unevenly), which gives a coefficient `h` times the noise at `ω = 2π j h/N`
/// ([`local_spacing`]). Both together took that frame's modelled lengthening from 33.6-34.1
/// to 32.8-33.3 µm, against 32.0 µm measured (docs/engine.md).
fn circumference(
    polar: &[(f64, f64)],
    radii: &[f64],
    kc: usize,
    shape: &[(f64, f64)],
    noise: NoiseSeen,
    correction: &Correction,
) -> Option<(f64, f64)> {
    let NoiseSeen { per_sample, relative_variance, trace } = noise;
    let density = |omega| trace.density(omega);
    let fine = series_at_own_angles(polar, radii, kc)?;
    let kc = fine.harmonics();
    let grid = fine.on_grid();
    let big_n = polar.len().max(1) as f64;
    let spacing = local_spacing(polar, grid.len());
    let shares: Vec<(f64, f64)> =
        grid.iter().enumerate().map(|(i, &(r, rp))| correction.noise_share(r, rp, grid_unit()[i])).collect();
    // The fourth differences see every sample alike, `1/h` of them a grid step.
    let (seen, count) =
        shares.iter().zip(&spacing).fold((0.0, 0.0), |(seen, count), (s, h)| (seen + s.1 / h, count + 1.0 / h));
    let share: Vec<f64> = shares.iter().map(|s| s.0 * count / seen).collect();
    let spectrum_at = |h: f64| {
        (0..=kc).fold((0.0, 0.0), |(s0, s2), j| {
            let w = if j == 0 { 1.0 } else { 2.0 } * h * density(TAU * j as f64 * h / big_n);
            (s0 + w, s2 + w * (j * j) as f64)
        })
    };
    // `S₀`, `S₂` at a few spacings across the trace's, linear between them.
    const LEVELS: usize = 8;
    let (lo, hi) = spacing.iter().fold((f64::INFINITY, 0.0f64), |(lo, hi), &h| (lo.min(h), hi.max(h)));
    let step = (hi - lo).max(1e-9) / LEVELS as f64;
    let table: Vec<(f64, f64)> = (0..=LEVELS).map(|l| spectrum_at(lo + l as f64 * step)).collect();
    let lengthening = noise_lengthening_along(&grid, |i| {
        let x = ((spacing[i] - lo) / step).clamp(0.0, LEVELS as f64);
        let l = (x as usize).min(LEVELS - 1);
        let (f, a, b) = (x - l as f64, table[l], table[l + 1]);
        let scale = share[i] * per_sample;
        ((a.0 + f * (b.0 - a.0)) * scale, (a.1 + f * (b.1 - a.1)) * scale)
    });
    let mean_share = share.iter().sum::<f64>() / share.len().max(1) as f64;
    let var: f64 = circumference_harmonic_responses(shape, kc)
        .iter()
        .enumerate()
        .map(|(j, (c, s))| {
            let w = if j == 0 { 1.0 } else { 2.0 } * density(TAU * j as f64 / big_n);
            w * if j == 0 { c * c } else { c * c + s * s }
        })
        .sum::<f64>()
        * per_sample
        * mean_share;
    let var_lengthening =
        lengthening * lengthening * (relative_variance + lengthening_relative_variance(&grid, kc, big_n, &density));
    let c = grid_length(&grid) - lengthening;
    (c.is_finite() && var.is_finite()).then_some((c, var + var_lengthening))
}

/// The trace's noise as [`circumference`] takes it.
struct NoiseSeen<'a> {
    /// `σ̂²/n`.
    per_sample: f64,
    /// `σ̂²`'s relative variance ([`sample_noise_relative_variance`]).
    relative_variance: f64,
    /// Its density along the trace ([`TraceNoise::density`]).
    trace: &'a TraceNoise,
}

/// The relative variance of the lengthening the noise makes in one trace (the one taken
/// off is its mean): harmonic `j`'s part of it is `t_j = w_j (A + j² B)`, `w_j` the noise's
/// density there (twice for `j > 0`), `A = ½∮ r'²/L³`, `B = ½∮ r²/L³` (the sum in
/// [`noise_lengthening`] harmonic by harmonic; the rail's share and the samples' spacing,
/// which vary along the contour, left out of the ratio), and each harmonic's two
/// coefficients' squares sum to an exponential variate, whose variance is its mean squared:
///
/// ```text
/// var λ / λ² = Σ_j t_j² / (Σ_j t_j)²        (white noise, a circle: 9/(5K), 11.9 % at K = 127)
/// ```
///
/// Independent of the error of `σ̂` ([`sample_noise_relative_variance`]) to within what
/// the two share: the fourth differences see the noise near `ω = π`, the lengthening up
/// to `2π K/N` weighted by `j²` (their relative covariance 0.0016 against 0.0132 and 0.0141
/// on white noise, 127 harmonics of 400 samples, left out: 5 % of the sum, on the safe
/// side). Measured on a frame by antithetic traces (the noise and its negative: the
/// lengthening is even in it): 6.5 µm of 36 where `σ̂`'s error alone said 5.0.
fn lengthening_relative_variance(grid: &[(f64, f64)], kc: usize, n: f64, density: &impl Fn(f64) -> f64) -> f64 {
    let (a, b) = grid.iter().fold((0.0, 0.0), |(a, b), &(r, rp)| {
        let l3 = (r * r + rp * rp).powf(1.5);
        (a + rp * rp / l3, b + r * r / l3)
    });
    let (sum, squares) = (0..=kc).fold((0.0, 0.0), |(sum, squares), j| {
        let w = if j == 0 { 1.0 } else { 2.0 } * density(TAU * j as f64 / n);
        let t = w * (a + (j * j) as f64 * b);
        // `a_0²` alone is a χ² of one degree of freedom: twice its mean squared.
        (sum + t, squares + if j == 0 { 2.0 } else { 1.0 } * t * t)
    });
    if sum > 0.0 { squares / (sum * sum) } else { 0.0 }
}

/// The points' angular spacing about each of `g` equal angles, over its mean `2π/N`: each
/// point's half-distance to its two neighbours in trace order, averaged over the points
/// within two grid steps.
fn local_spacing(polar: &[(f64, f64)], g: usize) -> Vec<f64> {
    let n = polar.len();
    let theta = |i: usize| polar[i].0;
    let (mut sum, mut count) = (vec![0.0; g], vec![0.0; g]);
    for i in 0..n {
        let half = (theta((i + 1) % n) - theta((i + n - 1) % n)).rem_euclid(TAU) / 2.0;
        let bin = ((theta(i) / TAU * g as f64) as usize).min(g - 1);
        for o in 0..5 {
            let j = (bin + g + o - 2) % g;
            sum[j] += half;
            count[j] += 1.0;
        }
    }
    let mean = TAU / n.max(1) as f64;
    sum.iter().zip(&count).map(|(s, c)| if *c > 0.0 { s / c / mean } else { 1.0 }).collect()
}

/// `∮ √(r² + r'²) dθ` of the curve with `r`, `r'` on `grid` (trapezoid, spectrally accurate
/// on a periodic function).
pub fn grid_length(grid: &[(f64, f64)]) -> f64 {
    grid.iter().map(|(r, rp)| (r * r + rp * rp).sqrt()).sum::<f64>() * TAU / grid.len().max(1) as f64
}

/// The circumference's first-order response to `cos kθ` and `sin kθ` for `k = 0..=K` of the
/// curve with `r`, `r'` on `grid` ([`Sizes::response`]): `∮ (r cos kθ - r' k sin kθ)/L` and
/// `∮ (r sin kθ + r' k cos kθ)/L`, from the DFTs `F` of `r/L` and `r'/L` on the grid:
/// `Re F(r/L)_k + k Im F(r'/L)_k` and `-Im F(r/L)_k + k Re F(r'/L)_k` (`K < GRID/2`).
fn circumference_harmonic_responses(grid: &[(f64, f64)], k_max: usize) -> Vec<(f64, f64)> {
    let h = TAU / GRID as f64;
    let k_max = k_max.min(GRID / 2 - 1);
    let inv_l: Vec<f64> = grid.iter().map(|(r, rp)| 1.0 / (r * r + rp * rp).sqrt()).collect();
    let rl: Vec<f64> = grid.iter().zip(&inv_l).map(|((r, _), il)| r * il).collect();
    let rpl: Vec<f64> = grid.iter().zip(&inv_l).map(|((_, rp), il)| rp * il).collect();
    let (Some(f_r), Some(f_rp)) = (forward_dft(&rl), forward_dft(&rpl)) else {
        return Vec::new(); // not reached: the plan's own lengths
    };
    (0..=k_max)
        .map(|k| {
            let kf = k as f64;
            ((f_r[k].re + kf * f_rp[k].im) * h, (-f_r[k].im + kf * f_rp[k].re) * h)
        })
        .collect()
}

fn argmax(v: &[f64]) -> usize {
    v.iter().enumerate().max_by(|x, y| x.1.total_cmp(y.1)).map_or(0, |(i, _)| i)
}

/// An extreme of a coordinate along the contour (a side of the box), and how it moves
/// with the contour: `Σ w_i δv(θ_i)` over the angles `θ_i` it rests on.
#[derive(Debug, Clone, PartialEq)]
struct Extreme {
    value: f64,
    weights: Vec<(f64, f64)>,
    /// Taken from the raw points (their noise independent of the smooth's).
    raw: bool,
}

/// The largest `v_i` on the grid, robust to a smooth fit's noise ripple: where the
/// contour is flat near its extreme (a frame's side), the largest value of a noisy curve
/// is biased up by its ripple. So the grid points within `tau` of the largest (`tau`: twice
/// the ripple's size) are fitted with a parabola `v = c_0 + c_1 s + c_2 s²` in the other
/// coordinate `s`, and its largest value over them taken; `weights` are that value's
/// first-order dependence on each `v_i` (`[1, s*, s*²] (XᵀX)⁻¹ Xᵀ`). With fewer than five
/// points within `tau` (a curved extreme, or no noise), the parabola through the largest
/// value and its two neighbours.
fn extreme(v: &[f64], s: &[f64], tau: f64) -> Extreme {
    let n = v.len();
    let top = argmax(v);
    let mut region = vec![top];
    for dir in [n - 1, 1] {
        let mut i = (top + dir) % n;
        while v[i] >= v[top] - tau && region.len() < n / 4 {
            region.push(i);
            i = (i + dir) % n;
        }
    }
    let h = TAU / n as f64;
    let peak = || {
        let (angle, value) = refine(v, top);
        Extreme { value, weights: vec![(angle, 1.0)], raw: false }
    };
    if region.len() < 5 {
        return peak();
    }
    let pairs: Vec<(f64, f64)> = region.iter().map(|&i| (s[i], v[i])).collect();
    let Some(top_fit) = ParabolaTop::fit(&pairs, s[top]) else { return peak() };
    Extreme {
        value: top_fit.value,
        weights: region.iter().zip(&top_fit.weights).map(|(&i, w)| (i as f64 * h, *w)).collect(),
        raw: false,
    }
}

/// The least-squares parabola `v = c_0 + c_1 (s - s_0) + c_2 (s - s_0)²` through `(s, v)`
/// pairs, and its largest value over their span (at the vertex if it lies there, else at
/// the higher end), with that value's first-order weight on each `v`
/// (`[1, s*, s*²] (XᵀX)⁻¹ Xᵀ`): what [`extreme`] and [`raw_extreme`] take a side from.
struct ParabolaTop {
    c: nalgebra::Vector3<f64>,
    s0: f64,
    /// The span of `s - s_0`.
    lo: f64,
    hi: f64,
    value: f64,
    weights: Vec<f64>,
    /// `(XᵀX)⁻¹`.
    inv: nalgebra::Matrix3<f64>,
}

impl ParabolaTop {
    /// `None` if the pairs do not determine a parabola.
    fn fit(pairs: &[(f64, f64)], s0: f64) -> Option<ParabolaTop> {
        let row = |s: f64| nalgebra::Vector3::new(1.0, s - s0, (s - s0).powi(2));
        let xtx: nalgebra::Matrix3<f64> = pairs.iter().map(|&(s, _)| row(s) * row(s).transpose()).sum();
        let inv = xtx.try_inverse()?;
        let c = inv * pairs.iter().map(|&(s, v)| row(s) * v).sum::<nalgebra::Vector3<f64>>();
        let (lo, hi) =
            pairs.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &(s, _)| (a.min(s - s0), b.max(s - s0)));
        let mut top = ParabolaTop { c, s0, lo, hi, value: 0.0, weights: Vec::new(), inv };
        let mut best = if top.at(lo) >= top.at(hi) { lo } else { hi };
        if c[2] < 0.0 {
            let vertex = -c[1] / (2.0 * c[2]);
            if (lo..=hi).contains(&vertex) {
                best = vertex;
            }
        }
        top.value = top.at(best);
        top.weights = top.weights_at(pairs.iter().map(|p| p.0), best);
        Some(top)
    }

    /// The first-order weight of the parabola's value at `s - s_0 = x` on each `v` of the
    /// pairs whose `s` are given: `[1, x, x²] (XᵀX)⁻¹ Xᵀ`.
    fn weights_at(&self, s: impl Iterator<Item = f64>, x: f64) -> Vec<f64> {
        let w = self.inv * nalgebra::Vector3::new(1.0, x, x * x);
        s.map(|s| {
            let d = s - self.s0;
            w[0] + w[1] * d + w[2] * d * d
        })
        .collect()
    }

    /// The first-order weight of the parabola's slope at `s_0`, `c_1`, on each `v` of the
    /// pairs whose `s` are given: `[0, 1, 0] (XᵀX)⁻¹ Xᵀ`.
    fn weights_of_slope(&self, s: impl Iterator<Item = f64>) -> Vec<f64> {
        let w = self.inv.column(1);
        s.map(|s| {
            let d = s - self.s0;
            w[0] + w[1] * d + w[2] * d * d
        })
        .collect()
    }

    /// The parabola at `s - s_0 = x`.
    fn at(&self, x: f64) -> f64 {
        self.c[0] + self.c[1] * x + self.c[2] * x * x
    }
}

/// A side of the box from the raw points themselves: those the smooth `r(θ)` puts within
/// `tau` of its extreme `near` in side `k_side`'s coordinate `v` ([`SIDE_COORDINATES`]),
/// fitted with a parabola in the other coordinate `s` as [`extreme`] does. The smooth's ripple where a side is flat (a frame's: its
/// truncated harmonics overshoot there by microns) does not reach it, and the samples'
/// noise averages over the side. `None` with fewer than 6 points (a curved extreme: the
/// smooth's own is good there).
///
/// The top of a parabola through a noisy flat is biased up (the larger of its ends, or a
/// vertex that noise put far out: by about the noise, a frame's 2-5 µm at σ = 10 µm). But
/// the points, chosen by a band about the top, centre on it: where the parabola does not
/// tilt (falls by less than a third of the band over half the points' width, or its slope
/// `c_1` is within [`TILT_SIGNIFICANCE`] standard deviations of what the noise along the
/// trace and the calibration's covariance can make: `side_noise`), the side is
/// its value at the vertex kept within one point spacing of the points' centroid `s_0`
/// (at `s_0` if the parabola is not bent down). Unbiased on a flat and on a curved side
/// alike; the points' plain mean would fall short on a curved one by `|c_2|` times their
/// mean square distance from the top. The points are kept but where the smooth bends like
/// a corner ([`off_the_corners`]): dropping those the fit puts more than 2σ below its top
/// (as this once did, for a flat side's shoulders) cut a curved side to its few central
/// points and biased it down (3 µm at σ = 10 µm, 20 mm radius).
fn raw_extreme(
    points: &[Vector2<f64>],
    smooth: &impl Fn(f64) -> f64,
    bend: &impl Fn(f64) -> f64,
    k_side: usize,
    near: f64,
    tau: f64,
    side_noise: &SideNoise,
) -> Option<Extreme> {
    let coords = SIDE_COORDINATES[k_side];
    let noise = side_noise.sigma;
    // A point is chosen by where the smooth puts it, not by its own noisy value: a band
    // on the noisy values keeps a point at its edge when its noise is up and drops it when
    // down, so the choice would depend on the noise the fit's weights are to average.
    let choose = |band: f64| -> Vec<(f64, f64, f64)> {
        points
            .iter()
            .filter_map(|p| {
                let (v, s) = coords(p);
                if v < near - band - 4.0 * noise {
                    return None;
                }
                let norm = p.norm();
                let theta = super::correct::polar_angle(p.y, p.x);
                let on_smooth = if norm > 0.0 { p * (smooth(theta) / norm) } else { *p };
                (coords(&on_smooth).0 >= near - band).then_some((v, s, theta))
            })
            .collect()
    };
    let mut chosen = choose(tau);
    // Fewer than 6 in the band while the raw points lie below it: the smooth overshoots
    // the side by more than its noise ripple (the truncated harmonics at a flat side's
    // ends, which no noise covers on a quiet trace): the band is widened by that overshoot.
    if chosen.len() < 6 {
        let top = points.iter().map(|p| coords(p).0).fold(f64::NEG_INFINITY, f64::max);
        if near - top > tau {
            chosen = choose(tau + (near - top));
        }
    }
    if chosen.len() < 6 {
        return None;
    }
    let chosen = off_the_corners(chosen, bend);
    let s0 = chosen.iter().map(|c| c.1).sum::<f64>() / chosen.len() as f64;
    let fit = ParabolaTop::fit(&chosen.iter().map(|c| (c.1, c.0)).collect::<Vec<_>>(), s0)?;
    let half = (fit.hi - fit.lo) / 2.0;
    // The tilt's spread, the noise's along the trace and the calibration's: weighed only
    // where the band alone would take the tilt.
    let within_spread = || {
        let slope = fit.weights_of_slope(chosen.iter().map(|c| c.1));
        let weighted: Vec<(f64, f64)> = chosen.iter().zip(&slope).map(|(c, w)| (c.2, *w)).collect();
        let spread = correlated_sum(slope.iter().copied(), side_noise.phi) * noise * noise
            + (side_noise.calibration)(k_side, &weighted);
        fit.c[1].abs() < TILT_SIGNIFICANCE * spread.sqrt()
    };
    if fit.c[1].abs() * half < tau / 3.0 || within_spread() {
        // Not tilted (doc above): the vertex, kept near the centroid.
        let spacing = (fit.hi - fit.lo) / (chosen.len() - 1) as f64;
        let x = if fit.c[2] < 0.0 { (-fit.c[1] / (2.0 * fit.c[2])).clamp(-spacing, spacing) } else { 0.0 };
        let w = fit.weights_at(chosen.iter().map(|c| c.1), x);
        let weights = chosen.iter().zip(w).map(|(c, w)| (c.2, w)).collect();
        let value = fit.at(x);
        return value.is_finite().then_some(Extreme { value, weights, raw: true });
    }
    fit.value.is_finite().then(|| Extreme {
        value: fit.value,
        weights: chosen.iter().zip(&fit.weights).map(|(c, w)| (c.2, *w)).collect(),
        raw: true,
    })
}

/// How many of its own standard deviations a side's tilt must reach to be taken
/// ([`raw_extreme`]): as the band's 3σ. Noise correlated along the trace tilts a fit over
/// fewer effectively independent stretches (a 120-point side at lag-1 0.8: the tilt's
/// spread about three times the white noise's), and a tilt the noise made reads the side at
/// its high end.
const TILT_SIGNIFICANCE: f64 = 3.0;

/// The least curvature a corner's shoulder is told by, 1/m: a radius of 8.3 mm. A frame's
/// 3-5 mm corners bend 200-330 m⁻¹; the smooth's noise ripple bends a flat by up to about
/// half of this at σ = 10 µm (3 µm at 60 harmonics on a 16 mm radius: 42 m⁻¹), and a
/// lower floor left the ripple's crests out of the side, where the noise lies high (B
/// -1.0 µm at 40 m⁻¹ on the 52 × 32 mm frame). A corner rounder than 8 mm keeps its
/// shoulders in the side, as before.
const SHOULDER_CURVATURE: f64 = 120.0;

/// The chosen points of a side (`(v, s, θ)`) less those where the smooth bends (its
/// curvature at `θ`, `bend`) more than three times the points' median curvature and more
/// than [`SHOULDER_CURVATURE`]: the shoulders of a flat side's corners, which the band
/// about the extreme takes in once it is wider than the noise (at 3σ, 0.7 mm of a 5 mm
/// corner each side at σ = 10 µm) and which, falling away at both ends, lift a parabola's
/// centre above the flat (a 52 × 32 mm frame's A by about 0.8 µm white, 1.4 µm with noise
/// correlated 0.8 along the trace). A side curved throughout (a lens) bends alike
/// everywhere and keeps every point; so does a side left with fewer than six.
fn off_the_corners(chosen: Vec<(f64, f64, f64)>, bend: &impl Fn(f64) -> f64) -> Vec<(f64, f64, f64)> {
    let bends: Vec<f64> = chosen.iter().map(|c| bend(c.2)).collect();
    let mut sorted = bends.clone();
    sorted.sort_by(f64::total_cmp);
    let limit = (3.0 * sorted[sorted.len() / 2].abs()).max(SHOULDER_CURVATURE);
    let kept: Vec<_> = chosen.iter().zip(&bends).filter(|(_, k)| **k <= limit).map(|(c, _)| *c).collect();
    if kept.len() >= 6 { kept } else { chosen }
}

/// A candidate for the FED's far point: a local maximum of the distance from the box
/// centre, its value and where it is.
#[derive(Debug, Clone, PartialEq)]
struct FarPoint {
    /// Its distance from the box centre (half the FED if it is the farthest).
    value: f64,
    /// The contour's polar angle there.
    angle: f64,
    /// The unit vector from the box centre towards it.
    direction: Vector2<f64>,
    /// From the raw points ([`raw_far`]): the value's first-order weight on each point's
    /// radial change, `(θ_i, w_i)`; `None`: the smooth's own value at `angle`.
    raw: Option<Vec<(f64, f64)>>,
}

/// The distance from the box centre `c` of a far point, from the raw points themselves:
/// the circle `|P - a| = R` fitted (geometrically, Gauss-Newton from the algebraic fit) to
/// the `2h + 1` points nearest the direction `e` seen from `c`, and its farthest point from
/// `c`, `|a - c| + R`. A rounded corner is a circle, any smooth contour one to second order
/// (its osculating circle); a parabola in the angle about `c` is not (its quartic term:
/// +10 µm on a 3 mm corner). The smooth cannot give it: where a frame's corner meets its
/// sides the curvature jumps, and the truncated harmonics overshoot there by microns
/// (52 × 32 mm, 5 mm corners: +12.5 µm of FED at 40 harmonics, noise-free), which the
/// noise then keeps at 40. The weights: `δ(|a - c| + R) = gᵀ δ(a, R)`, `g = ((a - c)/|a - c|,
/// 1)`, `δ(a, R) = -(JᵀJ)⁻¹ Jᵀ δρ`, each point's residual moved by its radial change times
/// `n_i·e_r` (`n_i` the circle's normal there). `None` with too few points near `e`, or a
/// circle that does not hold its points (a flat: the smooth's own is good there).
fn raw_far(points: &[Vector2<f64>], center: Vector2<f64>, e: Vector2<f64>) -> Option<(f64, Vec<(f64, f64)>)> {
    const HALF: usize = 3;
    let angle_of = |p: &Vector2<f64>| {
        let q = p - center;
        let a = super::correct::polar_angle(e.x * q.y - e.y * q.x, e.dot(&q));
        if a > std::f64::consts::PI { a - TAU } else { a }
    };
    let mut near: Vec<(f64, Vector2<f64>)> = points.iter().map(|p| (angle_of(p), *p)).collect();
    if near.len() < 2 * HALF + 1 {
        return None;
    }
    near.select_nth_unstable_by(2 * HALF, |a, b| a.0.abs().total_cmp(&b.0.abs()));
    near.truncate(2 * HALF + 1);
    if near.iter().any(|(a, _)| a.abs() > 0.25) {
        return None;
    }
    // In trace order (their noise's correlation runs along it).
    near.sort_by(|a, b| a.0.total_cmp(&b.0));
    let (a, radius) = fit_circle(&near.iter().map(|n| n.1).collect::<Vec<_>>())?;
    let to_a = a - center;
    // The circle must bulge away from the centre (a corner, not a dent).
    if to_a.dot(&e) <= 0.0 {
        return None;
    }
    // Larger than 0.9 of its far point's distance from the centre: a broad crest, where the
    // smooth's own value is good.
    let value = to_a.norm() + radius;
    if radius > 0.9 * value {
        return None;
    }
    let g = nalgebra::Vector3::new(to_a.x, to_a.y, 0.0) / to_a.norm().max(f64::MIN_POSITIVE)
        + nalgebra::Vector3::new(0.0, 0.0, 1.0);
    let rows: Vec<(nalgebra::Vector3<f64>, Vector2<f64>)> = near
        .iter()
        .map(|(_, p)| {
            let n = (p - a) / (p - a).norm();
            (nalgebra::Vector3::new(-n.x, -n.y, -1.0), n)
        })
        .collect();
    let jtj: nalgebra::Matrix3<f64> = rows.iter().map(|(j, _)| j * j.transpose()).sum();
    let h = jtj.try_inverse()? * g;
    let weights = near
        .iter()
        .zip(&rows)
        .map(|((_, p), (j, n))| {
            let theta = super::correct::polar_angle(p.y, p.x);
            let e_r = Vector2::new(theta.cos(), theta.sin());
            (theta, -h.dot(j) * n.dot(&e_r))
        })
        .collect();
    value.is_finite().then_some((value, weights))
}

/// The circle `|P - a| = R` through `points` by least squares on `|P_i - a| - R`:
/// Gauss-Newton from the algebraic fit `x² + y² + D x + E y + F = 0`. `None` if the points
/// do not determine one.
fn fit_circle(points: &[Vector2<f64>]) -> Option<(Vector2<f64>, f64)> {
    // Centred and scaled for conditioning.
    let mean = points.iter().sum::<Vector2<f64>>() / points.len() as f64;
    let scale = points.iter().map(|p| (p - mean).norm()).fold(0.0, f64::max);
    if scale <= 0.0 {
        return None;
    }
    let q: Vec<Vector2<f64>> = points.iter().map(|p| (p - mean) / scale).collect();
    let m: nalgebra::Matrix3<f64> =
        q.iter().map(|p| nalgebra::Vector3::new(p.x, p.y, 1.0)).map(|v| v * v.transpose()).sum();
    let b: nalgebra::Vector3<f64> = q.iter().map(|p| -nalgebra::Vector3::new(p.x, p.y, 1.0) * p.norm_squared()).sum();
    let d = m.try_inverse()? * b;
    let mut a = Vector2::new(-d[0] / 2.0, -d[1] / 2.0);
    let mut r = (a.norm_squared() - d[2]).max(0.0).sqrt();
    for _ in 0..20 {
        let mut jtj = nalgebra::Matrix3::zeros();
        let mut jtr = nalgebra::Vector3::zeros();
        for p in &q {
            let dist = (p - a).norm();
            if dist <= 0.0 {
                return None;
            }
            let n = (p - a) / dist;
            let j = nalgebra::Vector3::new(-n.x, -n.y, -1.0);
            jtj += j * j.transpose();
            jtr += j * (dist - r);
        }
        let step = jtj.try_inverse()? * jtr;
        a -= Vector2::new(step[0], step[1]);
        r -= step[2];
        if step.norm() < 1e-13 {
            break;
        }
    }
    (r.is_finite() && r > 0.0).then(|| (mean + a * scale, r * scale))
}

/// A side's coordinate of a point and the one along the side.
type SideCoordinates = fn(&Vector2<f64>) -> (f64, f64);

/// Each side's coordinates (max x, max -x, max y, max -y).
const SIDE_COORDINATES: [SideCoordinates; 4] = [|p| (p.x, p.y), |p| (-p.x, p.y), |p| (p.y, p.x), |p| (-p.y, p.x)];

/// Each side's coordinate's change for a radial change `δr` at `θ`, per unit `δr`, from
/// `(cos θ, sin θ)`.
const SIDE_DIRECTION: [fn(f64, f64) -> f64; 4] = [|c, _| c, |c, _| -c, |_, s| s, |_, s| -s];

/// The calibration's variance of side `k`'s weighted change over `(θ_i, w_i)`.
pub type SideVariance<'a> = dyn Fn(usize, &[(f64, f64)]) -> f64 + 'a;

/// What a side read from the raw points ([`Sizes::of_noisy`]) knows of their spread: the
/// samples' noise `σ`, its lag-1 correlation along the trace, and the calibration's
/// variance of a side's weighted change `Σ w_i δv(θ_i)` (side index, `(θ_i, w_i)`).
pub struct SideNoise<'a> {
    /// The samples' noise, m.
    pub sigma: f64,
    /// Its lag-1 correlation along the trace.
    pub phi: f64,
    /// The calibration's variance of a side's weighted change.
    pub calibration: &'a SideVariance<'a>,
}

impl SideNoise<'_> {
    /// No noise, no calibration.
    pub const QUIET: SideNoise<'static> = SideNoise { sigma: 0.0, phi: 0.0, calibration: &|_, _| 0.0 };
}

/// A calibration's covariance over a contour: the parameters' covariance and each one's
/// radial change at the grid angles ([`Correction::all_sensitivities_at`]).
struct CalibrationSpread {
    /// Parameters: the five, then the angle's coefficients when the covariance has them.
    n: usize,
    sigma: DMatrix<f64>,
    /// A grid point's `n` radial changes at `n k`.
    table: Vec<f64>,
}

impl CalibrationSpread {
    /// The covariance's rows: the five, then the angle's coefficients when it has them (a
    /// covariance without them: the five alone); `None` if it has fewer than five.
    fn new(cov: &DMatrix<f64>, correction: &Correction, grid: &[(f64, f64)]) -> Option<CalibrationSpread> {
        let mut correction = *correction;
        let with_angle = 5 + 2 * correction.angle_orders.len();
        let n = if cov.shape() == (with_angle, with_angle) {
            with_angle
        } else {
            correction.angle_orders = HarmonicOrders::NONE;
            if cov.nrows() >= 5 && cov.ncols() >= 5 { 5 } else { return None }
        };
        let mut row = Vec::with_capacity(with_angle);
        let mut table = vec![0.0; GRID * n];
        for (k, ((r, rp), u)) in grid.iter().zip(grid_unit()).enumerate() {
            correction.all_sensitivities_at(*r, *rp, *u, &mut row);
            table[k * n..(k + 1) * n].copy_from_slice(&row[..n]);
        }
        Some(CalibrationSpread { n, sigma: cov.view((0, 0), (n, n)).into_owned(), table })
    }

    /// Grid point `k`'s radial changes.
    fn at(&self, k: usize) -> &[f64] {
        &self.table[k * self.n..(k + 1) * self.n]
    }

    /// `sᵀ Σ s`.
    fn quadratic(&self, s: &[f64]) -> f64 {
        let mut v = 0.0;
        for (a, sa) in s.iter().enumerate() {
            v += sa * s.iter().enumerate().map(|(b, sb)| self.sigma[(a, b)] * sb).sum::<f64>();
        }
        v
    }

    /// The variance of side `k_side`'s weighted change `Σ w_i δv(θ_i)` over `(θ_i, w_i)`.
    fn side_variance(&self, k_side: usize, weights: &[(f64, f64)]) -> f64 {
        let mut s = vec![0.0; self.n];
        for &(t, w) in weights {
            let (sin, cos) = t.sin_cos();
            let f = w * SIDE_DIRECTION[k_side](cos, sin);
            let (j, frac) = grid_place(t.rem_euclid(TAU) / (TAU / GRID as f64));
            let (a, b) = (self.at(j), self.at((j + 1) % GRID));
            for (p, x) in s.iter_mut().enumerate() {
                *x += f * (a[p] * (1.0 - frac) + b[p] * frac);
            }
        }
        self.quadratic(&s)
    }
}

/// The size figures of a smooth contour, and where its extremes are.
#[derive(Debug, Clone, PartialEq)]
pub struct Sizes {
    pub circumference: f64,
    /// `A`, along the output frame's x axis.
    pub box_width: f64,
    /// `B`, along y.
    pub box_height: f64,
    pub effective_diameter: f64,
    /// Max x, max -x, max y, max -y.
    sides: [Extreme; 4],
    /// The candidates for the FED's far point, farthest first ([`Sizes::of_noisy`]; the
    /// first is the FED's).
    far: Vec<FarPoint>,
    /// The box centre.
    center: Vector2<f64>,
    /// `r` and `r'` on the grid.
    grid: Vec<(f64, f64)>,
}

impl Sizes {
    /// The figures of `smooth` (module docs), taken as noise-free.
    pub fn of(smooth: &Smooth) -> Sizes {
        Self::of_noisy(smooth, 0.0, &[], &SideNoise::QUIET)
    }

    /// The figures of `smooth` whose radii have a noise ripple of standard deviation
    /// `ripple` (`extreme`), fitted to the raw `points` whose spread `side_noise` states:
    /// the box's flat sides are taken from those (`raw_extreme`).
    pub fn of_noisy(smooth: &Smooth, ripple: f64, points: &[Vector2<f64>], side_noise: &SideNoise) -> Sizes {
        Self::of_noisy_grid(smooth.on_grid(), ripple, points, side_noise)
    }

    /// [`Self::of_noisy`] of the smooth whose `r`, `r'` on the grid are `grid`
    /// ([`Smooth::on_grid`]), for a caller that has them already.
    fn of_noisy_grid(grid: Vec<(f64, f64)>, ripple: f64, points: &[Vector2<f64>], side_noise: &SideNoise) -> Sizes {
        let noise = side_noise.sigma;
        let h = TAU / GRID as f64;
        let unit = grid_unit();
        let circumference = grid_length(&grid);
        let x: Vec<f64> = grid.iter().zip(unit).map(|((r, _), (c, _))| r * c).collect();
        let y: Vec<f64> = grid.iter().zip(unit).map(|((r, _), (_, s))| r * s).collect();
        let neg = |v: &[f64]| v.iter().map(|a| -a).collect::<Vec<_>>();
        let tau = 2.0 * ripple;
        let mut sides =
            [extreme(&x, &y, tau), extreme(&neg(&x), &y, tau), extreme(&y, &x, tau), extreme(&neg(&y), &x, tau)];
        if !points.is_empty() {
            let raw_tau = 3.0 * noise + tau;
            // The smooth between grid angles, linearly (a point's choice needs no more).
            let r_at = |t: f64| between_grid_angles(t, |i| grid[i].0);
            // Its curvature, `κ = (r² + 2r'² - r r'')/(r² + r'²)^{3/2}`, `r''` by central
            // differences of the grid's `r'`; between grid angles linearly.
            let curvature: Vec<f64> = (0..GRID)
                .map(|i| {
                    let (r, rp) = grid[i];
                    let rpp = (grid[(i + 1) % GRID].1 - grid[(i + GRID - 1) % GRID].1) / (2.0 * h);
                    (r * r + 2.0 * rp * rp - r * rpp) / (r * r + rp * rp).powf(1.5)
                })
                .collect();
            let bend_at = |t: f64| between_grid_angles(t, |i| curvature[i]);
            for (k_side, side) in sides.iter_mut().enumerate() {
                if let Some(raw) = raw_extreme(points, &r_at, &bend_at, k_side, side.value, raw_tau, side_noise) {
                    *side = raw;
                }
            }
        }
        let [xmax, nxmin, ymax, nymin] = [0, 1, 2, 3].map(|i| sides[i].value);
        let center = Vector2::new((xmax - nxmin) / 2.0, (ymax - nymin) / 2.0);
        let dist: Vec<f64> =
            grid.iter().zip(unit).map(|((r, _), (c, s))| (Vector2::new(*c, *s) * *r - center).norm()).collect();
        let far = far_points(&dist, &grid, center, points, 6.0 * noise + 4.0 * ripple);
        Sizes {
            circumference,
            box_width: xmax + nxmin,
            box_height: ymax + nymin,
            effective_diameter: 2.0 * far[0].value,
            sides,
            far,
            center,
            grid,
        }
    }

    /// `r` and `r'` at the [`GRID`] angles.
    pub fn grid(&self) -> &[(f64, f64)] {
        &self.grid
    }

    /// `[C, A, B, FED]`.
    pub fn figures(&self) -> [f64; 4] {
        [self.circumference, self.box_width, self.box_height, self.effective_diameter]
    }

    /// First-order change of `[C, A, B, FED]` for the radial change `dr(θ)` (module docs).
    pub fn response(&self, dr: impl Fn(f64) -> f64) -> [f64; 4] {
        let h = TAU / GRID as f64;
        self.response_on_grid(&(0..GRID).map(|i| dr(i as f64 * h)).collect::<Vec<_>>())
    }

    /// [`Self::response`] to a radial change given on the grid (read between grid angles
    /// by linear interpolation).
    pub fn response_on_grid(&self, d: &[f64]) -> [f64; 4] {
        let h = TAU / GRID as f64;
        let mut dc = 0.0;
        for i in 0..GRID {
            let (r, rp) = self.grid[i];
            let ddr = (d[(i + 1) % GRID] - d[(i + GRID - 1) % GRID]) / (2.0 * h);
            dc += (r * d[i] + rp * ddr) / (r * r + rp * rp).sqrt();
        }
        self.extremes_response(dc * h, |t| between_grid_angles(t, |i| d[i]))
    }

    /// [`Self::response`] to `cos kθ` and `sin kθ` for `k = 0..=K` (`k = 0`: the constant).
    /// The circumference's by [`circumference_harmonic_responses`].
    fn harmonic_responses(&self, k_max: usize) -> Vec<[f64; 4]> {
        let k_max = k_max.min(GRID / 2 - 1);
        let dc = circumference_harmonic_responses(&self.grid, k_max);
        if dc.is_empty() {
            return Vec::new();
        }
        // Each side's response to cos kθ and sin kθ, all k at once (rotation per point).
        let sides = self.side_harmonics(k_max);
        let t_fed = self.far[0].angle;
        let e = self.far_direction();
        let e_r = Vector2::new(t_fed.cos(), t_fed.sin());
        let assemble = |dc: f64, side: [f64; 4], at_fed: f64| -> [f64; 4] {
            let [dxmax, dnxmin, dymax, dnymin] = side;
            let dcenter = Vector2::new(dxmax - dnxmin, dymax - dnymin) / 2.0;
            [dc, dxmax + dnxmin, dymax + dnymin, 2.0 * (e_r * at_fed - dcenter).dot(&e)]
        };
        let mut out = Vec::with_capacity(2 * k_max + 1);
        for k in 0..=k_max {
            let kf = k as f64;
            out.push(assemble(dc[k].0, [0, 1, 2, 3].map(|j| sides[j][k].0), (kf * t_fed).cos()));
            if k > 0 {
                out.push(assemble(dc[k].1, [0, 1, 2, 3].map(|j| sides[j][k].1), (kf * t_fed).sin()));
            }
        }
        out
    }

    /// For each side of the box and `k = 0..=k_max`, its response to `cos kθ` and `sin kθ`
    /// ([`Self::side_responses`] of each harmonic, by rotation instead of trigonometry).
    fn side_harmonics(&self, k_max: usize) -> [Vec<(f64, f64)>; 4] {
        [0, 1, 2, 3].map(|j| {
            let mut out = vec![(0.0, 0.0); k_max + 1];
            for &(t, w) in &self.sides[j].weights {
                let (s1, c1) = t.sin_cos();
                let f = w * SIDE_DIRECTION[j](c1, s1);
                let (mut c, mut s) = (1.0, 0.0);
                for o in out.iter_mut() {
                    o.0 += f * c;
                    o.1 += f * s;
                    (c, s) = (c * c1 - s * s1, s * c1 + c * s1);
                }
            }
            out
        })
    }

    /// How each side of the box (max x, max -x, max y, max -y) moves with the radial change.
    fn side_responses(&self, dr: &impl Fn(f64) -> f64) -> [f64; 4] {
        let side = |k: usize, f: &dyn Fn(f64) -> f64| -> f64 {
            self.sides[k].weights.iter().map(|&(t, w)| w * dr(t) * f(t)).sum()
        };
        [side(0, &|t| t.cos()), side(1, &|t| -t.cos()), side(2, &|t| t.sin()), side(3, &|t| -t.sin())]
    }

    /// `[δC, δA, δB, δFED]` given `δC` and the radial change.
    fn extremes_response(&self, dc: f64, dr: impl Fn(f64) -> f64) -> [f64; 4] {
        let [dxmax, dnxmin, dymax, dnymin] = self.side_responses(&dr);
        let dcenter = Vector2::new(dxmax - dnxmin, dymax - dnymin) / 2.0;
        let t_fed = self.far[0].angle;
        let e_r = Vector2::new(t_fed.cos(), t_fed.sin());
        let e = self.far_direction();
        let dfed = 2.0 * (e_r * dr(t_fed) - dcenter).dot(&e);
        [dc, dxmax + dnxmin, dymax + dnymin, dfed]
    }

    /// The unit vector from the box centre towards the FED's far point.
    fn far_direction(&self) -> Vector2<f64> {
        self.far[0].direction
    }
}

/// `Σ_ij a_i a_j φ^|i-j|`, the variance of `Σ a_i n_i` over unit AR(1) noise `n_i` taken
/// in trace order: `Σ_i a_i (a_i + 2 F_i)`, `F_i = φ (F_(i-1) + a_(i-1))`.
fn correlated_sum(a: impl Iterator<Item = f64>, phi: f64) -> f64 {
    let (mut sum, mut forward, mut last) = (0.0, 0.0, 0.0);
    for a in a {
        forward = phi * (forward + last);
        sum += a * (a + 2.0 * forward);
        last = a;
    }
    sum.max(0.0)
}

/// The candidates for the FED's far point, farthest first: the local maxima of the smooth's
/// distance `dist` from the box centre `center` on the grid, within `gap` of the largest
/// and 0.2 rad apart (a frame's corners; a symmetric frame has four equally far), each
/// taken from the raw `points` where they give it ([`raw_far`]), else the smooth's value
/// (refined by a parabola). Never empty.
fn far_points(
    dist: &[f64],
    grid: &[(f64, f64)],
    center: Vector2<f64>,
    points: &[Vector2<f64>],
    gap: f64,
) -> Vec<FarPoint> {
    let n = dist.len();
    let mut maxima: Vec<usize> =
        (0..n).filter(|&i| dist[i] >= dist[(i + n - 1) % n] && dist[i] > dist[(i + 1) % n]).collect();
    maxima.sort_by(|a, b| dist[*b].total_cmp(&dist[*a]));
    if maxima.is_empty() {
        maxima.push(argmax(dist));
    }
    let top = dist[maxima[0]];
    let mut far: Vec<FarPoint> = Vec::new();
    for i in maxima {
        let (angle, value) = refine(dist, i);
        let apart = |f: &FarPoint| {
            let d = (f.angle - angle).rem_euclid(TAU);
            d.min(TAU - d) >= 0.2
        };
        if !far.is_empty() && (dist[i] < top - gap || !far.iter().all(apart) || far.len() == 8) {
            continue;
        }
        let e_r = Vector2::new(angle.cos(), angle.sin());
        let direction = (e_r * grid_r_at(grid, angle) - center).try_normalize(0.0).unwrap_or(e_r);
        let raw = if points.is_empty() { None } else { raw_far(points, center, direction) };
        // A circle far off the smooth's crest is not this crest's (the smooth is within its
        // noise of the points).
        let raw = raw.filter(|(v, _)| (v - value).abs() <= gap.max(1e-6) * 4.0);
        far.push(match raw {
            Some((value, weights)) => FarPoint { value, angle, direction, raw: Some(weights) },
            None => FarPoint { value, angle, direction, raw: None },
        });
    }
    far.sort_by(|a, b| b.value.total_cmp(&a.value));
    far
}

/// The FED's far distance from its candidates' values `v_j`, corrected for the bias of
/// the largest of noisy values, and that estimate's variance. Each candidate has its own
/// independent noise `ε_j` (variances `own`) and shares the box centre's `δc` (variances
/// `centre` in x and y): a value is `μ_j + ε_j - e_j·δc`.
///
/// The largest of equals is biased up (four at one standard deviation `s`: `+1.03 s`). The
/// bias `B(μ) = E max_j(μ_j + ε_j - e_j·δc) - max_j μ_j` is taken at `μ̂`, the values shrunk
/// towards their mean as far as their spread is twice the noise's (James-Stein-like: `λ =
/// 1 - 2 (n - 1) s̄²/Σ(v_j - v̄)²`, at least 0), for the values themselves spread equals
/// apart and would show less bias than there is; `B` by Clark's moments of the largest of
/// normals ([`largest_normal`], the centre's share of each variance taken as its own). The
/// estimate `T(v) = max_j v_j - B(μ̂(v))`; its variance is `T`'s over 300 draws about `μ̂`
/// of one fixed sequence (the same figures for the same trace), the centre shared as it is.
/// One candidate: `v`, `own + e·Σ_c e`.
fn largest_of(far: &[FarPoint], own: &[f64], centre: [f64; 2]) -> (f64, f64) {
    // Each candidate's whole variance, its own and the centre's along it (the bias below
    // takes them as independent: the centre's share is small beside a corner's own).
    let whole: Vec<f64> = far
        .iter()
        .zip(own)
        .map(|(f, v)| v.max(0.0) + f.direction.x.powi(2) * centre[0] + f.direction.y.powi(2) * centre[1])
        .collect();
    if far.len() == 1 {
        return (far[0].value, whole[0]);
    }
    use rand::SeedableRng;
    use rand_distr::{Distribution, StandardNormal};
    let mut rng = rand::rngs::StdRng::seed_from_u64(0x00FE_D000);
    let mut normal = move || -> f64 { StandardNormal.sample(&mut rng) };
    let sd: Vec<f64> = own.iter().map(|v| v.max(0.0).sqrt()).collect();
    let sc = centre.map(|v| v.max(0.0).sqrt());
    let n = far.len();
    // A draw of every candidate's noise, `s_j z_j - e_j·(s_x z_x, s_y z_y)`, into `out`.
    let mut draw = |out: &mut [f64]| {
        let dc = Vector2::new(sc[0] * normal(), sc[1] * normal());
        for ((o, f), s) in out.iter_mut().zip(far).zip(&sd) {
            *o = s * normal() - f.direction.dot(&dc);
        }
    };
    const OUTER: usize = 300;
    let largest = |v: &[f64]| v.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let count = n as f64;
    let s2 = own.iter().sum::<f64>() / count;
    // The values shrunk towards their mean, less the largest of them (`≤ 0`), into `out`.
    let shrunk_below_top = |v: &[f64], out: &mut [f64]| {
        let mean = v.iter().sum::<f64>() / count;
        let spread: f64 = v.iter().map(|x| (x - mean).powi(2)).sum();
        let lambda = if spread > 0.0 { (1.0 - 2.0 * (count - 1.0) * s2 / spread).max(0.0) } else { 0.0 };
        for (o, x) in out.iter_mut().zip(v) {
            *o = lambda * (x - mean);
        }
        let top = largest(out);
        out.iter_mut().for_each(|o| *o -= top);
    };
    let mut d = vec![0.0; n];
    let mut estimate = |v: &[f64]| {
        shrunk_below_top(v, &mut d);
        largest(v) - largest_normal(&d, &whole).0
    };
    let values: Vec<f64> = far.iter().map(|f| f.value).collect();
    let mut mu = vec![0.0; n];
    shrunk_below_top(&values, &mut mu);
    let at = estimate(&values);
    let (mut sum, mut sq) = (0.0, 0.0);
    let (mut e, mut v) = (vec![0.0; n], vec![0.0; n]);
    for _ in 0..OUTER {
        draw(&mut e);
        for ((v, m), e) in v.iter_mut().zip(&mu).zip(&e) {
            *v = m + e;
        }
        let t = estimate(&v);
        sum += t;
        sq += t * t;
    }
    let mean = sum / OUTER as f64;
    (at, (sq / OUTER as f64 - mean * mean).max(0.0))
}

/// The mean and variance of the largest of independent normals `N(μ_j, v_j)`, by Clark's
/// moments (1961), one pair at a time: for `X ~ N(m, s²)` and `Y ~ N(μ, v)`, `a² = s² + v`,
/// `α = (m - μ)/a`, `E max = m Φ(α) + μ Φ(-α) + a φ(α)`, `E max² = (m² + s²) Φ(α) + (μ² +
/// v) Φ(-α) + (m + μ) a φ(α)`, the largest taken as normal for the next. Exact for two.
fn largest_normal(mu: &[f64], var: &[f64]) -> (f64, f64) {
    let (mut m, mut s2) = (mu[0], var[0].max(0.0));
    for (&mj, &vj) in mu.iter().zip(var).skip(1) {
        let a = (s2 + vj.max(0.0)).sqrt();
        if a <= 0.0 {
            if mj > m {
                (m, s2) = (mj, vj.max(0.0));
            }
            continue;
        }
        let alpha = (m - mj) / a;
        let (p, q) = (normal_cdf(alpha), normal_cdf(-alpha));
        let density = (-0.5 * alpha * alpha).exp() / (TAU).sqrt();
        let first = m * p + mj * q + a * density;
        let second = (m * m + s2) * p + (mj * mj + vj.max(0.0)) * q + (m + mj) * a * density;
        (m, s2) = (first, (second - first * first).max(0.0));
    }
    (m, s2)
}

/// The standard normal distribution function `Φ(x) = erfc(-x/√2)/2`, `erfc` by the
/// Chebyshev fit of Numerical Recipes (§6.2, relative error under 1.2e-7).
fn normal_cdf(x: f64) -> f64 {
    let z = (-x / std::f64::consts::SQRT_2).abs();
    let t = 1.0 / (1.0 + 0.5 * z);
    let poly = -z * z - 1.265_512_23
        + t * (1.000_023_68
            + t * (0.374_091_96
                + t * (0.096_784_18
                    + t * (-0.186_288_06
                        + t * (0.278_868_07
                            + t * (-1.135_203_98 + t * (1.488_515_87 + t * (-0.822_152_23 + t * 0.170_872_77))))))));
    let erfc = t * poly.exp();
    let erfc = if -x >= 0.0 { erfc } else { 2.0 - erfc };
    0.5 * erfc
}

/// The grid's `r` nearest the angle `t`.
fn grid_r_at(grid: &[(f64, f64)], t: f64) -> f64 {
    let h = TAU / GRID as f64;
    grid[((t.rem_euclid(TAU) / h).round() as usize) % GRID].0
}

/// How the corrected contour was made: what moves its points.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Correction {
    pub mounting: Mounting,
    pub tip_radius: f64,
    pub traced: Traced,
    /// The groove the tip sat in when it traced from inside (a frame's rim: the contour is
    /// its bottom, [`crate::stylus`]); ignored from outside.
    pub groove: Groove,
    /// The orders of the angle error the correction applied (their coefficients' rows
    /// follow the five in the covariance, [`super::calibrate::covariance_names`]).
    pub angle_orders: HarmonicOrders,
    /// The tracer's noise as the calibration measured it, and what one trace cannot show.
    pub noise: TraceNoise,
}

/// The tracer's noise beyond what one trace shows (module docs, *this scan's noise*).
/// The default is white noise, no quantum, no reproducibility term.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct TraceNoise {
    /// Lag-1 correlation `φ` of the encoder noise along the trace, AR(1), as the
    /// calibration measured it on the plate (`calibration.noise_lag1`): one trace cannot
    /// tell noise below the smooth's cut-off from shape.
    pub lag1: f64,
    /// The length of one encoder count, metres: no reading is surer than `q/√12`
    /// (GUM F.2.2.1), however constant the radius.
    pub quantum: f64,
    /// Standard uncertainty of a radius between repeated traces of one shape beyond their
    /// noise (re-seating, clamping; `size.reproducibility`, metres): a uniform radial
    /// change, in every figure by its response to one.
    pub reproducibility: f64,
}

impl TraceNoise {
    fn phi(&self) -> f64 {
        if self.lag1.is_finite() { self.lag1.clamp(-0.95, 0.95) } else { 0.0 }
    }

    /// The noise's spectral density at `ω` (rad a sample) over its variance:
    /// `S(ω) = (1 - φ²)/(1 - 2φ cos ω + φ²)`, mean 1 over `[0, π]`; 1 for white noise.
    pub fn density(&self, omega: f64) -> f64 {
        let p = self.phi();
        (1.0 - p * p) / (1.0 - 2.0 * p * omega.cos() + p * p)
    }

    /// What the fourth differences of [`sample_noise`] see of the noise's variance:
    /// `Σ_ij c_i c_j φ^|i-j| / 70 = (70 - 112φ + 56φ² - 16φ³ + 2φ⁴)/70`
    /// (`c = 1, -4, 6, -4, 1`); 0.37 at `φ = 0.5`, 0.08 at 0.8.
    pub fn fourth_difference_share(&self) -> f64 {
        let p = self.phi();
        (70.0 - 112.0 * p + 56.0 * p * p - 16.0 * p.powi(3) + 2.0 * p.powi(4)) / 70.0
    }

    /// The mean density over the harmonics `k` of `n` samples above `harmonics`, `ω = 2πk/n`:
    /// what a smooth's residual scatter sees of the noise's variance.
    fn above_share(&self, harmonics: usize, n: usize) -> f64 {
        let top = n / 2;
        if harmonics >= top || self.phi() == 0.0 {
            return 1.0;
        }
        let sum: f64 = (harmonics + 1..=top).map(|k| self.density(TAU * k as f64 / n as f64)).sum();
        sum / (top - harmonics) as f64
    }
}

impl Correction {
    /// How far the tip's centre sat from the contour per unit of tip radius: `1/sin(γ/2)`
    /// in a groove traced from inside, else 1.
    pub fn contact_factor(&self) -> f64 {
        match self.traced {
            Traced::Inside => self.groove.factor(),
            Traced::Outside => 1.0,
        }
    }

    /// How far the tip's centre sat from the contour: `ρ`, or `ρ/sin(γ/2)` in a groove
    /// ([`crate::stylus::contact_offset`]).
    pub fn contact_offset(&self) -> f64 {
        self.tip_radius * self.contact_factor()
    }

    /// The standard uncertainty of [`Self::contact_offset`] from the groove angle's:
    /// `|∂o/∂γ| u_γ` (0 from outside or for a groove known exactly).
    pub fn groove_offset_uncertainty(&self) -> f64 {
        match self.traced {
            Traced::Inside if self.groove.uncertainty > 0.0 => {
                (contact_offset_per_groove_angle(self.tip_radius, self.groove.angle) * self.groove.uncertainty).abs()
            }
            _ => 0.0,
        }
    }

    /// `δr(θ)` per unit change of each tracer parameter `[alpha0, d, dL, k, ρ]` at the
    /// surface point at `θ` of `smooth` (module docs).
    pub fn radial_sensitivities(&self, smooth: &Smooth, theta: f64) -> [f64; 5] {
        let (r, rp) = smooth.at(theta);
        let (s, c) = theta.sin_cos();
        self.radial_sensitivities_at(r, rp, (c, s))
    }

    /// [`Self::radial_sensitivities`] where `r(θ)`, `r'(θ)` and `(cos θ, sin θ)` are known.
    ///
    /// The rail that measured the tip's centre `c` runs at `a = atan2(c) - atan2(d, t)`,
    /// `t = √(|c|² - d²)`; its direction `u = (cos a, sin a)` is `c` turned back by the
    /// angle whose cosine is `t/|c|` and sine `d/|c|`: `u = (c_x t + c_y d, c_y t - c_x d)/|c|²` (normalised, for a centre
    /// inside the offset circle),
    /// and `v = (-u_y, u_x)` (no trigonometry).
    pub fn radial_sensitivities_at(&self, r: f64, rp: f64, cs: (f64, f64)) -> [f64; 5] {
        self.radial_sensitivities_and_rail(r, rp, cs).0
    }

    /// [`Self::radial_sensitivities_at`], then each angle coefficient's: a coefficient
    /// moves the rail as `alpha0` does, times `cos hφ` or `sin hφ` at the rail's step
    /// angle `φ = a - alpha0` ([`super::angle`]).
    pub fn all_sensitivities_at(&self, r: f64, rp: f64, cs: (f64, f64), out: &mut Vec<f64>) {
        let (five, u) = self.radial_sensitivities_and_rail(r, rp, cs);
        out.clear();
        out.extend_from_slice(&five);
        if !self.angle_orders.is_empty() {
            let phi = u.y.atan2(u.x) - self.mounting.alpha0;
            out.extend(self.angle_orders.basis(phi).map(|b| b * five[0]));
        }
    }

    /// How the tracer's noise, along the rail `u` that measured the point at `θ` of the
    /// contour with `r`, `r'` there, shows: in the radius at a fixed angle, `((u·N)/(N·e_r))²`
    /// of its variance (the point moves off the contour by `u·N`, the radius by that over
    /// `N·e_r`), and in the point's distance from the axis, which [`sample_noise`] sees,
    /// `(u·e_r)²`. Both 1 with the rail through the axis on a circle.
    pub fn noise_share(&self, r: f64, rp: f64, cs: (f64, f64)) -> (f64, f64) {
        let (_, u, normal) = self.sensitivities_rail_normal(r, rp, cs);
        let e_r = Vector2::new(cs.0, cs.1);
        let (un, ne, ue) = (u.dot(&normal), normal.dot(&e_r), u.dot(&e_r));
        ((un / ne).powi(2), ue * ue)
    }

    /// The five sensitivities and the rail direction `u` that measured the point.
    fn radial_sensitivities_and_rail(&self, r: f64, rp: f64, cs: (f64, f64)) -> ([f64; 5], Vector2<f64>) {
        let (five, u, _) = self.sensitivities_rail_normal(r, rp, cs);
        (five, u)
    }

    /// [`Self::radial_sensitivities_and_rail`] and the contour's normal `N` there.
    fn sensitivities_rail_normal(
        &self,
        r: f64,
        rp: f64,
        (cos, sin): (f64, f64),
    ) -> ([f64; 5], Vector2<f64>, Vector2<f64>) {
        let e_r = Vector2::new(cos, sin);
        let e_t = Vector2::new(-sin, cos);
        let normal = (e_r * r - e_t * rp).normalize();
        let s = match self.traced {
            Traced::Outside => 1.0,
            Traced::Inside => -1.0,
        };
        // The tip's centre, and the rail that measured it.
        let c = self.contact_factor();
        let centre = e_r * r + normal * (s * c * self.tip_radius);
        let d = self.mounting.offset;
        let t = (centre.norm_squared() - d * d).max(0.0).sqrt();
        let u = Vector2::new(centre.x * t + centre.y * d, centre.y * t - centre.x * d).normalize();
        let v = Vector2::new(-u.y, u.x);
        let rho = (t + self.mounting.delta_l) / self.mounting.scale;
        let moves = [v * t - u * d, v, -u, u * rho, -normal * (s * c)];
        let n_er = normal.dot(&e_r);
        (moves.map(|dp| dp.dot(&normal) / n_er), u, normal)
    }
}

/// The samples' own noise, seen in the fourth differences of their distances from the
/// axis in sample order, `d_i = r_{i-2} - 4 r_{i-1} + 6 r_i - 4 r_{i+1} + r_{i+2}`
/// (`E d_i² = 70 σ²` for white noise): the mean of the smallest [`SAMPLE_NOISE_KEPT`] of the
/// `d_i²/70`, over the share of a Gaussian's variance that lies below that quantile
/// ([`TRIMMED_SECOND_MOMENT`]). Second differences would see the shape too: `r'' h²` is 4-11
/// µm on a frame's flat side at 400 steps, as much as the noise; the fourth, `r'''' h⁴`, a
/// tenth of a micron at most (a 52 × 32 mm frame noise-free reads 0.003 µm), and the
/// trimming keeps a few spikes or a sharper corner out.
///
/// Against the median of `|d_i|` (what this was): its `σ̂²` was 1.7 % high and spread 16.5 %
/// a trace (400 samples of white noise, 3000 traces), this one's is 0.3-0.7 % high and
/// spreads 12.6-12.8 % ([`sample_noise_relative_variance`]); a frame's circumference takes 35 µm of noise
/// lengthening off in proportion to `σ̂²`, so both count.
pub fn sample_noise(points: &[Vector2<f64>]) -> f64 {
    let r: Vec<f64> = points.iter().map(|p| p.norm()).collect();
    sample_noise_of(&r)
}

/// Each point's angle about the axis (in `[0, 2π)`) and distance from it, in trace order.
fn polar_form(points: &[Vector2<f64>]) -> Vec<(f64, f64)> {
    points.iter().map(|p| (polar_angle(p.y, p.x), p.norm())).collect()
}

/// [`sample_noise`] of the points' distances from the axis `r`, in trace order.
fn sample_noise_of(r: &[f64]) -> f64 {
    trimmed_noise(squared_fourth_differences(r).collect()).unwrap_or(0.0)
}

/// `d_i²` of [`sample_noise`], `d_i = r_{i-2} - 4 r_{i-1} + 6 r_i - 4 r_{i+1} + r_{i+2}`, one
/// for each five neighbours in trace order.
fn squared_fourth_differences(r: &[f64]) -> impl Iterator<Item = f64> + '_ {
    r.windows(5).map(|w| (w[0] - 4.0 * w[1] + 6.0 * w[2] - 4.0 * w[3] + w[4]).powi(2))
}

/// [`sample_noise`] clear of a contour's curvature jumps: a frame's corners (an arc meeting
/// a flat side) put shape into about a tenth of the fourth differences, moderately (a
/// jump `J` in `r''` gives a few `J h²`, tens of µm on a 52 × 32 mm frame with 5 mm
/// corners), which neither trimming nor a median removes: on that frame `σ̂²` reads 1.2-2.2 %
/// high at σ = 10 µm, 5 % at 5 µm, 15 % at 2 µm (0.6-1.7 µm² whatever the noise), and a
/// circumference's noise lengthening, in proportion to `σ̂²`, is taken off that much too
/// long. A difference is left out where the shape may reach it, from `smooth` (the
/// contour's series, harmonics `K`): a jump spreads over about `π/K` in its series, so
/// `|r'''| π/K h²` bounds what it puts into a difference at spacing `h`; left out where that
/// exceeds [`CLEAR_OF_SHAPE`] of the noise's own `√70 σ̂` (`seen`: [`sample_noise`]'s) at
/// any of the five samples. `polar`: each point's angle about the axis (in `[0, 2π)`)
/// and distance from it, in trace order. Returns the noise and the share left out (none
/// on a lens or a circle; 19 % on that frame at σ = 10 µm, where `σ̂²` then reads 0.6 %
/// above what it reads on a circle, 1.6 % without: 2000 traces each).
pub fn sample_noise_clear_of_shape(polar: &[(f64, f64)], smooth: &Smooth, seen: f64) -> (f64, f64) {
    let r3 = smooth.third_derivative_on_grid();
    let k = smooth.harmonics().max(1) as f64;
    let h = TAU / polar.len().max(1) as f64;
    let reach = std::f64::consts::PI / k * h * h;
    let threshold = CLEAR_OF_SHAPE * 70f64.sqrt() * seen;
    let shape: Vec<f64> = polar
        .iter()
        .map(|&(t, _)| {
            let (j, f) = grid_place(t / TAU * GRID as f64);
            (r3[j] * (1.0 - f) + r3[(j + 1) % GRID] * f).abs() * reach
        })
        .collect();
    let r: Vec<f64> = polar.iter().map(|p| p.1).collect();
    let d2: Vec<f64> = squared_fourth_differences(&r)
        .zip(shape.windows(5))
        .filter(|(_, reached)| reached.iter().all(|&x| x <= threshold))
        .map(|(d2, _)| d2)
        .collect();
    let left_out = 1.0 - d2.len() as f64 / r.len().saturating_sub(4).max(1) as f64;
    match trimmed_noise(d2) {
        Some(noise) => (noise, left_out),
        None => (seen, left_out),
    }
}

/// What of the noise's own fourth difference (`√70 σ̂`) the shape may put into one before
/// [`sample_noise_clear_of_shape`] leaves it out: 0.4. Tighter does not help: at 0.2 a
/// third of a frame's differences are left out (σ = 10 µm) and `σ̂²` reads 1.3 % high
/// (0.4 % at 0.4), at 0.1 two thirds and 3.5 % (only the quietest are left; 600 traces
/// each).
pub const CLEAR_OF_SHAPE: f64 = 0.4;

/// The noise of squared fourth differences `d2` ([`sample_noise`]): the mean of the
/// smallest [`SAMPLE_NOISE_KEPT`] over `70` [`TRIMMED_SECOND_MOMENT`]; `None` if empty.
fn trimmed_noise(mut d2: Vec<f64>) -> Option<f64> {
    if d2.is_empty() {
        return None;
    }
    let kept = ((d2.len() as f64 * SAMPLE_NOISE_KEPT).round() as usize).clamp(1, d2.len());
    if kept < d2.len() {
        d2.select_nth_unstable_by(kept - 1, f64::total_cmp);
    }
    let mean = d2[..kept].iter().sum::<f64>() / kept as f64;
    Some((mean / (70.0 * TRIMMED_SECOND_MOMENT)).sqrt())
}

/// The share of the fourth differences [`sample_noise`] keeps (the smallest).
pub const SAMPLE_NOISE_KEPT: f64 = 0.9;

/// `E[X² | |X| < q]` of a standard normal `X` at the quantile `q` below which lies
/// [`SAMPLE_NOISE_KEPT`] of `|X|` (`q = 1.6449`): `(p - 2q φ(q))/p`, `p = 0.9`.
pub const TRIMMED_SECOND_MOMENT: f64 = 0.623_015_484_134_683_4;

/// The relative variance of [`sample_noise`]'s `σ̂²` from `n` samples of noise with lag-1
/// correlation `phi` (AR(1)): the mean of `m = n - 4` squared fourth differences has
/// `2 Σ_l ρ_l² / m`, `ρ_l` their autocorrelation (white noise: `1, -0.8, 0.4, -0.11, 0.01`,
/// `Σ ρ² = 2.63`), and the trimming costs 19 % more (simulated: 12.8 % against 11.7 % in
/// `σ̂²` a trace at `n` = 400).
pub fn sample_noise_relative_variance(n: usize, phi: f64) -> f64 {
    const C: [f64; 5] = [1.0, -4.0, 6.0, -4.0, 1.0];
    let m = n.saturating_sub(4).max(1) as f64;
    let phi = if phi.is_finite() { phi.clamp(-0.95, 0.95) } else { 0.0 };
    // The fourth differences' autocovariance at lag `l`: `Σ_ab c_a c_b φ^|l + a - b|`.
    let gamma = |l: i32| -> f64 {
        let mut g = 0.0;
        for (a, ca) in (0i32..).zip(C) {
            for (b, cb) in (0i32..).zip(C) {
                g += ca * cb * phi.powi((l + a - b).abs());
            }
        }
        g
    };
    let g0 = gamma(0);
    let sum: f64 = 1.0 + 2.0 * (1..200).map(|l| (gamma(l) / g0).powi(2)).sum::<f64>();
    1.19 * 2.0 * sum / m
}

/// The size figures of one contour with their uncertainties.
#[derive(Debug, Clone, PartialEq)]
pub struct SizeReport {
    pub sizes: Sizes,
    /// Expanded (k = 2) uncertainty of `[C, A, B, FED]`.
    pub u95: [f64; 4],
    /// Expanded uncertainty of each equal-angle radius.
    pub radii_u95: Vec<f64>,
    /// The raw radii's scatter about the smooth fit, `σ_r`.
    pub noise: f64,
}

/// The figures of the contour whose equal-angle radii are `radii`, resampled from the
/// corrected `points` (the surface touched, one per raw sample) made by `correction`, with
/// uncertainties from `covariance` (the calibration's, certificates included; `None`:
/// unknown, the calibration's part left out) and the scan's own noise (module docs).
/// `radii_gain`: each radius' noise variance per unit variance of a sample's
/// ([`PolarContour::resample_with_gain`](super::correct::PolarContour::resample_with_gain);
/// empty: 1, as a sample's). `None` if there are too few radii.
pub fn uncertainty(
    points: &[Vector2<f64>],
    radii: &[f64],
    radii_gain: &[f64],
    correction: &Correction,
    covariance: Option<&DMatrix<f64>>,
) -> Option<SizeReport> {
    let m = radii.len();
    let tn = correction.noise;
    let big_n = points.len().max(1);
    // The noise's variance, σ², from what the fourth differences see of it (the
    // calibration's correlation), never below the quantum's.
    let quantum = tn.quantum / 12f64.sqrt();
    // Each point's angle and distance from the axis, once: the noise, the circumference's
    // series at the points' own angles and their spacing all read them.
    let polar = polar_form(points);
    let distances: Vec<f64> = polar.iter().map(|p| p.1).collect();
    let seen = sample_noise_of(&distances);
    let floor = (seen / tn.fourth_difference_share().sqrt()).max(quantum);
    // The fewest harmonics that leave only noise: the raw points' radial scatter about
    // the fit, each at its own angle (the resampled radii are interpolated, smoother than
    // the samples), against the noise their fourth differences show ([`sample_noise`]),
    // both as the noise's σ (the scatter sees the noise above the fit's harmonics only).
    // Sharp corners (a frame's 3 mm) need more than [`HARMONICS`]; more cost noise.
    let scatter = |smooth: &Smooth| {
        let k = smooth.harmonics();
        let s2 = smooth.squared_residuals(points) / points.len().saturating_sub(2 * k + 1).max(1) as f64;
        (s2 / tn.above_share(k, big_n)).sqrt().max(quantum)
    };
    let mut smooth = Smooth::fit(radii, HARMONICS)?;
    let mut noise = scatter(&smooth);
    for more in [60, 80, 100, 127] {
        if noise <= 1.2 * floor || more > m / 2 {
            break;
        }
        smooth = Smooth::fit(radii, more)?;
        noise = scatter(&smooth);
    }
    let k = smooth.harmonics();
    // The smooth holds the information of min(N, M) equal-angle values.
    let n = points.len().min(m).max(1);
    // The calibration's spread over the contour, when its covariance is given: the box's
    // sides take a tilt only beyond what it and the noise can make ([`raw_extreme`]).
    let grid = smooth.on_grid();
    let calibration = covariance.and_then(|cov| CalibrationSpread::new(cov, correction, &grid));
    let side_spread =
        |side: usize, weights: &[(f64, f64)]| calibration.as_ref().map_or(0.0, |cal| cal.side_variance(side, weights));
    let side_noise = SideNoise { sigma: noise, phi: tn.phi(), calibration: &side_spread };
    // The smooth's own ripple: 2K + 1 coefficients of n values.
    let mut sizes = Sizes::of_noisy_grid(grid, noise * ((2 * k + 1) as f64 / n as f64).sqrt(), points, &side_noise);
    let responses = sizes.harmonic_responses(k);
    let mut var_noise = [0.0; 4];
    for (i, g) in responses.iter().enumerate() {
        // A coefficient of harmonic kk (the responses to `cos kkθ`, then `sin kkθ`) has the
        // noise's density there (sample-to-sample correlation: `ω = 2π kk/N`).
        let kk = i.div_ceil(2);
        let weight = if i == 0 { 1.0 } else { 2.0 } * tn.density(TAU * kk as f64 / big_n as f64);
        for f in 0..4 {
            var_noise[f] += weight * g[f] * g[f];
        }
    }
    var_noise = var_noise.map(|v| v * noise * noise / n as f64);
    // The circumference from a finer smooth, its noise's lengthening taken off.
    // The noise for the circumference's lengthening from the fourth differences clear of
    // the shape's curvature jumps (a frame's corners reach about a tenth of them), its
    // relative variance as many times larger as fewer of them are left.
    let (seen_clear, left_out) = sample_noise_clear_of_shape(&polar, &smooth, seen);
    let floor_c = (seen_clear / tn.fourth_difference_share().sqrt()).max(quantum);
    let relative_variance = sample_noise_relative_variance(points.len(), tn.phi()) / (1.0 - left_out).max(0.05);
    let (circumference, var_circumference) = circumference(
        &polar,
        radii,
        circumference_harmonics(k),
        &sizes.grid,
        NoiseSeen { per_sample: floor_c * floor_c / n as f64, relative_variance, trace: &tn },
        correction,
    )?;
    sizes.circumference = circumference;
    var_noise[0] = var_circumference;
    // A side taken from the raw points has their noise alone (`Σ_ij a_i a_j φ^|i-j| σ²`,
    // the points in trace order), independent of the other side's; a side from the
    // smooth its harmonics'.
    let harmonics = sizes.side_harmonics(k);
    let phi = tn.phi();
    // The variance of a figure whose response to `cos kθ` and `sin kθ` is `c_k`, `s_k`
    // (each coefficient's noise weighted by the density at its harmonic).
    let harmonic_var = |cs: &mut dyn Iterator<Item = (f64, f64)>| -> f64 {
        let v: f64 = cs
            .enumerate()
            .map(|(kk, (c, s))| {
                let density = tn.density(TAU * kk as f64 / big_n as f64);
                if kk == 0 { c * c * density } else { 2.0 * (c * c + s * s) * density }
            })
            .sum();
        v * noise * noise / n as f64
    };
    let side_var = |k_side: usize| -> f64 {
        let side = &sizes.sides[k_side];
        if side.raw {
            // The noise moves a point off the contour by its radial scatter times `N·e_r`
            // (the radial offset at a fixed angle is the normal one over it), and at a
            // side the normal is the side's axis: `|cos θ|` for x, `|sin θ|` for y.
            let along = |t: f64| if k_side < 2 { t.cos() } else { t.sin() };
            correlated_sum(side.weights.iter().map(|(t, w)| w * along(*t)), phi) * noise * noise
        } else {
            harmonic_var(&mut harmonics[k_side].iter().copied())
        }
    };
    for (figure, pair) in [(1, [0, 1]), (2, [2, 3])] {
        if pair.iter().any(|&i| sizes.sides[i].raw) {
            var_noise[figure] = side_var(pair[0]) + side_var(pair[1]);
        }
    }
    // The FED: the farthest of its candidates ([`far_points`]). Each one's own noise (its
    // raw points' or the smooth's ripple there, along its direction `e_j`), the box
    // centre's, shared (`-e_j·δc`); the largest of noisy candidates is biased up where they
    // are near each other (a symmetric frame's four corners: by about one standard
    // deviation), so the FED is corrected by that bias and its variance is the largest's.
    let density_sum: f64 =
        (0..=k).map(|kk| if kk == 0 { 1.0 } else { 2.0 } * tn.density(TAU * kk as f64 / big_n as f64)).sum();
    let own: Vec<f64> = sizes
        .far
        .iter()
        .map(|f| match &f.raw {
            Some(weights) => correlated_sum(weights.iter().map(|w| w.1), phi) * floor * floor,
            None => {
                let along = f.angle.cos() * f.direction.x + f.angle.sin() * f.direction.y;
                along * along * density_sum * noise * noise / n as f64
            }
        })
        .collect();
    let raw_pair = |a: usize| sizes.sides[a].raw || sizes.sides[a + 1].raw;
    let centre_var = [0, 2].map(|pair| {
        if raw_pair(pair) {
            (side_var(pair) + side_var(pair + 1)) / 4.0
        } else {
            // The centre's coordinate, `(max - min)/2`.
            let half_difference = harmonics[pair].iter().zip(&harmonics[pair + 1]);
            harmonic_var(&mut half_difference.map(|(a, b)| ((a.0 - b.0) / 2.0, (a.1 - b.1) / 2.0)))
        }
    });
    let (far, var_far) = largest_of(&sizes.far, &own, centre_var);
    sizes.effective_diameter = 2.0 * far;
    var_noise[3] = 4.0 * var_far;
    // Repeated traces' radial spread, a uniform change of the radius.
    let uniform = sizes.response(|_| 1.0);
    let u_r = tn.reproducibility;
    for (v, g) in var_noise.iter_mut().zip(uniform) {
        *v += g * g * u_r * u_r;
    }
    let mut var_cal = [0.0; 4];
    let mut radii_var_cal = vec![0.0; m];
    if let Some(cal) = &calibration {
        let n = cal.n;
        let mut g = vec![[0.0; 4]; n];
        for (j, gj) in g.iter_mut().enumerate() {
            if cal.sigma[(j, j)] > 0.0 {
                *gj = sizes.response_on_grid(&cal.table.iter().skip(j).step_by(n).copied().collect::<Vec<_>>());
            }
        }
        for (f, v) in var_cal.iter_mut().enumerate() {
            *v = cal.quadratic(&g.iter().map(|gj| gj[f]).collect::<Vec<_>>());
        }
        // Each radius' own, read off the grid between its neighbours.
        let mut between = vec![0.0; n];
        for (i, v) in radii_var_cal.iter_mut().enumerate() {
            let (j, f) = grid_place(i as f64 * GRID as f64 / m as f64);
            let (a, b) = (cal.at(j), cal.at((j + 1) % GRID));
            between.iter_mut().enumerate().for_each(|(p, x)| *x = a[p] * (1.0 - f) + b[p] * f);
            *v = cal.quadratic(&between);
        }
    }
    // The groove angle assumed: the contour moves along its normal by `∂o/∂γ u_γ`, a
    // radius by that over `N·e_r = r/√(r² + r'²)`.
    let u_groove = correction.groove_offset_uncertainty();
    if u_groove > 0.0 {
        let along_normal: Vec<f64> = sizes.grid.iter().map(|&(r, rp)| (r * r + rp * rp).sqrt() / r).collect();
        let g = sizes.response_on_grid(&along_normal);
        for (v, g) in var_cal.iter_mut().zip(g) {
            *v += g * g * u_groove * u_groove;
        }
        for (i, v) in radii_var_cal.iter_mut().enumerate() {
            let (j, f) = grid_place(i as f64 * GRID as f64 / m as f64);
            let dr = along_normal[j] * (1.0 - f) + along_normal[(j + 1) % GRID] * f;
            *v += dr * dr * u_groove * u_groove;
        }
    }
    let u95 = [0, 1, 2, 3].map(|f| 2.0 * (var_cal[f] + var_noise[f]).max(0.0).sqrt());
    let radii_u95 = radii_var_cal
        .iter()
        .enumerate()
        .map(|(i, v)| {
            // Interpolating between two neighbours whose noise correlates by φ:
            // `(1-f)² + f² + 2f(1-f)φ` = gain + (1 - gain) φ.
            let gain = radii_gain.get(i).copied().unwrap_or(1.0);
            let gain = gain + (1.0 - gain) * phi;
            2.0 * (v + gain * floor * floor + u_r * u_r).max(0.0).sqrt()
        })
        .collect();
    let report = SizeReport { sizes, u95, radii_u95, noise };
    report.sizes.figures().iter().chain(&report.u95).all(|v| v.is_finite()).then_some(report)
}

/// The figures of a contour given as its points alone (a file's trace: no tracer, no
/// calibration), each a multiple of `quantum` metres in radius (a file's 1/100 mm): its
/// radii resampled to `m` equal angles, the figures and their noise's U95 as
/// [`uncertainty`] takes them (the smooth, the raw points' sides and far corners). `None`
/// if the points do not go round (a gap over 0.2 rad) or are too few.
pub fn of_contour(points: &[Vector2<f64>], m: usize, quantum: f64) -> Option<SizeReport> {
    let (radii, gain) = super::correct::resample_radii_with_gain(points, m, 0.2)?;
    let correction = Correction {
        mounting: Mounting::new(0.0, 0.0, 0.0),
        tip_radius: 0.0,
        traced: Traced::Outside,
        groove: Groove::default(),
        angle_orders: HarmonicOrders::NONE,
        noise: TraceNoise { quantum, ..TraceNoise::default() },
    };
    uncertainty(points, &radii, &gain, &correction, None)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ellipse_radii(a: f64, b: f64, m: usize) -> Vec<f64> {
        (0..m)
            .map(|i| {
                let t = TAU * i as f64 / m as f64;
                1.0 / ((t.cos() / a).powi(2) + (t.sin() / b).powi(2)).sqrt()
            })
            .collect()
    }

    #[test]
    fn a_circle_and_an_ellipse_have_their_sizes() {
        let circle = Sizes::of(&Smooth::fit(&vec![0.02; 400], 40).unwrap());
        assert!((circle.circumference - TAU * 0.02).abs() < 1e-12, "{}", circle.circumference);
        assert!((circle.box_width - 0.04).abs() < 1e-12 && (circle.box_height - 0.04).abs() < 1e-12);
        assert!((circle.effective_diameter - 0.04).abs() < 1e-12);
        let e = Sizes::of(&Smooth::fit(&ellipse_radii(0.025, 0.015, 400), 40).unwrap());
        // Ramanujan's second approximation, exact to 1e-10 relative here.
        let [c, ..] = crate::shape::Ellipse { center: Vector2::zeros(), a: 0.025, b: 0.015, angle: 0.0 }.exact_sizes();
        assert!((e.circumference - c).abs() < 1e-9, "{} vs {c}", e.circumference);
        assert!((e.box_width - 0.05).abs() < 1e-9 && (e.box_height - 0.03).abs() < 1e-9, "{e:?}");
        assert!((e.effective_diameter - 0.05).abs() < 1e-9);
    }

    /// A circle's smooth under white noise is longer by `π S₂/R` on average, as
    /// [`noise_lengthening`] says (a Monte Carlo of 2000 draws, within 4 of its standard
    /// errors), and an ellipse's by its own.
    #[test]
    fn the_noise_lengthens_a_smooth_as_predicted() {
        use rand::SeedableRng;
        use rand_distr::{Distribution, Normal};
        let mut rng = rand::rngs::StdRng::seed_from_u64(7);
        let (n, k, sigma) = (400, 60, 1e-5);
        let per_sample = sigma * sigma / n as f64;
        let s0 = per_sample * (1 + 2 * k) as f64;
        let s2 = per_sample * (1..=k).map(|j| 2.0 * (j * j) as f64).sum::<f64>();
        for base in [vec![0.021; n], ellipse_radii(0.026, 0.016, n)] {
            let exact = Sizes::of(&Smooth::fit(&base, k).unwrap());
            let predicted = noise_lengthening(exact.grid(), s0, s2);
            let noise = Normal::new(0.0, sigma).unwrap();
            let draws: Vec<f64> = (0..2000)
                .map(|_| {
                    let noisy: Vec<f64> = base.iter().map(|r| r + noise.sample(&mut rng)).collect();
                    Sizes::of(&Smooth::fit(&noisy, k).unwrap()).circumference - exact.circumference
                })
                .collect();
            let mean = draws.iter().sum::<f64>() / draws.len() as f64;
            let sd = (draws.iter().map(|d| (d - mean).powi(2)).sum::<f64>() / (draws.len() - 1) as f64).sqrt();
            let se = sd / (draws.len() as f64).sqrt();
            assert!(predicted > 4e-6 && predicted < 8e-6, "{predicted}");
            assert!((mean - predicted).abs() < 4.0 * se, "mean {mean:e} vs predicted {predicted:e} (se {se:e})");
        }
        // A circle: π S₂ / R.
        let circle = Sizes::of(&Smooth::fit(&vec![0.021; n], k).unwrap());
        let closed = std::f64::consts::PI * s2 / 0.021;
        assert!((noise_lengthening(circle.grid(), s0, s2) - closed).abs() < 1e-9 * closed);
    }

    #[test]
    fn responses_match_finite_differences() {
        let base = ellipse_radii(0.025, 0.016, 400);
        let sizes = Sizes::of(&Smooth::fit(&base, 40).unwrap());
        let bump = |t: f64| 1e-3 * (0.3 + (2.0 * t).cos() + 0.5 * (3.0 * t + 0.4).sin());
        let eps = 1e-6;
        let moved: Vec<f64> = base.iter().enumerate().map(|(i, r)| r + eps * bump(TAU * i as f64 / 400.0)).collect();
        let after = Sizes::of(&Smooth::fit(&moved, 40).unwrap()).figures();
        let predicted = sizes.response(|t| eps * bump(t));
        for f in 0..4 {
            let numeric = after[f] - sizes.figures()[f];
            assert!(
                (numeric - predicted[f]).abs() < 1e-3 * numeric.abs() + 1e-13,
                "figure {f}: {numeric} vs {}",
                predicted[f]
            );
        }
    }

    #[test]
    fn the_largest_of_normals_has_clarks_moments() {
        assert!((normal_cdf(1.959_963_985) - 0.975).abs() < 1e-7);
        assert!((normal_cdf(0.0) - 0.5).abs() < 1e-7 && (normal_cdf(-3.0) - 0.001_349_898).abs() < 1e-7);
        // Two independent standard normals: E max = 1/√π, var = 1 - 1/π.
        let (m, v) = largest_normal(&[0.0, 0.0], &[1.0, 1.0]);
        assert!(
            (m - 1.0 / std::f64::consts::PI.sqrt()).abs() < 1e-6
                && (v - (1.0 - 1.0 / std::f64::consts::PI)).abs() < 1e-6
        );
        // Far apart: the larger alone; four equal: about 1.03 (exactly 1.0294), Clark's within 1 %.
        let (m, v) = largest_normal(&[0.0, -20.0], &[1.0, 1.0]);
        assert!(m.abs() < 1e-9 && (v - 1.0).abs() < 1e-9);
        let (m, _) = largest_normal(&[0.0; 4], &[1.0; 4]);
        assert!((m - 1.0294).abs() < 0.011, "{m}");
    }

    #[test]
    fn a_circle_through_an_arc_is_found() {
        let (a, r) = (Vector2::new(0.021, 0.011), 0.005);
        let arc: Vec<Vector2<f64>> = (0..7)
            .map(|i| a + Vector2::new((0.3 + 0.08 * i as f64).cos(), (0.3 + 0.08 * i as f64).sin()) * r)
            .collect();
        let (centre, radius) = fit_circle(&arc).unwrap();
        assert!((centre - a).norm() < 1e-12 && (radius - r).abs() < 1e-12, "{centre} {radius}");
        // Its far point from the origin, with a weight on each of the seven points: the
        // first-order change of the far point when each point moves along its radius.
        let e = a.normalize();
        let (value, weights) = raw_far(&arc, Vector2::zeros(), e).unwrap();
        assert!((value - (a.norm() + r)).abs() < 1e-12);
        assert_eq!(weights.len(), 7);
        for k in 0..7 {
            let mut moved = arc.clone();
            moved[k] = arc[k] + arc[k].normalize() * 1e-7;
            let (changed, _) = raw_far(&moved, Vector2::zeros(), e).unwrap();
            let w = weights.iter().find(|(t, _)| (t - arc[k].y.atan2(arc[k].x)).abs() < 1e-12).unwrap().1;
            assert!(((changed - value) / 1e-7 - w).abs() < 1e-4, "point {k}: {} against {w}", (changed - value) / 1e-7);
        }
    }

    /// Four equally far candidates with unit noise: the plain largest is biased up by about
    /// one standard deviation; [`largest_of`]'s estimate is not, and its variance is its
    /// spread's.
    #[test]
    fn the_largest_of_equal_candidates_is_corrected_for_its_bias() {
        use rand::SeedableRng;
        use rand_distr::{Distribution, StandardNormal};
        let mut rng = rand::rngs::StdRng::seed_from_u64(3);
        let directions =
            [(1.0, 1.0), (-1.0, 1.0), (-1.0, -1.0), (1.0, -1.0)].map(|(x, y)| Vector2::new(x, y).normalize());
        let trials = 200;
        let (mut plain, mut corrected, mut sq, mut stated) = (0.0, 0.0, 0.0, 0.0);
        for _ in 0..trials {
            let far: Vec<FarPoint> = directions
                .iter()
                .map(|&direction| {
                    let z: f64 = StandardNormal.sample(&mut rng);
                    FarPoint { value: 10.0 + z, angle: 0.0, direction, raw: None }
                })
                .collect();
            plain += far.iter().map(|f| f.value).fold(f64::MIN, f64::max) - 10.0;
            let (v, var) = largest_of(&far, &[1.0; 4], [0.0; 2]);
            corrected += v - 10.0;
            sq += (v - 10.0).powi(2);
            stated += var;
        }
        let n = trials as f64;
        let (plain, corrected) = (plain / n, corrected / n);
        let spread = (sq / n - corrected * corrected).sqrt();
        let stated = (stated / n).sqrt();
        assert!((0.85..1.2).contains(&plain), "the plain largest: {plain}");
        assert!(corrected.abs() < 0.3, "corrected: {corrected}");
        assert!((stated / spread - 1.0).abs() < 0.25, "stated {stated}, spread {spread}");
    }

    /// The distance from the origin of a 52 × 32 mm box with 5 mm corners, centred, along
    /// the ray at `t` (bisection on its signed distance).
    fn frame_radius(t: f64) -> f64 {
        let (hw, hh, rc) = (0.026, 0.016, 0.005);
        let sdf = |x: f64, y: f64| {
            let (qx, qy) = (x.abs() - (hw - rc), y.abs() - (hh - rc));
            qx.max(0.0).hypot(qy.max(0.0)) + qx.max(qy).min(0.0) - rc
        };
        let (mut lo, mut hi) = (0.0, 0.05);
        for _ in 0..60 {
            let mid = 0.5 * (lo + hi);
            if sdf(mid * t.cos(), mid * t.sin()) < 0.0 { lo = mid } else { hi = mid }
        }
        0.5 * (lo + hi)
    }

    /// Through points at their own, unequal angles the fixed point finds the series a
    /// band-limited contour is, where the series of the resampled radii misses it by the
    /// cubic's error.
    #[test]
    fn the_series_at_the_points_own_angles_is_the_contours() {
        let r = |t: f64| 0.02 + 0.003 * (2.0 * t).cos() + 0.001 * (3.0 * t).sin() + 0.0002 * (17.0 * t).cos();
        let points: Vec<Vector2<f64>> = (0..400)
            .map(|i| {
                let step = i as f64 + 0.3 + 0.25 * (TAU * 3.0 * i as f64 / 400.0).sin();
                let t = TAU * step / 400.0;
                Vector2::new(t.cos(), t.sin()) * r(t)
            })
            .collect();
        let (radii, _) = super::super::correct::resample_radii_with_gain(&points, 400, 0.2).unwrap();
        let worst =
            |s: &Smooth| (0..360).map(|i| TAU * i as f64 / 360.0).map(|t| (s.at(t).0 - r(t)).abs()).fold(0.0, f64::max);
        let resampled = worst(&Smooth::fit(&radii, 40).unwrap());
        let own = worst(&series_at_own_angles(&polar_form(&points), &radii, 40).unwrap());
        assert!(own < 1e-10 && own * 100.0 < resampled, "own angles {own}, resampled {resampled}");
    }

    /// A frame's corners put their shape into the fourth differences; left out, the noise
    /// reads within 1 % of what it reads on a circle (2000 traces each at σ = 10 µm,
    /// samples a third of a step off the resampling's angles), on which none is left out.
    #[test]
    fn the_noise_clear_of_a_frames_corners_is_unbiased() {
        use rand::SeedableRng;
        use rand_distr::{Distribution, StandardNormal};
        let mut rng = rand::rngs::StdRng::seed_from_u64(3);
        let sigma = 10e-6;
        let mut read = Vec::new();
        for frame in [false, true] {
            let (mut plain, mut clear, mut left_out) = (0.0, 0.0, 0.0);
            let traces = 2000;
            for _ in 0..traces {
                let points: Vec<Vector2<f64>> = (0..400)
                    .map(|i| {
                        let t = TAU * (i as f64 + 0.37) / 400.0;
                        let e: f64 = StandardNormal.sample(&mut rng);
                        Vector2::new(t.cos(), t.sin()) * (if frame { frame_radius(t) } else { 0.02 } + sigma * e)
                    })
                    .collect();
                let (radii, _) = super::super::correct::resample_radii_with_gain(&points, 400, 0.2).unwrap();
                let smooth = Smooth::fit(&radii, if frame { 60 } else { 40 }).unwrap();
                let seen = sample_noise(&points);
                let (noise, out) = sample_noise_clear_of_shape(&polar_form(&points), &smooth, seen);
                plain += (seen / sigma).powi(2) / traces as f64;
                clear += (noise / sigma).powi(2) / traces as f64;
                left_out += out / traces as f64;
            }
            read.push((plain, clear, left_out));
        }
        // The frame's excess over the circle's (the same noise, the estimator's own bias
        // taken out): 1.6 % plain, 0.6 % clear of the corners, a fifth of the differences out.
        let ((_, circle, none), (plain, clear, left_out)) = (read[0], read[1]);
        assert_eq!(none, 0.0);
        assert!(clear - circle < 0.01 && plain - clear > 0.005, "{plain} {clear} {circle}");
        assert!((0.1..0.3).contains(&left_out), "{left_out}");
    }

    /// The noise along a rail through the axis is radial; off the axis, on a circle (the
    /// normal radial) the radius at a fixed angle and the point's distance see it alike.
    #[test]
    fn a_rail_off_the_axis_shares_its_noise_by_how_it_meets_the_contour() {
        let mut c = Correction {
            mounting: Mounting::new(0.0, 0.0, 0.0),
            tip_radius: 0.0,
            traced: Traced::Outside,
            groove: Groove::default(),
            angle_orders: HarmonicOrders::NONE,
            noise: TraceNoise::default(),
        };
        let (a, b) = c.noise_share(0.02, 0.0, (0.6, 0.8));
        assert!((a - 1.0).abs() < 1e-12 && (b - 1.0).abs() < 1e-12);
        c.mounting = Mounting::new(0.0, 0.005, 0.0);
        let (a, b) = c.noise_share(0.02, 0.0, (0.6, 0.8));
        assert!((a - b).abs() < 1e-12 && (b - (1.0 - 0.25f64.powi(2))).abs() < 1e-9, "{a} {b}");
        // On a flat side met obliquely the two differ, by side.
        let (a1, b1) = c.noise_share(0.02, 0.01, (0.6, 0.8));
        let (a2, b2) = c.noise_share(0.02, -0.01, (0.6, 0.8));
        assert!((b1 - b2).abs() < 1e-12 && (a1 - a2).abs() > 0.05, "{a1} {a2}");
    }

    /// The samples' noise from their trimmed fourth differences is unbiased and spreads as
    /// [`sample_noise_relative_variance`] says, for white and correlated noise (AR(1)), on
    /// a circle of 400 samples, 3000 traces each (the spread's own standard error: 1.3 %).
    #[test]
    fn the_sample_noise_is_unbiased_and_spreads_as_stated() {
        use rand::SeedableRng;
        use rand_distr::{Distribution, StandardNormal};
        let mut rng = rand::rngs::StdRng::seed_from_u64(11);
        for phi in [0.0, 0.5] {
            let traces = 3000;
            let mut v = Vec::with_capacity(traces);
            for _ in 0..traces {
                let mut e = 0.0;
                let points: Vec<Vector2<f64>> = (0..400)
                    .map(|i| {
                        let z: f64 = StandardNormal.sample(&mut rng);
                        e = phi * e + (1.0f64 - phi * phi).sqrt() * z;
                        let (s, c) = (TAU * i as f64 / 400.0).sin_cos();
                        Vector2::new(c, s) * (0.02 + 10e-6 * e)
                    })
                    .collect();
                let share = TraceNoise { lag1: phi, ..TraceNoise::default() }.fourth_difference_share();
                v.push((sample_noise(&points) / 10e-6).powi(2) / share);
            }
            let mean = v.iter().sum::<f64>() / traces as f64;
            let spread = (v.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / traces as f64).sqrt();
            let stated = sample_noise_relative_variance(400, phi).sqrt();
            assert!((mean - 1.0).abs() < 0.01, "φ {phi}: σ̂²/σ² {mean}");
            assert!((spread / stated - 1.0).abs() < 0.06, "φ {phi}: spread {spread}, stated {stated}");
        }
    }

    /// A raw side's reported noise (`Σ w² σ²` of the points the smooth chose) is its
    /// spread, and it is unbiased: the top of a 20 mm circle with radial noise, as a lens
    /// side at σ = 10 µm has it (6-8 points), 2000 times.
    #[test]
    fn a_raw_side_is_unbiased_and_its_weights_tell_its_variance() {
        use rand::SeedableRng;
        use rand_distr::{Distribution, Normal};
        let mut rng = rand::rngs::StdRng::seed_from_u64(1);
        let sigma = 10e-6;
        let noise = Normal::new(0.0, sigma).unwrap();
        let (mut sum, mut sq, mut reported, mut n) = (0.0, 0.0, 0.0, 0.0);
        for _ in 0..2000 {
            let points: Vec<Vector2<f64>> = (0..400)
                .map(|i| {
                    let t = TAU * i as f64 / 400.0;
                    Vector2::new(t.cos(), t.sin()) * (0.02 + noise.sample(&mut rng))
                })
                .collect();
            let side = raw_extreme(
                &points,
                &|_| 0.02,
                &|_| 50.0,
                2,
                0.02,
                3.6 * sigma,
                &SideNoise { sigma, ..SideNoise::QUIET },
            )
            .unwrap();
            let e = side.value - 0.02;
            (sum, sq, n) = (sum + e, sq + e * e, n + 1.0);
            reported += side.weights.iter().map(|(_, w)| w * w).sum::<f64>() * sigma * sigma;
        }
        let (bias, spread, told) = (sum / n, (sq / n - (sum / n).powi(2)).sqrt(), (reported / n).sqrt());
        assert!(bias.abs() < 0.1 * spread, "bias {bias:e} for a spread of {spread:e}");
        assert!((told / spread - 1.0).abs() < 0.06, "told {told:e}, seen {spread:e}");
    }

    /// A quiet trace of a flat side whose smooth overshoots it by more than its noise band
    /// (the truncated harmonics where a frame's side meets its corner): the side is still the
    /// raw points', not the smooth's overshoot (once +9.4 µm of B, noise-free, 52 × 32 mm).
    #[test]
    fn a_quiet_flat_side_is_the_points_not_the_smooths_overshoot() {
        // The line y = 0.015 over ±40°, points 0.9° apart.
        let points: Vec<Vector2<f64>> = (-44..=44)
            .map(|i| {
                let t = std::f64::consts::FRAC_PI_2 + (i as f64 * 0.9).to_radians();
                Vector2::new(t.cos(), t.sin()) * (0.015 / t.sin())
            })
            .collect();
        // A smooth 9 µm above the side at its ends, 1 µm above mid-way.
        let smooth = |t: f64| {
            let u = (t - std::f64::consts::FRAC_PI_2) / 40f64.to_radians();
            (0.015 + 1e-6 + 8e-6 * u.powi(8)) / t.sin()
        };
        let near = 0.015 + 9e-6;
        let side =
            raw_extreme(&points, &smooth, &|_| 0.0, 2, near, 0.5e-6, &SideNoise { sigma: 0.1e-6, ..SideNoise::QUIET })
                .unwrap();
        assert!(side.raw);
        assert!((side.value - 0.015).abs() < 1e-9, "side {} µm off", (side.value - 0.015) * 1e6);
    }

    /// A flat side's band wide enough to take in its corners' shoulders (a 52 × 32 mm box,
    /// 5 mm corners, a band of 45 µm: σ = 10 µm's): the side is the flat's, not lifted by
    /// the shoulders falling away at both ends (which [`off_the_corners`] leaves out).
    #[test]
    fn a_flat_sides_corners_do_not_lift_it() {
        let (hw, hh, r) = (0.026, 0.016, 0.005);
        let sdf = |p: Vector2<f64>| {
            let q = Vector2::new(p.x.abs() - (hw - r), p.y.abs() - (hh - r));
            Vector2::new(q.x.max(0.0), q.y.max(0.0)).norm() + q.x.max(q.y).min(0.0) - r
        };
        let radius = |t: f64| {
            let u = Vector2::new(t.cos(), t.sin());
            let (mut lo, mut hi) = (0.0, 0.1);
            for _ in 0..80 {
                let mid = 0.5 * (lo + hi);
                if sdf(u * mid) < 0.0 { lo = mid } else { hi = mid }
            }
            0.5 * (lo + hi)
        };
        let points: Vec<Vector2<f64>> = (0..400)
            .map(|i| {
                let t = TAU * (i as f64 + 0.3) / 400.0;
                Vector2::new(t.cos(), t.sin()) * radius(t)
            })
            .collect();
        // The box's curvature: 0 on its flats, 1/r on its corners' arcs.
        let bend = |t: f64| {
            let p = Vector2::new(t.cos(), t.sin()) * radius(t);
            if p.x.abs() > hw - r && p.y.abs() > hh - r { 1.0 / r } else { 0.0 }
        };
        let side = raw_extreme(&points, &radius, &bend, 2, hh, 45e-6, &SideNoise { sigma: 10e-6, ..SideNoise::QUIET })
            .unwrap();
        assert!((side.value - hh).abs() < 0.05e-6, "side {:+.3} µm off", (side.value - hh) * 1e6);
    }
}
