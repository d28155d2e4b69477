//! Does a fit leave structure in an artefact's residuals? A test of their low harmonics
//! round the turn against the scan's own noise.
//!
//! What a model lacks is smooth round the turn: a turntable whose angle is off once a
//! turn (a disc or gear eccentricity) or twice (an elliptic disc, a bearing) leaves, on a
//! square plate whose radius `R(θ)` has the plate's four-fold harmonics, a residual
//! `R'(θ) ε(θ)` at harmonics `m ± 4, m ± 8` (once a turn: 3, 5, 7, 9; twice: 2, 6, 10); a
//! plate of the wrong size or corner radius, a stylus tip or an encoder scale left out
//! show at 4, 8 and 12. Noise spreads over all harmonics. A residual RMS against the noise
//! between neighbouring samples (the older check) lets tens of micrometres of such
//! structure through; this test sees a few.
//!
//! The residuals `r_k` of a turn of `N` angle steps, in step order (a sample the fit left
//! out, or a missing step, filled in linearly from its neighbours; a scan with more than a
//! tenth of its steps so filled is not tested), and their periodogram
//! `I_h = |Σ_k r_k e^{-2πihk/N}|² / N`:
//!
//! 1. **The noise's spectrum, from the harmonics above the tested ones**, `h = H+1 … N/2-1`
//!    (`H` = [`HARMONICS`]): an AR(1) spectrum `S(ω) = σ_w² / |1 - φ e^{-iω}|²` fitted by
//!    Whittle's likelihood (`σ_w²` in closed form for each `φ`, `φ` by a search over
//!    [-0.9, 0.95]). White noise gives `φ ≈ 0`, a flat spectrum; noise correlated along
//!    the trace (stick-slip, interpolation error) crowds its power into the low harmonics,
//!    and the fitted `φ` carries that down to them, so it is not taken for structure.
//!    Structure below `H` does not enter the estimate at all. Since `S` at the low
//!    harmonics grows fast with `φ` (as `1/(1-φ)²`), the test takes the `φ` at the upper
//!    end of its one-sided 95 % likelihood interval (the negative log-likelihood within
//!    1.35 of its least): the most low-harmonic noise the high harmonics allow.
//! 2. **The test**: under noise alone each `2 I_h / S(ω_h)` is `χ²₂`, so
//!    `T = Σ_{h=1..H} 2 I_h / Ŝ(ω_h)` is `χ²_{2H}`; with `Ŝ` estimated from `M` ordinates,
//!    `(T / 2H)` is taken as `F(2H, 2M)` and `p = P(F > T/2H)` ([`f_survival`]). The fit
//!    already took out what its parameters can explain (a plate centre looks like harmonic
//!    1), so under the null `T` runs a little below its distribution: the test is
//!    conservative (it refuses fewer clean scans than its level).
//!
//! A scan refused by it names the harmonics that stand out and what they usually mean
//! ([`Structure::describe`]). Structure whose RMS is below [`STRUCTURE_FLOOR`] is never
//! refused: it is below anything an edger sees, and a noise-free simulation would
//! otherwise fail on the model's round-off.

use realfft::RealFftPlanner;

/// Harmonics tested: 1 to 12 a turn.
pub const HARMONICS: usize = 12;

/// Structure below this RMS (metres) is not refused, whatever its significance.
pub const STRUCTURE_FLOOR: f64 = 0.5e-6;

/// The largest fraction of a turn's steps filled in from their neighbours.
const MAX_FILLED: f64 = 0.1;

/// What the test found in one scan's residuals.
#[derive(Debug, Clone, PartialEq)]
pub struct Structure {
    /// `T / 2H` and its F degrees of freedom `(2H, 2M)`.
    pub f: f64,
    pub dof: (usize, usize),
    /// `P(F > f)` under the hypothesis of no structure.
    pub p_value: f64,
    /// Amplitude of each harmonic `h = 1..=H` (metres): `2 |X_h| / N`.
    pub amplitudes: Vec<f64>,
    /// What noise alone gives at each harmonic, as an amplitude (metres): `√(4 Ŝ(ω_h) / N)`.
    pub noise_amplitudes: Vec<f64>,
    /// RMS of the harmonics' sum round the turn (metres): `√(Σ A_h² / 2)`.
    pub rms: f64,
    /// The lag-1 correlation of the noise, as fitted (`φ`).
    pub lag1: f64,
    /// The noise's standard deviation, as fitted: `σ_w / √(1 - φ²)` (metres).
    pub noise: f64,
}

