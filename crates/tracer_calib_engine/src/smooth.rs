//! A closed contour about the axis as a smooth curve: its radius `r(θ)` as a Fourier
//! series of `K` harmonics fitted to equal-angle radii (the sizes of
//! [`super::size`](mod@super::size), and the normals the stylus's offset takes,
//! [`super::stylus`]).

use nalgebra::Vector2;
use realfft::RealFftPlanner;
use realfft::num_complex::Complex;
use std::f64::consts::TAU;

/// Angles the figures are evaluated at.
pub const GRID: usize = 256;

/// A contour's smooth fit, `r(θ)` as a Fourier series (module docs).
#[derive(Debug, Clone, PartialEq)]
pub struct Smooth {
    /// `a_0`, then `a_k`, `b_k` for `k = 1..K`.
    coefficients: Vec<f64>,
}

impl Smooth {
    /// The first `harmonics` harmonics of equal-angle radii (`radii[m]` at `2π m/M`), at
    /// most `M/2 - 1` and fewer than `GRID/2`: from the DFT `X_k = Σ_m r_m e^{-2πi mk/M}`,
    /// `a_0 = X_0/M`, `a_k = 2 Re X_k/M`, `b_k = -2 Im X_k/M`. `None` for fewer than 8 radii.
    pub fn fit(radii: &[f64], harmonics: usize) -> Option<Smooth> {
        let m = radii.len();
        if m < 8 {
            return None;
        }
        let k_max = harmonics.clamp(1, (m / 2 - 1).min(GRID / 2 - 1)); // m >= 8: a bound of 2 or more
        let spectrum = forward_dft(radii)?;
        let scale = 2.0 / m as f64;
        let mut coefficients = Vec::with_capacity(2 * k_max + 1);
        coefficients.push(spectrum[0].re / m as f64);
        for x in &spectrum[1..=k_max] {
            coefficients.extend([x.re * scale, -x.im * scale]);
        }
        Some(Smooth { coefficients })
    }

    /// Harmonics `K`.
    pub fn harmonics(&self) -> usize {
        (self.coefficients.len() - 1) / 2
    }

    /// `r` and `r'` at `θ`.
    pub fn at(&self, theta: f64) -> (f64, f64) {
        let (s1, c1) = theta.sin_cos();
        let (mut c, mut s) = (1.0, 0.0);
        let (mut r, mut dr) = (self.coefficients[0], 0.0);
        for k in 1..=self.harmonics() {
            (c, s) = (c * c1 - s * s1, s * c1 + c * s1);
            let (a, b) = (self.coefficients[2 * k - 1], self.coefficients[2 * k]);
            r += a * c + b * s;
            dr += k as f64 * (b * c - a * s);
        }
        (r, dr)
    }

    /// `r` and `r'` at the [`GRID`] angles, by two inverse FFTs: `r_i = Σ_k Y_k e^{ikθ_i}`
    /// over the Hermitian spectrum with `Y_0 = a_0`, `Y_k = (a_k - i b_k)/2`, and for `r'`,
    /// `Y'_k = k (b_k + i a_k)/2`.
    pub(super) fn on_grid(&self) -> Vec<(f64, f64)> {
        let y = self.values_spectrum(GRID);
        let yp = self.spectrum(GRID, |k, a, b| Complex::new(k * b / 2.0, k * a / 2.0));
        match (inverse_dft(y), inverse_dft(yp)) {
            (Some(r), Some(rp)) => r.into_iter().zip(rp).collect(),
            // Not reached (the plan's own lengths); the sums themselves, then.
            _ => grid_unit().iter().map(|(c, s)| self.at(s.atan2(*c))).collect(),
        }
    }

    /// `r` at the [`FINE`] angles `2π i/FINE` (the spectrum zero-padded, one inverse FFT).
    pub(super) fn on_fine_grid(&self) -> Vec<f64> {
        inverse_dft(self.values_spectrum(FINE))
            .unwrap_or_else(|| (0..FINE).map(|i| self.at(TAU * i as f64 / FINE as f64).0).collect())
    }

