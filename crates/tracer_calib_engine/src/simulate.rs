//! A simulated tracer: what the encoders of a tracer with given mounting errors read
//! when it traces a known shape. Tests, the demo, the accuracy study and the
//! benchmarks all draw their scans from here.
//!
//! For each angle step the rail ray `d v + t u` leaves the shape at `t`
//! ([`super::shape::Shape::exit`]); the encoder reads `rho = (t + dL) / k`, plus Gaussian
//! noise, optionally quantised to the encoder's counts, with optional spikes (dust, a
//! probe bounce) and missing samples. The true touched point `d v + t u` comes along,
//! so a corrected scan can be compared with the truth.
//!
//! A height channel ([`simulate_heights`]) reads each sample's height along the axis: the
//! groove bottom's, where the shape lies on a surface in the frame holder ([`on_sphere`]:
//! a frame's base curve), plus the holder's tilt against the axis at the ball's centre
//! ([`super::height`]'s model), plus noise, in counts.

use nalgebra::Vector2;
use rand::Rng;
use rand::seq::index::sample as sample_indices;
use rand_distr::{Distribution, Normal};

use super::geometry::{Mounting, rail_angle, rail_frame};
use super::scan::{Sample, Scan};
use super::shape::Shape;
use super::stylus::contact_offset;

/// How a simulated revolution is taken.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SimOptions {
    pub steps_per_rev: u32,
    /// Standard deviation of the encoder noise, metres.
    pub noise: f64,
    /// Encoder resolution (metres per count) to quantise to; 0 = no quantisation.
    pub quantum: f64,
    /// First step of the revolution (the scan wraps around to `start_step - 1`).
    pub start_step: u32,
    /// Fraction of samples missing, at random.
    pub missing: f64,
    /// Number of samples spiked by `spike_height`.
    pub spikes: usize,
    /// Height of a spike, metres (positive: the probe reads longer).
    pub spike_height: f64,
    /// Radius of the probe's contact tip, metres (0: a point): the encoder reads where
    /// the tip's centre is ([`tip_exit`]).
    pub tip_radius: f64,
    /// The shape is traced from inside (a frame, a ring gauge), the tip touching it
    /// from within; else from outside (a plate, a lens).
    pub inside: bool,
    /// Traced from inside, the shape is the bottom of a V-groove of this included angle
    /// (rad; π a plain bore): the tip's centre sits `tip_radius / sin(angle/2)` from it
    /// ([`crate::stylus`]).
    pub groove_angle: f64,
    /// The turntable's angle error round the turn, `ε(θ) = Σ c_h cos hθ + s_h sin hθ`
    /// (radians) added to the rail angle at `θ = 2π step / N`: up to three harmonics,
    /// each `(h, c_h, s_h)`; `h = 0` unused. A disc or gear eccentricity is `h = 1`, an
    /// elliptic disc `h = 2`.
    pub angle_harmonics: [(u32, f64, f64); 3],
    /// Lag-1 correlation `φ` of the encoder noise along the trace (AR(1), marginal standard
    /// deviation `noise`): stick-slip, interpolation error. 0 = white.
    pub noise_lag1: f64,
}

impl Default for SimOptions {
    fn default() -> Self {
        SimOptions {
            steps_per_rev: 400,
            noise: 0.0,
            quantum: 0.0,
            start_step: 0,
            missing: 0.0,
            spikes: 0,
            spike_height: 0.5e-3,
            tip_radius: 0.0,
            inside: false,
            groove_angle: crate::stylus::PLAIN_BORE,
            angle_harmonics: [(0, 0.0, 0.0); 3],
            noise_lag1: 0.0,
        }
    }
}

impl SimOptions {
    /// The angle error at step `step` of `n` (radians).
    pub fn angle_error(&self, step: u32, n: u32) -> f64 {
        let theta = std::f64::consts::TAU * f64::from(step) / f64::from(n);
        self.angle_harmonics
            .iter()
            .filter(|(h, _, _)| *h > 0)
            .map(|&(h, c, s)| c * (f64::from(h) * theta).cos() + s * (f64::from(h) * theta).sin())
            .sum()
    }
}