impl Structure {
    /// Does it show structure at significance level `alpha`? (Never below
    /// [`STRUCTURE_FLOOR`]; never for `alpha` 0.)
    pub fn refused_at(&self, alpha: f64) -> bool {
        self.p_value < alpha && self.rms > STRUCTURE_FLOOR
    }

    /// The harmonics that stand out (above three times what noise gives there), largest
    /// first, with what they usually mean on a square plate.
    pub fn describe(&self) -> String {
        // (harmonic, amplitude, noise's amplitude), largest first; those that stand out, or
        // else the three largest.
        let mut ranked: Vec<(usize, f64, f64)> =
            self.amplitudes.iter().zip(&self.noise_amplitudes).enumerate().map(|(i, (a, n))| (i + 1, *a, *n)).collect();
        ranked.sort_by(|a, b| b.1.total_cmp(&a.1));
        let mut standing: Vec<(usize, f64)> =
            ranked.iter().filter(|(_, a, n)| *a > 3.0 * *n).map(|&(h, a, _)| (h, a)).collect();
        if standing.is_empty() {
            standing = ranked.iter().take(3).map(|&(h, a, _)| (h, a)).collect();
        }
        let list: Vec<String> = standing.iter().map(|(h, a)| format!("{h} ({:.1} µm)", a * 1e6)).collect();
        let mut meanings = Vec::new();
        let has = |f: &dyn Fn(usize) -> bool| standing.iter().any(|(h, _)| f(*h));
        if has(&|h| h % 2 == 1) {
            meanings.push("odd harmonics (3, 5, 7, 9): the turntable's angle off once a turn (a disc or gear eccentricity), or the plate not flat on the holder");
        }
        if has(&|h| h % 4 == 2) {
            meanings.push("harmonics 2, 6, 10: the angle off twice a turn (an elliptic disc, a bearing)");
        }
        if has(&|h| h % 4 == 0) {
            meanings.push(
                "harmonics 4, 8, 12: the plate's side or corner radius, the stylus tip or the encoder scale not as set",
            );
        }
        if has(&|h| h % 4 != 0) {
            meanings.push("an angle error is fitted with the calibration: set calibration.angle_harmonics (e.g. [1, 2]; the offline --angle-harmonics 1,2)");
        }
        format!(
            "harmonics {} stand out (p = {:.1e}; structure {:.1} µm rms, noise {:.1} µm with lag-1 correlation {:.2}); {}",
            list.join(", "),
            self.p_value,
            self.rms * 1e6,
            self.noise * 1e6,
            self.lag1,
            meanings.join("; ")
        )
    }
}

/// The harmonic test (module docs) of residuals `residuals[k]` at angle steps `steps[k]`
/// of a turn of `steps_per_rev`, over the samples where `used[k]`. `None` if the turn is
/// too short or has too many steps missing to tell noise from structure.
pub fn harmonic_test(steps: &[u32], steps_per_rev: u32, residuals: &[f64], used: &[bool]) -> Option<Structure> {
    let n = steps_per_rev as usize;
    if n < 8 * HARMONICS {
        return None;
    }
    // The turn in step order, gaps filled linearly from the nearest used neighbours.
    let mut at: Vec<Option<f64>> = vec![None; n];
    for ((&step, &r), &u) in steps.iter().zip(residuals).zip(used) {
        let slot = &mut at[step as usize % n];
        if u && r.is_finite() && slot.is_none() {
            *slot = Some(r);
        }
    }
    let known: Vec<usize> = (0..n).filter(|&k| at[k].is_some()).collect();
    if ((n - known.len()) as f64) > MAX_FILLED * n as f64 || known.len() < 2 {
        return None;
    }
    let mut r = vec![0.0; n];
    for (i, &k) in known.iter().enumerate() {
        let next = known[(i + 1) % known.len()];
        let gap = (next + n - k) % n;
        let (a, b) = (at[k].unwrap_or(0.0), at[next].unwrap_or(0.0));
        for j in 0..gap.max(1) {
            r[(k + j) % n] = a + (b - a) * j as f64 / gap.max(1) as f64;
        }
    }
    // The periodogram.
    let (spectrum, periodogram) = periodogram(&mut r)?;
    // 1. Whittle's AR(1) fit above the tested harmonics.
    let Whittle { grid, phi, best, sigma2, shape, fitted } = whittle(&periodogram, n)?;
    // The noise the low harmonics are held against: the AR(1) at the upper end of φ's
    // one-sided 95 % likelihood interval (the negative log-likelihood within 1.35 of its
    // least), the most low-harmonic power the high harmonics allow. An estimate of φ a
    // little low would otherwise make correlated noise look like structure.
    let &(phi_up, (_, sigma2_up)) =
        grid.iter().rev().find(|(p, (l, _))| *p >= phi && *l <= best + 1.35).unwrap_or(&(phi, (best, sigma2)));
    let dof = (2 * HARMONICS, 2 * fitted);
    let amplitudes: Vec<f64> = (1..=HARMONICS).map(|h| 2.0 * spectrum[h].norm() / n as f64).collect();
    if sigma2.is_nan() || sigma2 <= 0.0 {
        // Noise-free: nothing to test against, and nothing an edger would see.
        return Some(Structure {
            f: 0.0,
            dof,
            p_value: 1.0,
            amplitudes,
            noise_amplitudes: vec![0.0; HARMONICS],
            rms: 0.0,
            lag1: 0.0,
            noise: 0.0,
        });
    }
    // 2. The low harmonics against the noise's spectrum there.
    let s_at = |h: usize| sigma2_up / shape.at(phi_up, h);
    let t: f64 = (1..=HARMONICS).map(|h| 2.0 * periodogram[h] / s_at(h)).sum();
    let f = t / dof.0 as f64;
    let noise_amplitudes = (1..=HARMONICS).map(|h| (4.0 * s_at(h) / n as f64).sqrt()).collect();
    let rms = (amplitudes.iter().map(|a| a * a).sum::<f64>() / 2.0).sqrt();
    Some(Structure {
        f,
        dof,
        p_value: f_survival(f, dof.0 as f64, dof.1 as f64),
        amplitudes,
        noise_amplitudes,
        rms,
        lag1: phi,
        noise: (sigma2 / (1.0 - phi * phi)).sqrt(),
    })
}