    /// `r'''` at the [`GRID`] angles: `Σ_k k³ (a_k sin kθ - b_k cos kθ)`.
    pub(super) fn third_derivative_on_grid(&self) -> Vec<f64> {
        let y = self.spectrum(GRID, |k, a, b| Complex::new(-k * k * k * b / 2.0, -k * k * k * a / 2.0));
        inverse_dft(y).unwrap_or_else(|| vec![0.0; GRID])
    }

    /// The first half (`0..=n/2`) of the Hermitian spectrum of `n` equal-angle values of a
    /// derivative of the series: `Y_k = term(k, a_k, b_k)` for `k = 1..=K`, `Y_0 = 0`.
    fn spectrum(&self, n: usize, term: impl Fn(f64, f64, f64) -> Complex<f64>) -> Vec<Complex<f64>> {
        let mut y = vec![Complex::new(0.0, 0.0); n / 2 + 1];
        for (k, yk) in y.iter_mut().enumerate().skip(1).take(self.harmonics().min(n / 2 - 1)) {
            *yk = term(k as f64, self.coefficients[2 * k - 1], self.coefficients[2 * k]);
        }
        y
    }

    /// [`Self::spectrum`] of the series' own values: `Y_0 = a_0`, `Y_k = (a_k - i b_k)/2`.
    fn values_spectrum(&self, n: usize) -> Vec<Complex<f64>> {
        let mut y = self.spectrum(n, |_, a, b| Complex::new(a / 2.0, -b / 2.0));
        y[0].re = self.coefficients[0];
        y
    }

    /// `Σ (|p| - r(θ_p))²` over `points` (`θ_p` the angle of `p`, whose cosine and sine
    /// are `p/|p|`), LANES points at a time.
    pub(super) fn squared_residuals(&self, points: &[Vector2<f64>]) -> f64 {
        let mut sum = 0.0;
        for ps in points.chunks(LANES) {
            let mut norm = [1.0; LANES];
            let (mut c1, mut s1) = ([1.0; LANES], [0.0; LANES]);
            for (l, p) in ps.iter().enumerate() {
                norm[l] = p.norm();
                if norm[l] > 0.0 {
                    (c1[l], s1[l]) = (p.x / norm[l], p.y / norm[l]);
                }
            }
            let mut r = [self.coefficients[0]; LANES];
            let (mut c, mut s) = ([1.0; LANES], [0.0; LANES]);
            for k in 1..=self.harmonics() {
                rotate(&mut c, &mut s, &c1, &s1);
                let (a, b) = (self.coefficients[2 * k - 1], self.coefficients[2 * k]);
                for l in 0..LANES {
                    r[l] += a * c[l] + b * s[l];
                }
            }
            sum += (0..ps.len()).map(|l| (norm[l] - r[l]).powi(2)).sum::<f64>();
        }
        sum
    }
}

thread_local! {
    /// FFT plans, made once per length (and thread) and kept.
    static FFT: std::cell::RefCell<RealFftPlanner<f64>> = std::cell::RefCell::new(RealFftPlanner::new());
}

/// The DFT of real `values`: `X_k = Σ_i f_i e^{-2πi ik/n}`, `k = 0..=n/2`.
pub(super) fn forward_dft(values: &[f64]) -> Option<Vec<Complex<f64>>> {
    FFT.with(|planner| {
        let fft = planner.borrow_mut().plan_fft_forward(values.len());
        let mut input = values.to_vec();
        let mut output = fft.make_output_vec();
        fft.process(&mut input, &mut output).ok()?;
        Some(output)
    })
}