/// A simulated revolution and its ground truth.
#[derive(Debug, Clone)]
pub struct SimScan {
    pub scan: Scan,
    /// The point each sample really touched, in sample order.
    pub truth: Vec<Vector2<f64>>,
    /// Which samples were spiked.
    pub spiked: Vec<bool>,
    /// Where the tip's centre was at each sample, in sample order.
    pub centres: Vec<Vector2<f64>>,
}

/// Why a scan cannot be simulated.
#[derive(Debug, Clone, PartialEq)]
pub enum SimError {
    /// The rail ray at this step misses the shape (the mounting puts the rail outside).
    RayMissesShape {
        step: u32,
    },
    Invalid(String),
}

impl std::fmt::Display for SimError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::RayMissesShape { step } => {
                write!(f, "at step {step} the rail misses the shape: the rail offset is larger than the shape")
            }
            Self::Invalid(why) => write!(f, "{why}"),
        }
    }
}

impl std::error::Error for SimError {}

/// Where the centre of a tip of radius `tip` stops on the rail ray `origin + t u` when
/// it touches `shape` (from inside if `inside`): `(t, the point touched)`.
///
/// The centre follows the contour offset by `s = ±tip` along its outward normal (`+`
/// from outside). From a surface point `X` with normal `N` the offset contour's tangent
/// line is `N·(Y - X) = s`; the ray meets it at `t = (N·(X - origin) + s)/(N·u)`. The
/// next `X` is where the ray from `origin` through `origin + t u - s N` leaves the shape.
/// Exact at once on a flat, a few rounds on a curve (to 1e-15 m).
pub fn tip_exit(
    shape: &impl Shape,
    origin: Vector2<f64>,
    u: Vector2<f64>,
    tip: f64,
    inside: bool,
) -> Option<(f64, Vector2<f64>)> {
    let mut hit = shape.exit(origin, u)?;
    let mut touched = origin + u * hit.t;
    if tip == 0.0 {
        return Some((hit.t, touched));
    }
    let s = if inside { -tip } else { tip };
    let mut t = hit.t + s / hit.normal.dot(&u);
    for _ in 0..100 {
        let dir = (origin + u * t - hit.normal * s - origin).try_normalize(0.0)?;
        hit = shape.exit(origin, dir)?;
        touched = origin + dir * hit.t;
        let next = (hit.normal.dot(&(touched - origin)) + s) / hit.normal.dot(&u);
        let done = (next - t).abs() <= 1e-15;
        t = next;
        if done {
            break;
        }
    }
    t.is_finite().then_some((t, touched))
}