/// The spectrum of a series of `n` values and its periodogram `|X_h|²/n`.
fn periodogram(series: &mut [f64]) -> Option<(Vec<realfft::num_complex::Complex<f64>>, Vec<f64>)> {
    let n = series.len();
    let fft = RealFftPlanner::<f64>::new().plan_fft_forward(n);
    let mut spectrum = fft.make_output_vec();
    fft.process(series, &mut spectrum).ok()?;
    let periodogram = spectrum.iter().map(|c| c.norm_sqr() / n as f64).collect();
    Some((spectrum, periodogram))
}

/// `|1 - φe^{-iω_h}|²`, the AR(1) spectrum's shape, from a table of `cos ω_h`.
struct Shape(Vec<f64>);

impl Shape {
    fn at(&self, phi: f64, h: usize) -> f64 {
        1.0 + phi * phi - 2.0 * phi * self.0[h]
    }
}

/// Whittle's AR(1) fit to the periodogram's harmonics above [`HARMONICS`]: its grid of
/// `(φ, (negative log-likelihood, innovation variance))`, the best `φ` with its values.
struct Whittle {
    grid: Vec<(f64, (f64, f64))>,
    phi: f64,
    best: f64,
    sigma2: f64,
    shape: Shape,
    /// How many harmonics it fitted.
    fitted: usize,
}

fn whittle(periodogram: &[f64], n: usize) -> Option<Whittle> {
    let high: Vec<usize> = (HARMONICS + 1..n.div_ceil(2)).collect();
    // cos ω_h once for every harmonic: the grid evaluates the shape 70 000 times.
    let shape = Shape((0..n.div_ceil(2)).map(|h| (std::f64::consts::TAU * h as f64 / n as f64).cos()).collect());
    let likelihood = |phi: f64| {
        let sigma2 = high.iter().map(|&h| periodogram[h] * shape.at(phi, h)).sum::<f64>() / high.len() as f64;
        // Σ ln(σ²/shape) = n ln σ² - ln Π shape, the product taken in blocks (no overflow:
        // each shape is within [(1-|φ|)², (1+|φ|)²]).
        let ln_shapes: f64 = high.chunks(16).map(|b| b.iter().map(|&h| shape.at(phi, h)).product::<f64>().ln()).sum();
        (high.len() as f64 * sigma2.ln() - ln_shapes + high.len() as f64, sigma2)
    };
    let grid: Vec<(f64, (f64, f64))> =
        (0..=370).map(|i| -0.9 + 0.005 * i as f64).map(|phi| (phi, likelihood(phi))).collect();
    let &(phi, (best, sigma2)) = grid.iter().min_by(|a, b| a.1.0.total_cmp(&b.1.0))?;
    Some(Whittle { grid, phi, best, sigma2, shape, fitted: high.len() })
}