/// The `n` real values `f_i = Σ_k Y_k e^{2πi ik/n}` (over the Hermitian spectrum whose
/// first half, `k = 0..=n/2`, is `spectrum`, `n/2 + 1` long; `Y_0` and `Y_{n/2}` real).
fn inverse_dft(mut spectrum: Vec<Complex<f64>>) -> Option<Vec<f64>> {
    FFT.with(|planner| {
        let fft = planner.borrow_mut().plan_fft_inverse(2 * spectrum.len().saturating_sub(1));
        let mut output = fft.make_output_vec();
        fft.process(&mut spectrum, &mut output).ok()?;
        Some(output)
    })
}

/// How many equal angles [`Smooth::on_fine_grid`] samples a series at: enough to read it
/// between them by a cubic ([`read_fine`]).
pub(super) const FINE: usize = 2048;

/// A series sampled by [`Smooth::on_fine_grid`], read at angle `t` by the cubic through
/// the four samples about it (Lagrange). For the grid's top harmonic (127, `ωh` = 0.39 a
/// sample) within `(ωh)⁴/24 · 9/16` = 5·10⁻⁴ of its amplitude; for a contour's first ten
/// harmonics, 10⁻⁸ of theirs.
pub(super) fn read_fine(fine: &[f64], t: f64) -> f64 {
    let n = fine.len();
    let x = t.rem_euclid(TAU) / TAU * n as f64;
    let i = x.floor() as usize;
    let f = x - i as f64;
    let at = |j: usize| fine[(i + n + j - 1) % n];
    let w0 = -f * (f - 1.0) * (f - 2.0) / 6.0;
    let w1 = (f + 1.0) * (f - 1.0) * (f - 2.0) / 2.0;
    let w2 = -(f + 1.0) * f * (f - 2.0) / 2.0;
    let w3 = (f + 1.0) * f * (f - 1.0) / 6.0;
    w0 * at(0) + w1 * at(1) + w2 * at(2) + w3 * at(3)
}

/// `(cos θ_i, sin θ_i)` of the [`GRID`] angles `θ_i = 2π i/GRID`, computed once.
pub(super) fn grid_unit() -> &'static [(f64, f64); GRID] {
    static UNIT: std::sync::OnceLock<[(f64, f64); GRID]> = std::sync::OnceLock::new();
    UNIT.get_or_init(|| {
        std::array::from_fn(|i| {
            let (s, c) = (TAU * i as f64 / GRID as f64).sin_cos();
            (c, s)
        })
    })
}

/// Where a place `x` on the grid, counted in grid steps from angle 0, lies: between grid
/// angles `i` and `i + 1` (round the end), the fraction `f` of the way (what the readings
/// between grid angles interpolate with).
pub(super) fn grid_place(x: f64) -> (usize, f64) {
    (x.floor() as usize % GRID, x - x.floor())
}

/// A reading given at the grid angles (`value(i)` at angle `i·2π/GRID`) at the angle `t`,
/// linearly between its two neighbours.
pub(super) fn between_grid_angles(t: f64, value: impl Fn(usize) -> f64) -> f64 {
    let (i, f) = grid_place(t.rem_euclid(TAU) / (TAU / GRID as f64));
    value(i) * (1.0 - f) + value((i + 1) % GRID) * f
}

/// Points taken together in [`Smooth::squared_residuals`]: independent rotations side by
/// side (instruction-level parallelism, and SIMD where the compiler finds it).
const LANES: usize = 4;

/// One step of `LANES` rotations: `(c, s) ← (c c1 - s s1, s c1 + c s1)`, i.e. from
/// `cos kθ`, `sin kθ` to `cos (k+1)θ`, `sin (k+1)θ`.
#[inline(always)]
fn rotate(c: &mut [f64; LANES], s: &mut [f64; LANES], c1: &[f64; LANES], s1: &[f64; LANES]) {
    for l in 0..LANES {
        (c[l], s[l]) = (c[l] * c1[l] - s[l] * s1[l], s[l] * c1[l] + c[l] * s1[l]);
    }
}