/// Simulate one revolution of a tracer with mounting `m` around `shape`.
pub fn simulate(shape: &impl Shape, m: &Mounting, opt: &SimOptions, rng: &mut impl Rng) -> Result<SimScan, SimError> {
    let n = opt.steps_per_rev;
    if n == 0 {
        return Err(SimError::Invalid("steps_per_rev must be positive".into()));
    }
    if !(opt.noise >= 0.0 && opt.quantum >= 0.0 && (0.0..1.0).contains(&opt.missing)) {
        return Err(SimError::Invalid("noise and quantum must be >= 0, missing in [0, 1)".into()));
    }
    if !(opt.noise_lag1 > -1.0 && opt.noise_lag1 < 1.0) {
        return Err(SimError::Invalid("noise_lag1 must be in (-1, 1)".into()));
    }
    let noise = Normal::new(0.0, opt.noise).map_err(|e| SimError::Invalid(e.to_string()))?;
    // AR(1) along the trace: e_k = φ e_(k-1) + √(1-φ²) w_k keeps the marginal σ.
    // (White noise draws one number a sample, as it always has: seeded scans stay as they were.)
    let phi = opt.noise_lag1;
    let mut correlated = if phi == 0.0 { 0.0 } else { noise.sample(rng) };
    let mut samples = Vec::with_capacity(n as usize);
    let mut truth = Vec::with_capacity(n as usize);
    let mut centres = Vec::with_capacity(n as usize);
    let contact = if opt.inside { contact_offset(opt.tip_radius, opt.groove_angle) } else { opt.tip_radius };
    for i in 0..n {
        let step = (opt.start_step % n + i) % n;
        if opt.missing > 0.0 && rng.random::<f64>() < opt.missing {
            continue;
        }
        let (u, v) = rail_frame(rail_angle(m.alpha0, step, n) + opt.angle_error(step, n));
        let origin = v * m.offset;
        let (t, touched) = tip_exit(shape, origin, u, contact, opt.inside).ok_or(SimError::RayMissesShape { step })?;
        let e = if phi == 0.0 {
            noise.sample(rng)
        } else {
            let now = correlated;
            correlated = phi * correlated + (1.0 - phi * phi).sqrt() * noise.sample(rng);
            now
        };
        let mut rho = (t + m.delta_l) / m.scale + e;
        if opt.quantum > 0.0 {
            rho = (rho / opt.quantum).round() * opt.quantum;
        }
        samples.push(Sample { step, rho });
        truth.push(touched);
        centres.push(origin + u * t);
    }
    let mut spiked = vec![false; samples.len()];
    for i in sample_indices(rng, samples.len(), opt.spikes.min(samples.len())) {
        samples[i].rho += opt.spike_height;
        spiked[i] = true;
    }
    let scan = Scan::from_samples(n, samples).map_err(|e| SimError::Invalid(e.to_string()))?;
    Ok(SimScan { scan, truth, spiked, centres })
}

/// A height channel and the frame holder it reads against.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HeightOptions {
    /// The holder's plane's height where the axis meets it, metres.
    pub zero: f64,
    /// The holder's tilt against the axis, `[τ_x, τ_y]`, rad.
    pub tilt: [f64; 2],
    /// Standard deviation of the height noise, metres.
    pub noise: f64,
    /// The height count's length, metres; 0 = not quantised.
    pub quantum: f64,
}

/// The height reading of each sample of `sim`: `zero + c·(tan τ_x, tan τ_y) + surface(X)`
/// at the tip's centre `c` over the point touched `X` (the groove's bottom, whose height
/// the ball shares), plus noise, quantised.
pub fn simulate_heights(
    sim: &SimScan,
    surface: impl Fn(Vector2<f64>) -> f64,
    opt: &HeightOptions,
    rng: &mut impl Rng,
) -> Result<Vec<f64>, SimError> {
    let noise = Normal::new(0.0, opt.noise).map_err(|e| SimError::Invalid(e.to_string()))?;
    let slopes = Vector2::new(opt.tilt[0].tan(), opt.tilt[1].tan());
    Ok(sim
        .centres
        .iter()
        .zip(&sim.truth)
        .map(|(c, x)| {
            let h = opt.zero + c.dot(&slopes) + surface(*x) + noise.sample(rng);
            if opt.quantum > 0.0 { (h / opt.quantum).round() * opt.quantum } else { h }
        })
        .collect())
}

/// A sphere of `base` dioptres (radius `530 mm / base`) whose apex is at `apex`, `level`
/// above the holder: the height of a frame's groove over `p` (`level` everywhere for a
/// base of 0, a flat artefact).
pub fn on_sphere(base: f64, apex: Vector2<f64>, level: f64) -> impl Fn(Vector2<f64>) -> f64 {
    let radius = if base > 0.0 { super::height::FRAME_CURVE_METRES / base } else { f64::INFINITY };
    move |p: Vector2<f64>| {
        let q = (p - apex).norm_squared();
        // `R - √(R² - q)`, written to keep its digits for a large R.
        if radius.is_finite() { level + q / (radius + (radius * radius - q).max(0.0).sqrt()) } else { level }
    }
}