/// The lag-1 correlation of the noise in a series of residuals taken one after another
/// (a trace), by Whittle's AR(1) fit to its periodogram above [`HARMONICS`] a series: blind
/// to the smooth structure a misfit leaves, which a lag-1 correlation of the residuals
/// themselves would take for correlated noise. `None` for a series too short to tell.
pub fn noise_lag1(series: &[f64]) -> Option<f64> {
    if series.len() < 8 * HARMONICS || !series.iter().all(|r| r.is_finite()) {
        return None;
    }
    let mut r = series.to_vec();
    let (_, periodogram) = periodogram(&mut r)?;
    let w = whittle(&periodogram, series.len())?;
    (w.sigma2.is_finite() && w.sigma2 > 0.0).then_some(w.phi)
}

/// `P(F > f)` for an F distribution with `d1`, `d2` degrees of freedom:
/// `I_{d2/(d2 + d1 f)}(d2/2, d1/2)`, the regularised incomplete beta function.
pub fn f_survival(f: f64, d1: f64, d2: f64) -> f64 {
    if f <= 0.0 {
        return 1.0;
    }
    incomplete_beta(d2 / 2.0, d1 / 2.0, d2 / (d2 + d1 * f))
}

/// The regularised incomplete beta function `I_x(a, b)`, by its continued fraction
/// (modified Lentz), on the side of `x` where it converges fast.
pub fn incomplete_beta(a: f64, b: f64, x: f64) -> f64 {
    if x <= 0.0 {
        return 0.0;
    }
    if x >= 1.0 {
        return 1.0;
    }
    let ln_front = ln_gamma(a + b) - ln_gamma(a) - ln_gamma(b) + a * x.ln() + b * (1.0 - x).ln();
    if x < (a + 1.0) / (a + b + 2.0) {
        ln_front.exp() * beta_fraction(a, b, x) / a
    } else {
        1.0 - ln_front.exp() * beta_fraction(b, a, 1.0 - x) / b
    }
}

/// The continued fraction of the incomplete beta function (Numerical Recipes' `betacf`).
fn beta_fraction(a: f64, b: f64, x: f64) -> f64 {
    const TINY: f64 = 1e-300;
    let (qab, qap, qam) = (a + b, a + 1.0, a - 1.0);
    let mut c = 1.0;
    let mut d = 1.0 - qab * x / qap;
    if d.abs() < TINY {
        d = TINY;
    }
    d = 1.0 / d;
    let mut h = d;
    for m in 1..=300 {
        let m = m as f64;
        let m2 = 2.0 * m;
        let aa = m * (b - m) * x / ((qam + m2) * (a + m2));
        d = 1.0 + aa * d;
        d = if d.abs() < TINY { TINY } else { d };
        c = 1.0 + aa / c;
        c = if c.abs() < TINY { TINY } else { c };
        d = 1.0 / d;
        h *= d * c;
        let aa = -(a + m) * (qab + m) * x / ((a + m2) * (qap + m2));
        d = 1.0 + aa * d;
        d = if d.abs() < TINY { TINY } else { d };
        c = 1.0 + aa / c;
        c = if c.abs() < TINY { TINY } else { c };
        d = 1.0 / d;
        let delta = d * c;
        h *= delta;
        if (delta - 1.0).abs() < 1e-15 {
            break;
        }
    }
    h
}

/// `ln Γ(x)` for `x > 0` (Lanczos, g = 7, n = 9: about 15 digits).
pub fn ln_gamma(x: f64) -> f64 {
    const G: f64 = 7.0;
    const C: [f64; 9] = [
        0.999_999_999_999_809_9,
        676.520_368_121_885_1,
        -1_259.139_216_722_402_8,
        771.323_428_777_653_1,
        -176.615_029_162_140_6,
        12.507_343_278_686_905,
        -0.138_571_095_265_720_12,
        9.984_369_578_019_572e-6,
        1.505_632_735_149_311_6e-7,
    ];
    if x < 0.5 {
        // Reflection: Γ(x) Γ(1-x) = π / sin(πx).
        return (std::f64::consts::PI / (std::f64::consts::PI * x).sin()).ln() - ln_gamma(1.0 - x);
    }
    let x = x - 1.0;
    let mut sum = C[0];
    for (i, c) in C.iter().enumerate().skip(1) {
        sum += c / (x + i as f64);
    }
    let t = x + G + 0.5;
    0.5 * (2.0 * std::f64::consts::PI).ln() + (x + 0.5) * t.ln() - t + sum.ln()
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand_distr::{Distribution, Normal};

    #[test]
    fn the_distribution_functions_meet_their_closed_forms() {
        // Γ(n) = (n-1)!, Γ(1/2) = √π.
        assert!((ln_gamma(5.0) - 24f64.ln()).abs() < 1e-13);
        assert!((ln_gamma(0.5) - std::f64::consts::PI.sqrt().ln()).abs() < 1e-13);
        assert!((ln_gamma(101.0) - 363.739_375_555_563_47).abs() < 1e-10, "ln 100!");
        for x in [0.01, 0.2, 0.5, 0.77, 0.99] {
            // I_x(a, 1) = x^a; I_x(1, b) = 1 - (1-x)^b; I_x(1/2, 1/2) = (2/π) asin √x.
            assert!((incomplete_beta(3.5, 1.0, x) - x.powf(3.5)).abs() < 1e-13, "{x}");
            assert!((incomplete_beta(1.0, 7.0, x) - (1.0 - (1.0 - x).powi(7))).abs() < 1e-13, "{x}");
            let arcsine = 2.0 / std::f64::consts::PI * x.sqrt().asin();
            assert!((incomplete_beta(0.5, 0.5, x) - arcsine).abs() < 1e-12, "{x}");
        }
        // F(2, d2): P(F > f) = (1 + 2f/d2)^(-d2/2).
        for f in [0.1f64, 1.0, 3.0, 10.0] {
            let want = (1.0 + 2.0 * f / 50.0).powf(-25.0);
            assert!((f_survival(f, 2.0, 50.0) - want).abs() < 1e-13, "{f}");
        }
        // The 1 % point of F(24, 350) is about 1.84 (tables).
        let p = f_survival(1.84, 24.0, 350.0);
        assert!((0.009..0.011).contains(&p), "{p}");
    }

    fn noise(seed: u64, n: usize, sigma: f64, lag1: f64) -> Vec<f64> {
        let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
        let white = Normal::new(0.0, sigma * (1.0 - lag1 * lag1).sqrt()).unwrap();
        let mut e = Normal::new(0.0, sigma).unwrap().sample(&mut rng);
        (0..n)
            .map(|_| {
                let now = e;
                e = lag1 * e + white.sample(&mut rng);
                now
            })
            .collect()
    }

    #[test]
    fn noise_alone_is_refused_at_about_the_level_and_structure_always() {
        let n = 400u32;
        let steps: Vec<u32> = (0..n).collect();
        let used = vec![true; n as usize];
        for lag1 in [0.0, 0.5, 0.8] {
            let refused = (0..400)
                .filter(|&seed| {
                    let r = noise(seed, n as usize, 5e-6, lag1);
                    harmonic_test(&steps, n, &r, &used).unwrap().refused_at(0.01)
                })
                .count();
            // Conservative at lag 0 (about 1 %); AR(1) prewhitened within a few per cent.
            assert!(refused <= 12, "lag-1 {lag1}: {refused} of 400 clean scans refused");
        }
        // 4 µm at harmonic 5 in 5 µm of noise: always seen, and named.
        for seed in 0..50 {
            let r: Vec<f64> = noise(seed, n as usize, 5e-6, 0.0)
                .iter()
                .zip(&steps)
                .map(|(e, s)| e + 4e-6 * (5.0 * std::f64::consts::TAU * f64::from(*s) / 400.0).cos())
                .collect();
            let t = harmonic_test(&steps, n, &r, &used).unwrap();
            assert!(t.refused_at(0.01), "seed {seed}: {t:?}");
            assert!((t.amplitudes[4] - 4e-6).abs() < 1.5e-6, "{:?}", t.amplitudes);
            assert!(t.describe().starts_with("harmonics 5 ("), "{}", t.describe());
        }
        // Noise-free round-off is never refused; gaps are fine; too few samples say so.
        let tiny: Vec<f64> = steps.iter().map(|s| 1e-12 * f64::from(*s % 7)).collect();
        assert!(!harmonic_test(&steps, n, &tiny, &used).unwrap().refused_at(0.01));
        let gappy: Vec<bool> = steps.iter().map(|s| s % 10 != 3).collect();
        assert!(harmonic_test(&steps, n, &noise(1, 400, 5e-6, 0.0), &gappy).is_some());
        assert!(harmonic_test(&steps[..40], n, &noise(1, 40, 5e-6, 0.0), &used[..40]).is_none());
    }
}
