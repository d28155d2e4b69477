//! From a plate scan to a calibration: start, fit, reject outliers, report.
//!
//! 1. [`super::start::initial_guess`] finds a start from any mounting error in range;
//! 2. the chosen model is fitted by [`super::lm::minimize`];
//! 3. **outliers** (dust, a probe bounce) are rejected on the residuals: with the
//!    robust scale `σ̂ = 1.4826 · MAD(r)`, samples with `|r_i| > k σ̂` (`k = 4` by
//!    default; never below 0.1 µm, the floor for noise-free data) are dropped and the
//!    fit repeated from where it stands, until the set of samples stops changing. All
//!    samples are re-tested in the first rounds, so a sample wrongly dropped early comes
//!    back; after `FREE_ROUNDS` samples may only leave, so a sample on the threshold
//!    cannot make the set oscillate, and the loop ends;
//! 4. `alpha0` is reported in `(-π/4, π/4]`: a square plate gives the same lengths for
//!    `(alpha0 + π/2, d, dL, R₉₀ c)` ([`super::geometry::wrap_quarter_turn`]);
//! 5. the standard uncertainty of each parameter from the covariance `σ̂² (JᵀJ)⁻¹`, or,
//!    when the residuals are correlated along the trace, the sandwich
//!    `(JᵀJ)⁻¹ JᵀΣJ (JᵀJ)⁻¹` of AR(1) noise (`correlated`); the
//!    tracer's part of it (the plate centre left out: the marginal covariance of a
//!    Gaussian estimate is the sub-matrix) reported whole, in the fixed [`Covariance`]
//!    layout, since the parameters correlate strongly (`dL` and the scale at 0.95): a
//!    numerical study of the model found a circumference's uncertainty eight times too
//!    large when computed from the standard uncertainties alone;
//! 6. **the encoder scale is checked** by the models that do not fit it (`full`,
//!    `paper`): a score test of the scale in force, `k = k₀`. At the fitted parameters
//!    `x̂` the encoder-scale model ([`super::model::full_scale`]) is linearised and one
//!    Gauss-Newton step taken, `δ = -(JᵀJ)⁻¹ Jᵀr` (six parameters, one pass over the
//!    samples); its scale component estimates `k/k₀ - 1`, with variance
//!    `σ̂² [(JᵀJ)⁻¹]_kk` (the sandwich of step 5 under noise correlated along the trace,
//!    its correlation from the residuals after the step, unless the fit rejected more
//!    than 1 % of the samples: then the residuals are more than noise). At the full
//!    model's minimum the other five components of the gradient vanish, so this is Rao's
//!    score (Lagrange multiplier) test of `k = k₀`. A
//!    scale off by more than [`Options::max_scale_sigma`] standard uncertainties *and*
//!    [`Options::scale_tolerance`] fails the calibration: the fitted `dL` would hide
//!    the size error at the plate's own radius, and every lens larger or smaller than
//!    the plate would come out the wrong size. Model `full_scale` fits `k` instead.
//!
//! 7. **the plate's residuals are tested for structure** the model lacks: their harmonics
//!    1-12 a turn against the scan's own noise ([`super::lack_of_fit`]), at the level
//!    [`Options::lack_of_fit_alpha`]. A turntable whose angle is off once or twice a turn
//!    leaves a few micrometres there, which the residual RMS does not show.
//!
//! A fit that does not converge, uses too few samples, leaves a residual larger than a
//! plate scan can have, finds the encoder scale off or leaves structure in the residuals is
//! an error: the caller keeps the calibration it had.

use nalgebra::allocator::Allocator;
use nalgebra::{DMatrix, DVector, DefaultAllocator, Dim, OMatrix, OVector, SMatrix, SVector, Vector2};
use std::borrow::Cow;
use std::fmt;

use super::angle::{AngleError, HarmonicOrders, coefficient_names};
use super::correct::correct;
use super::geometry::{Mounting, rotate_quarter_turns, wrap_quarter_turn};
use super::lack_of_fit::{Structure, harmonic_test, noise_lag1};
use super::lm::{self, Problem, Termination};
use super::model::full::{self, FullModel};
use super::model::full_scale::{self, FullScaleModel};
use super::model::paper::{self, PaperModel};
use super::model::tip::{self, RingSpec, TipModel, TipScaleModel};
use super::model::turntable::{self, TurntableModel};
use super::model::{InputDerivatives, ModelKind, PlateError, PlateSpec};
use super::scan::Scan;
use super::start::initial_guess;

/// Calibration settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Options {
    pub model: ModelKind,
    pub lm: lm::Options,
    /// Reject samples whose residual exceeds this many robust standard deviations.
    pub outlier_threshold: f64,
    /// A fit needs at least this many samples (after rejection).
    pub min_samples: usize,
    /// A fit whose RMS residual exceeds this (metres) is refused: the scan does not
    /// look like the plate (wrong plate size or encoder scale, plate not seated).
    pub max_rms_residual: f64,
    /// A fit whose residuals are systematic is refused: RMS residual above this many
    /// times the noise seen between neighbouring samples (and above
    /// [`Options::systematic_floor`]). A wrong plate size leaves smooth residuals of
    /// a tenth of a millimetre that plain noise cannot explain.
    pub max_lack_of_fit: f64,
    /// Systematic residuals below this RMS (metres) are tolerated.
    pub systematic_floor: f64,
    /// Significance level of the harmonic lack-of-fit test of the plate's residuals
    /// ([`super::lack_of_fit`]): a fit whose residuals show structure at this level is
    /// refused. 0 = not tested.
    pub lack_of_fit_alpha: f64,
    /// The encoder scale in force, `k₀`: the models that do not fit the scale take the
    /// true length along the rail as `k₀ × rho`.
    pub scale: f64,
    /// The scale check (module docs) fails a fit whose scan shows an encoder scale more
    /// than this many standard uncertainties from `k₀`...
    pub max_scale_sigma: f64,
    /// ... and off by more than this fraction (1e-4: 2.5 µm on a 25 mm radius).
    pub scale_tolerance: f64,
    /// The stylus tip's radius in force, metres (`stylus.tip_radius`): the models that do
    /// not fit it see the plate grown by it ([`super::model::tip`]).
    pub tip_radius: f64,
    /// A fit that rejects more than this fraction of a scan's samples as outliers is
    /// refused: dust and bounces spike a few samples, a scan that does not match the
    /// model spikes many.
    pub max_rejected_fraction: f64,
    /// Standard uncertainty of the plate's side from its certificate, metres
    /// (`plate.side_uncertainty`): a type B component of the covariance (`inputs_of`).
    pub plate_side_uncertainty: f64,
    /// Standard uncertainty of the ring gauge's diameter from its certificate, metres
    /// (`ring.diameter_uncertainty`), for the tip models.
    pub ring_diameter_uncertainty: f64,
    /// A tip model's fitted radius is refused above this (metres): no stylus of a
    /// tracer is that large, and a ring gauge of the wrong diameter can make it so.
    pub max_tip_radius: f64,
    /// Standard uncertainty of the plate's corner radius from its certificate, metres
    /// (`plate.corner_radius_uncertainty`): a type B part of the covariance.
    pub corner_radius_uncertainty: f64,
    /// Standard uncertainty of the tip radius in force, metres
    /// (`stylus.tip_radius_uncertainty`), for the models that do not fit it: a type B
    /// part of the covariance, with its own row.
    pub tip_radius_uncertainty: f64,
    /// Standard uncertainty of the encoder scale in force (an earlier fit's), for the
    /// models that do not fit it: carried into the covariance with its own row.
    pub scale_uncertainty: f64,
    /// Standard uncertainty of the plate's seating angle against the frame holder's
    /// datum, radians (`plate.seating_uncertainty`): added to `alpha0`'s variance (a plate
    /// seated turned by `ε` reads as a tracer whose rail starts `ε` off).
    pub seating_uncertainty: f64,
    /// Orders of the turntable's angle error fitted with the model
    /// (`calibration.angle_harmonics`, [`super::angle`]); none: the angle encoder taken
    /// as exact.
    pub angle_harmonics: HarmonicOrders,
}

impl Default for Options {
    fn default() -> Self {
        Options {
            model: ModelKind::Full,
            lm: lm::Options::default(),
            outlier_threshold: 4.0,
            min_samples: 24,
            max_rms_residual: 0.5e-3,
            max_lack_of_fit: 4.0,
            systematic_floor: 20e-6,
            lack_of_fit_alpha: 0.001,
            scale: 1.0,
            max_scale_sigma: 5.0,
            scale_tolerance: 1e-4,
            max_rejected_fraction: 0.25,
            tip_radius: 0.0,
            plate_side_uncertainty: 0.0,
            ring_diameter_uncertainty: 0.0,
            corner_radius_uncertainty: 0.0,
            tip_radius_uncertainty: 0.0,
            scale_uncertainty: 0.0,
            seating_uncertainty: 0.0,
            max_tip_radius: 2e-3,
            angle_harmonics: HarmonicOrders::NONE,
        }
    }
}

/// Floor of the outlier threshold, metres: keeps noise-free scans whole.
const OUTLIER_FLOOR: f64 = 1e-7;
/// Rounds in which a rejected sample may come back.
const FREE_ROUNDS: usize = 3;
/// Rejection rounds at most; the last round's fit stands.
const MAX_ROUNDS: usize = 12;
/// The share of a plate scan's samples a fit may reject as outliers with its residuals
/// still taken for noise by the scale check ([`noise_only`]): dust and a bounce or two
/// (Gaussian noise leaves about 1 in 16 000 beyond the outlier threshold).
const MAX_NOISE_REJECTED: f64 = 0.01;

/// The encoder scale a plate scan shows, with its standard uncertainty.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ScaleEstimate {
    pub scale: f64,
    pub stddev: f64,
}

impl ScaleEstimate {
    /// How far from `k₀`, in standard uncertainties.
    pub fn sigmas_from(&self, k0: f64) -> f64 {
        (self.scale - k0).abs() / self.stddev
    }
}

/// The covariance of the tracer's parameters in the contract's fixed layout,
/// `[alpha0, offset, delta_l, scale, tip_radius]` (radians, metres, 1, metres): rows and
/// columns of what a model does not fit are zero.
pub type Covariance = SMatrix<f64, 5, 5>;

/// Indices into [`Covariance`].
pub mod layout {
    pub const ALPHA0: usize = 0;
    pub const OFFSET: usize = 1;
    pub const DELTA_L: usize = 2;
    pub const SCALE: usize = 3;
    pub const TIP_RADIUS: usize = 4;
    /// Entries of the row-major form messages and records carry.
    pub const VALUES: usize = 25;
}

/// `cov` row-major: the 25 values of the Calibrate response, the `Calibration` message,
/// the `calibration.covariance` parameter and the history's records.
pub fn covariance_values(cov: &Covariance) -> Vec<f64> {
    (0..5).flat_map(|i| (0..5).map(move |j| cov[(i, j)])).collect()
}

/// The row-major values of a named covariance back as a [`Covariance`]: the block of its
/// first five names ([`named_covariance_from_values`]).
pub fn covariance_from_values(v: &[f64]) -> Result<Covariance, InvalidCovariance> {
    let c = named_covariance_from_values(v)?;
    Ok(Covariance::from_fn(|i, j| c[(i, j)]))
}

/// The row-major values of a named covariance ([`covariance_names`]: the five, then two a
/// harmonic of the angle error, so `n²` values for an odd `n ≥ 5`) back as a matrix, if
/// every one is finite, the matrix symmetric (to rounding) with no negative variance; else
/// what they are not, in the words the parameter, the params file and the history report.
pub fn named_covariance_from_values(v: &[f64]) -> Result<DMatrix<f64>, InvalidCovariance> {
    let refused = || Err(InvalidCovariance { values: v.len() });
    let n = (v.len() as f64).sqrt().round() as usize;
    if n * n != v.len() || n < 5 || n.is_multiple_of(2) || !v.iter().all(|x| x.is_finite()) {
        return refused();
    }
    let c = DMatrix::from_row_slice(n, n, v);
    let symmetric = (0..n).all(|i| {
        (0..i).all(|j| (c[(i, j)] - c[(j, i)]).abs() <= 1e-9 * (c[(i, i)] * c[(j, j)]).sqrt().max(f64::MIN_POSITIVE))
    });
    if symmetric && (0..n).all(|i| c[(i, i)] >= 0.0) { Ok(c) } else { refused() }
}

/// A named covariance row-major: the values of the Calibrate response, the `Calibration`
/// message, the `calibration.covariance` parameter and the history's records.
pub fn named_covariance_values(cov: &DMatrix<f64>) -> Vec<f64> {
    (0..cov.nrows()).flat_map(|i| (0..cov.ncols()).map(move |j| cov[(i, j)])).collect()
}

/// Values that are no covariance ([`named_covariance_from_values`]): not `n²` for an odd
/// `n ≥ 5`, not all finite, not symmetric, or with a negative variance.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
#[error(
    "expected n×n finite values of a symmetric matrix with no negative variance, n = 5 and 2 more an angle harmonic (25, 49, 81, ...), got {values} values"
)]
pub struct InvalidCovariance {
    /// How many values there were.
    pub values: usize,
}

/// A fitted calibration.
#[derive(Debug, Clone, PartialEq)]
pub struct Calibration {
    pub model: ModelKind,
    /// The mounting errors and the encoder scale (fitted by `full_scale`, else the scale
    /// in force, [`Options::scale`]).
    pub mounting: Mounting,
    /// Fitted plate centre, metres (in the frame where `alpha0` is as reported).
    pub plate_center: Vector2<f64>,
    /// Standard uncertainty of `[alpha0, offset, delta_l]`.
    pub stddev: [f64; 3],
    /// Covariance of the tracer's parameters ([`Covariance`]: the scale's row is zero
    /// unless the model fits it, the tip radius's until a model fits it).
    pub covariance: Covariance,
    /// Standard uncertainty of the encoder scale; 0 when the model does not fit it.
    pub scale_stddev: f64,
    /// The stylus tip's radius, metres: fitted by the tip models, else the one in force
    /// ([`Options::tip_radius`]).
    pub tip_radius: f64,
    /// Its standard uncertainty; 0 when the model does not fit it.
    pub tip_radius_stddev: f64,
    /// What a tip model fitted to the ring-gauge scan; `None` for the other models.
    pub ring: Option<RingFit>,
    /// The encoder scale the scan shows, by the score test of the models that do not
    /// fit it (module docs); `None` for `full_scale`.
    pub scale_check: Option<ScaleEstimate>,
    /// RMS of the residuals of the samples used, metres.
    pub rms_residual: f64,
    /// LM iterations, all rounds together.
    pub iterations: usize,
    pub samples_used: usize,
    pub samples_rejected: usize,
    pub termination: Termination,
    /// Residual (model - measured, metres) of every sample of the scan, in scan order,
    /// and whether the fit used it.
    pub residuals: Vec<(f64, bool)>,
    /// The turntable's angle error fitted ([`Options::angle_harmonics`]); with none
    /// fitted, [`AngleError::NONE`].
    pub angle: AngleError,
    /// The covariance over [`covariance_names`] of the angle's orders: [`Covariance`]'s
    /// five in its order, then the angle coefficients (`[c_h₁, s_h₁, ...]`).
    pub named_covariance: DMatrix<f64>,
    /// The plate scans after the first, when several placements were fitted.
    pub placements: Vec<PlacementFit>,
    /// The lag-1 correlation of the noise along the plate's trace, as its residuals show
    /// it ([`noise_lag1`]; 0 where they show none, `|φ̂| ≤ 2/√n`): kept with the calibration,
    /// it tells every trace's size uncertainty how its noise is correlated
    /// ([`super::size::TraceNoise`]).
    pub noise_lag1: f64,
}

/// A plate scan after the first of a calibration of several placements.
#[derive(Debug, Clone, PartialEq)]
pub struct PlacementFit {
    /// The plate's turn against the first placement (counter-clockwise), radians, in
    /// `(-π/4, π/4]`.
    pub turn: f64,
    /// Its centre, metres (in its own frame, as [`Calibration::plate_center`]).
    pub center: Vector2<f64>,
    /// RMS of the residuals of its samples used, metres.
    pub rms_residual: f64,
    /// Residual of every sample, in scan order, and whether the fit used it.
    pub residuals: Vec<(f64, bool)>,
}

/// The names of the rows of a calibration's named covariance: `alpha0, offset, delta_l,
/// scale, tip_radius` (the fixed [`Covariance`] layout), then the angle coefficients of
/// `orders` (`angle_c1, angle_s1, ...`).
pub fn covariance_names(orders: HarmonicOrders) -> Vec<String> {
    ["alpha0", "offset", "delta_l", "scale", "tip_radius"]
        .into_iter()
        .map(String::from)
        .chain(coefficient_names(orders))
        .collect()
}

/// What the scans of a plate are called in errors, placement by placement.
const PLATE_NAMES: [&str; 8] = [
    "plate",
    "second plate",
    "third plate",
    "fourth plate",
    "fifth plate",
    "sixth plate",
    "seventh plate",
    "eighth plate",
];

fn plate_name(p: usize) -> &'static str {
    PLATE_NAMES.get(p).copied().unwrap_or("plate")
}

impl Calibration {
    /// The names of [`Calibration::named_covariance`]'s rows ([`covariance_names`]).
    pub fn covariance_names(&self) -> Vec<String> {
        covariance_names(self.angle.orders())
    }

    /// A one-line summary in the units people read: degrees, millimetres, ppm.
    pub fn summary(&self) -> String {
        let scale = if self.model.fits_scale() {
            format!(", scale = {:.6} ± {:.6}", self.mounting.scale, self.scale_stddev)
        } else {
            String::new()
        };
        let tip = if self.model.fits_tip() {
            format!(", tip radius = {:.4} ± {:.4} mm", self.tip_radius * 1e3, self.tip_radius_stddev * 1e3)
        } else {
            String::new()
        };
        let check = match self.scale_check {
            Some(e) => format!(
                ", scale check: {:+.0} ± {:.0} ppm",
                (e.scale / self.mounting.scale - 1.0) * 1e6,
                e.stddev / self.mounting.scale * 1e6
            ),
            None => String::new(),
        };
        let angle: Vec<String> = self
            .angle
            .orders()
            .iter()
            .zip(self.angle.coefficients().chunks_exact(2))
            .map(|(h, cs)| format!("{h}: {:.4}°", cs[0].hypot(cs[1]).to_degrees()))
            .collect();
        let angle =
            if angle.is_empty() { String::new() } else { format!(", angle error (amplitude) {}", angle.join(", ")) };
        let placements = if self.placements.is_empty() {
            String::new()
        } else {
            format!(", {} placements", self.placements.len() + 1)
        };
        format!(
            "{} model: alpha0 = {:.4}° ± {:.4}°, d = {:.4} ± {:.4} mm, dL = {:.4} ± {:.4} mm{scale}{tip}{angle}{placements}, rms residual {:.4} mm, {} samples used, {} rejected, {} iterations{check}",
            self.model,
            self.mounting.alpha0.to_degrees(),
            self.stddev[0].to_degrees(),
            self.mounting.offset * 1e3,
            self.stddev[1] * 1e3,
            self.mounting.delta_l * 1e3,
            self.stddev[2] * 1e3,
            self.rms_residual * 1e3,
            self.samples_used,
            self.samples_rejected,
            self.iterations
        )
    }
}

/// The ring-gauge scan's part of a tip model's fit.
#[derive(Debug, Clone, PartialEq)]
pub struct RingFit {
    /// The ring's fitted centre, metres (in the frame where `alpha0` is as reported).
    pub center: Vector2<f64>,
    /// RMS of the residuals of the ring samples used, metres.
    pub rms_residual: f64,
    /// Residual of every ring sample, in scan order, and whether the fit used it.
    pub residuals: Vec<(f64, bool)>,
}

/// Why a calibration failed.
#[derive(Debug, Clone, PartialEq)]
pub enum CalibrationError {
    InvalidPlate(PlateError),
    TooFewSamples {
        got: usize,
        need: usize,
    },
    NoStart,
    Model(String),
    NotConverged {
        termination: Termination,
        iterations: usize,
    },
    Singular,
    ResidualTooLarge {
        rms: f64,
        limit: f64,
    },
    SystematicResidual {
        rms: f64,
        noise: f64,
    },
    /// The residuals of a scan (`"plate"`) show structure the model lacks at level `alpha`
    /// (the harmonic test, [`super::lack_of_fit`]).
    Structure {
        scan: &'static str,
        structure: Box<Structure>,
        alpha: f64,
    },
    /// An angle harmonic the plate's placements cannot tell from the plate's own shape
    /// ([`super::model::turntable`]): its order, its variance inflation, how many
    /// placements there were.
    HarmonicInseparable {
        order: u32,
        inflation: f64,
        placements: usize,
    },
    /// More plate scans than a calibration takes.
    TooManyPlacements(usize),
    /// The scan shows an encoder scale off from the one in force (`k0`).
    ScaleOff {
        estimate: ScaleEstimate,
        k0: f64,
    },
    InvalidScale(f64),
    /// More than [`Options::max_rejected_fraction`] of a scan's samples were outliers.
    TooManyOutliers {
        rejected: usize,
        samples: usize,
        /// Which scan: "plate" or "ring-gauge".
        scan: &'static str,
    },
    /// A tip model was asked for without a ring-gauge scan, or the ring is invalid.
    Ring(String),
    /// The tip radius in force is not a length a stylus can have.
    InvalidTipRadius(f64),
    /// The ring-gauge scan does not fit the ring (rms residual above the limit, or
    /// systematic residuals: `noise` is what neighbouring samples show).
    RingMismatch {
        rms: f64,
        noise: Option<f64>,
        diameter: f64,
    },
    /// A tip model's ring and plate disagree as a ring whose groove is not the one entered
    /// would make them: the plate's scale agrees with the one in force when the ring's
    /// groove has included angle `fits` ± `stddev` (rad), not `entered`
    /// ([`crate::stylus`]).
    RingGroove {
        entered: f64,
        fits: f64,
        stddev: f64,
    },
    /// The fitted tip radius is not one a stylus can have.
    TipRadiusImplausible {
        radius: f64,
        stddev: f64,
        diameter: f64,
    },
}

impl fmt::Display for CalibrationError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::InvalidPlate(why) => write!(f, "invalid plate: {why}"),
            Self::TooFewSamples { got, need } => {
                write!(f, "too few samples: {got} usable, at least {need} needed")
            }
            Self::NoStart => write!(
                f,
                "no starting point fits the scan: it does not look like the calibration plate (check plate.side and encoder.meters_per_count)"
            ),
            Self::Model(why) => write!(f, "{why}"),
            Self::NotConverged { termination, iterations } => {
                write!(f, "the fit {} after {iterations} iterations", termination.describe())
            }
            Self::Singular => write!(f, "the fit is degenerate (the samples do not determine all parameters)"),
            Self::ResidualTooLarge { rms, limit } => write!(
                f,
                "rms residual {:.3} mm exceeds {:.3} mm: the scan does not match the plate (check plate.side, plate.corner_radius, encoder.meters_per_count, and that the plate is seated)",
                rms * 1e3,
                limit * 1e3
            ),
            Self::SystematicResidual { rms, noise } => write!(
                f,
                "the residuals are systematic (rms {:.4} mm where neighbouring samples scatter by {:.4} mm): the scan does not match the plate (check plate.side, plate.corner_radius, encoder.meters_per_count, and stylus.tip_radius: a tip of a tenth of a millimetre or more shows in the corners, and the models full_tip and full_scale_tip fit it from a ring gauge)",
                rms * 1e3,
                noise * 1e3
            ),
            Self::Structure { scan, structure, alpha } => write!(
                f,
                "the {scan} scan's residuals show structure the model lacks (harmonic test at calibration.lack_of_fit_alpha = {alpha}): {}",
                structure.describe()
            ),
            Self::ScaleOff { estimate, k0 } => {
                let rel = estimate.scale / k0 - 1.0;
                write!(
                    f,
                    "the encoder scale looks off: the scan shows scale {:.6} ± {:.6} where {k0} is in force ({:+.3} %, {:.0} σ): the tracer reads lengths {:.3} % too {} ({:.0} µm on a 25 mm radius), which dL would hide only at the plate's own radius; calibrate with model full_scale, or check encoder.meters_per_count and plate.side",
                    estimate.scale,
                    estimate.stddev,
                    rel * 100.0,
                    estimate.sigmas_from(*k0),
                    rel.abs() * 100.0,
                    if rel < 0.0 { "long" } else { "short" },
                    (rel * 25e-3 * 1e6).abs(),
                )
            }
            Self::RingGroove { entered, fits, stddev } => write!(
                f,
                "the ring gauge's groove does not fit the scans: the plate and the ring agree with the encoder scale in force when the ring's groove has an included angle of {:.1}° ± {:.1}°, where ring.groove_angle is {:.1}°{}: set ring.groove_angle (rad) to the ring's certified groove angle, ring.diameter to its groove bottom's diameter, and check that the scan is of the ring gauge",
                fits.to_degrees(),
                stddev.to_degrees(),
                entered.to_degrees(),
                if *entered == crate::stylus::PLAIN_BORE { " (a plain bore)" } else { "" },
            ),
            Self::InvalidScale(k) => write!(f, "the encoder scale in force must be a positive number, got {k}"),
            Self::HarmonicInseparable { order, inflation, placements } => {
                let what =
                    if *placements == 1 { "one placement".to_string() } else { format!("{placements} placements") };
                let why = if order % 4 == 0 {
                    format!(
                        "the square plate repeats every quarter turn, so an angle error {order} times a turn moves its lengths as a change of its own shape would"
                    )
                } else {
                    format!("its coefficients' variance is {inflation:.0} times what it would be alone")
                };
                write!(
                    f,
                    "angle harmonic {order} cannot be told apart with {what} of the plate: {why}; add a scan of the plate turned by about {:.1}° (plate_scan_ids, or the offline --plate-scans) or leave {order} out of calibration.angle_harmonics",
                    if *order <= 12 { 22.5 } else { 180.0 / f64::from(*order) }
                )
            }
            Self::TooManyPlacements(n) => {
                write!(f, "{n} plate scans given: a calibration takes at most {MAX_PLACEMENTS}")
            }
            Self::TooManyOutliers { rejected, samples, scan } => write!(
                f,
                "{rejected} of the {samples} samples of the {scan} scan do not fit the model: it does not look like the {}",
                if *scan != "ring-gauge" {
                    "calibration plate (check plate.side, plate.corner_radius, encoder.meters_per_count, and that the plate is seated)"
                } else {
                    "ring gauge (check ring.diameter, and that the scan is of the ring gauge)"
                }
            ),
            Self::Ring(why) => write!(f, "{why}"),
            Self::InvalidTipRadius(r) => {
                write!(f, "the stylus tip radius in force must be a length of at least 0 m, got {r}")
            }
            Self::RingMismatch { rms, noise, diameter } => {
                let why = match noise {
                    Some(n) => format!(
                        "rms residual {:.4} mm where neighbouring samples scatter by {:.4} mm",
                        rms * 1e3,
                        n * 1e3
                    ),
                    None => format!("rms residual {:.4} mm", rms * 1e3),
                };
                write!(
                    f,
                    "the ring-gauge scan does not fit a ring of {:.4} mm ({why}): check ring.diameter, and that the scan is of the ring gauge, traced from inside",
                    diameter * 1e3
                )
            }
            Self::TipRadiusImplausible { radius, stddev, diameter } => write!(
                f,
                "the fitted tip radius {:.4} ± {:.4} mm is not one a stylus has: the ring gauge's diameter ({:.4} mm, ring.diameter) or the plate's size does not fit the scans",
                radius * 1e3,
                stddev * 1e3,
                diameter * 1e3
            ),
        }
    }
}

impl std::error::Error for CalibrationError {}

/// Fit the mounting errors to a scan of the calibration plate, with a model that needs
/// no ring-gauge scan ([`calibrate_with_ring`] for the tip models).
pub fn calibrate(scan: &Scan, plate: &PlateSpec, opt: &Options) -> Result<Calibration, CalibrationError> {
    calibrate_with_ring(scan, None, plate, opt)
}

/// A ring-gauge scan and the ring's certified size: what the tip models fit `ρ` from.
#[derive(Debug, Clone, Copy)]
pub struct Ring<'a> {
    pub scan: &'a Scan,
    pub spec: RingSpec,
}

/// Fit the mounting errors to a scan of the calibration plate and, for the tip models
/// (`full_tip`, `full_scale_tip`), a scan of the ring gauge (ignored by the others).
pub fn calibrate_with_ring(
    scan: &Scan,
    ring: Option<Ring>,
    plate: &PlateSpec,
    opt: &Options,
) -> Result<Calibration, CalibrationError> {
    calibrate_placements(&[scan], ring, plate, opt)
}

/// Plate scans a calibration takes at most.
pub const MAX_PLACEMENTS: usize = 8;

/// Fit the mounting errors to one or several scans of the calibration plate, each a
/// placement with its own centre and turn ([`super::model::turntable`]), with the angle
/// harmonics of [`Options::angle_harmonics`], and a ring-gauge scan for the tip models.
/// One scan and no harmonics is the plain models' fit.
pub fn calibrate_placements(
    plates: &[&Scan],
    ring: Option<Ring>,
    plate: &PlateSpec,
    opt: &Options,
) -> Result<Calibration, CalibrationError> {
    plate.validate().map_err(CalibrationError::InvalidPlate)?;
    let need = opt.min_samples.max(6);
    let Some(&scan) = plates.first() else {
        return Err(CalibrationError::TooFewSamples { got: 0, need });
    };
    if plates.len() > MAX_PLACEMENTS {
        return Err(CalibrationError::TooManyPlacements(plates.len()));
    }
    if let Some(short) = plates.iter().find(|s| s.len() < need) {
        return Err(CalibrationError::TooFewSamples { got: short.len(), need });
    }
    if opt.model == ModelKind::Paper && (plates.len() > 1 || !opt.angle_harmonics.is_empty()) {
        return Err(CalibrationError::Model(
            "the paper's model fits one plate scan without angle harmonics: use model full (or full_scale, full_tip, full_scale_tip) for several placements or calibration.angle_harmonics".into(),
        ));
    }
    if !(opt.scale.is_finite() && opt.scale > 0.0) {
        return Err(CalibrationError::InvalidScale(opt.scale));
    }
    if !(opt.tip_radius.is_finite() && opt.tip_radius >= 0.0) {
        return Err(CalibrationError::InvalidTipRadius(opt.tip_radius));
    }
    // The models that do not fit the scale see true lengths, k₀ rho; full_scale sees
    // the encoder's own.
    let known_scale = if opt.model.fits_scale() { 1.0 } else { opt.scale };
    let scaled = |scan: &Scan| -> Result<Scan, CalibrationError> {
        scan.scaled(known_scale).map_err(|e| CalibrationError::Model(e.to_string()))
    };
    let scan: Cow<Scan> = if known_scale == 1.0 { Cow::Borrowed(scan) } else { Cow::Owned(scaled(scan)?) };
    if opt.model.fits_tip() {
        let ring = ring.ok_or_else(|| {
            CalibrationError::Ring(format!(
                "model {} fits the tip radius from a ring-gauge scan and none was given: trace the ring gauge (target TARGET_RING_GAUGE) and set ring.diameter",
                opt.model
            ))
        })?;
        ring.spec.validate().map_err(|e| CalibrationError::Ring(e.to_string()))?;
        if ring.scan.len() < need {
            return Err(CalibrationError::Ring(format!(
                "the ring-gauge scan has {} samples, at least {need} needed",
                ring.scan.len()
            )));
        }
        let ring_scan = if known_scale == 1.0 { Cow::Borrowed(ring.scan) } else { Cow::Owned(scaled(ring.scan)?) };
        if plates.len() > 1 || !opt.angle_harmonics.is_empty() {
            let plates = plates.iter().map(|s| scaled(s)).collect::<Result<Vec<_>, _>>()?;
            let fit_with = |spec: &RingSpec| fit_turntable(&plates, Some((&ring_scan, spec)), plate, opt, known_scale);
            return match fit_with(&ring.spec) {
                Err(CalibrationError::ScaleOff { estimate, .. }) => {
                    // The scale the plates show with the ring's groove taken as `spec`.
                    let scale_at = |spec: &RingSpec| match fit_with(spec) {
                        Ok(cal) => cal.scale_check.map(|e| relative_scale(e, opt)),
                        Err(CalibrationError::ScaleOff { estimate, .. }) => Some(relative_scale(estimate, opt)),
                        Err(_) => None,
                    };
                    Err(ring_groove_instead(&ring.spec, opt, estimate, scale_at)
                        .unwrap_or(CalibrationError::ScaleOff { estimate, k0: opt.scale }))
                }
                other => other,
            };
        }
        let fit = fit_tip(&scan, &ring_scan, &ring.spec, plate, opt)?;
        let fit = Fit { scale: fit.scale * known_scale, ..fit };
        let grown = FullModel::from_scan(&plate.grown(fit.tip_radius), &scan);
        let x = fit.x;
        let score = |tested: &[bool]| {
            scale_score(grown.retain(|i| tested[i]), &x, opt.plate_side_uncertainty, noise_only(tested))
        };
        let result = finish(&scan, &[], fit, Some((&ring_scan, &ring.spec)), opt, score);
        return match result {
            Err(CalibrationError::ScaleOff { estimate, .. }) => {
                let scale_at = |spec: &RingSpec| {
                    let fit = fit_tip(&scan, &ring_scan, spec, plate, opt).ok()?;
                    let grown = FullModel::from_scan(&plate.grown(fit.tip_radius), &scan);
                    scale_score(
                        grown.retain(|i| fit.used[i]),
                        &fit.x,
                        opt.plate_side_uncertainty,
                        noise_only(&fit.used),
                    )
                };
                Err(ring_groove_instead(&ring.spec, opt, estimate, scale_at)
                    .unwrap_or(CalibrationError::ScaleOff { estimate, k0: opt.scale }))
            }
            other => other,
        };
    }
    if plates.len() > 1 || !opt.angle_harmonics.is_empty() {
        let plates = plates.iter().map(|s| scaled(s)).collect::<Result<Vec<_>, _>>()?;
        return fit_turntable(&plates, None, plate, opt, known_scale);
    }
    // The centre of a tip of radius ρ traces the plate grown by ρ.
    let grown = plate.grown(opt.tip_radius);
    let all = FullModel::from_scan(&grown, &scan);
    let start = initial_guess(&all, &grown).ok_or(CalibrationError::NoStart)?;
    let fit = match opt.model {
        ModelKind::Full => fit_full(&all, start.x, opt)?,
        ModelKind::Paper => fit_paper(&scan, &grown, &all, wrap(start.x), opt)?,
        ModelKind::FullScale => fit_full_scale(&all, start.x, opt)?,
        ModelKind::FullTip | ModelKind::FullScaleTip => unreachable!("fitted above"),
    };
    let fit = Fit { scale: fit.scale * known_scale, tip_radius: opt.tip_radius, ..fit };
    let x = fit.x;
    let score =
        |tested: &[bool]| scale_score(all.retain(|i| tested[i]), &x, opt.plate_side_uncertainty, noise_only(tested));
    finish(&scan, &[], fit, None, opt, score)
}

/// What a model's fit hands to [`finish`].
struct Fit {
    model: ModelKind,
    x: full::Params,
    /// The encoder scale (fitted, or 1 relative to the lengths fitted).
    scale: f64,
    /// In the [`Covariance`] layout.
    covariance: Covariance,
    /// Samples the fit used.
    used: Vec<bool>,
    /// Samples rejected as outliers.
    rejected: usize,
    residuals: Vec<f64>,
    iterations: usize,
    termination: Termination,
    /// The tip radius, fitted or in force.
    tip_radius: f64,
    /// A tip model's ring: its centre (as fitted, before [`wrap`]), residuals and which
    /// samples it used.
    ring: Option<(Vector2<f64>, Vec<f64>, Vec<bool>)>,
    /// The angle error fitted.
    angle: AngleError,
    /// The covariance over [`covariance_names`] when the angle has coefficients (else
    /// `covariance`'s).
    named: Option<DMatrix<f64>>,
    /// The placements after the first.
    placements: Vec<PlacementPart>,
}

/// A placement after the first as fitted: the plate's turn, its centre (before [`wrap`]),
/// its residuals and the samples used.
struct PlacementPart {
    turn: f64,
    center: Vector2<f64>,
    residuals: Vec<f64>,
    used: Vec<bool>,
}

/// The checks of one plate scan's residuals (`rejected` of its samples outliers; the
/// paper's model uses fewer than it keeps): not too many outliers, an RMS a plate scan
/// can have, and not systematic against the noise neighbouring samples show; its RMS.
fn check_plate(
    scan: &Scan,
    residuals: &[f64],
    used: &[bool],
    rejected: usize,
    opt: &Options,
    name: &'static str,
) -> Result<f64, CalibrationError> {
    let n_used = used.iter().filter(|&&u| u).count();
    if rejected as f64 > opt.max_rejected_fraction * used.len() as f64 {
        return Err(CalibrationError::TooManyOutliers { rejected, samples: used.len(), scan: name });
    }
    let ss: f64 = residuals.iter().zip(used).filter(|(_, a)| **a).map(|(r, _)| r * r).sum();
    let rms = (ss / n_used.max(1) as f64).sqrt();
    if rms.is_nan() || rms > opt.max_rms_residual {
        return Err(CalibrationError::ResidualTooLarge { rms, limit: opt.max_rms_residual });
    }
    if let Some(noise) = neighbour_noise(scan, residuals, used)
        && rms > opt.systematic_floor
        && rms > opt.max_lack_of_fit * noise
    {
        return Err(CalibrationError::SystematicResidual { rms, noise });
    }
    Ok(rms)
}

/// The checks of a fit and its report. `more`: the plate scans after the first, as
/// `fit.placements`; `score`: the score test of the scale on the samples tested (those of
/// the first scan given; a fit of several placements tests all of its own).
fn finish(
    scan: &Scan,
    more: &[Scan],
    fit: Fit,
    ring: Option<(&Scan, &RingSpec)>,
    opt: &Options,
    score: impl FnOnce(&[bool]) -> Option<ScaleEstimate>,
) -> Result<Calibration, CalibrationError> {
    let mut fit = fit;
    // The plate's seating against the frame holder's datum: alpha0 as the plate lies.
    let seating = opt.seating_uncertainty * opt.seating_uncertainty;
    fit.covariance[(layout::ALPHA0, layout::ALPHA0)] += seating;
    if let Some(named) = fit.named.as_mut() {
        named[(layout::ALPHA0, layout::ALPHA0)] += seating;
    }
    let used = fit.used.iter().filter(|&&a| a).count();
    if used < opt.min_samples {
        return Err(CalibrationError::TooFewSamples { got: used, need: opt.min_samples });
    }
    let too_many = |rejected: usize, samples: usize| rejected as f64 > opt.max_rejected_fraction * samples as f64;
    let rms = check_plate(scan, &fit.residuals, &fit.used, fit.rejected, opt, plate_name(0))?;
    let mut placement_rms = Vec::with_capacity(more.len());
    for (p, (scan, part)) in more.iter().zip(&fit.placements).enumerate() {
        let rejected = part.used.iter().filter(|&&u| !u).count();
        placement_rms.push(check_plate(scan, &part.residuals, &part.used, rejected, opt, plate_name(p + 1))?);
    }
    let scale_check = if fit.model.fits_scale() {
        None
    } else {
        // The scale shows in how the plate's radius varies round the turn, most near the
        // corners: test every sample that is not an outlier, also those the paper's
        // model leaves out (it uses flat samples only).
        let tested = match fit.model {
            ModelKind::Paper => inliers(&fit.residuals, opt.outlier_threshold),
            _ => fit.used.clone(),
        };
        let relative = score(&tested).ok_or(CalibrationError::Singular)?;
        let estimate = ScaleEstimate { scale: relative.scale * opt.scale, stddev: relative.stddev * opt.scale };
        let off = (relative.scale - 1.0).abs();
        if off > opt.scale_tolerance && off > opt.max_scale_sigma * relative.stddev {
            return Err(CalibrationError::ScaleOff { estimate, k0: opt.scale });
        }
        Some(estimate)
    };
    // After the scale check: a scale off shows at harmonics 4, 8, 12 too, and that check
    // says it more precisely.
    if opt.lack_of_fit_alpha > 0.0 {
        let plates = std::iter::once((scan, &fit.residuals, &fit.used))
            .chain(more.iter().zip(&fit.placements).map(|(s, part)| (s, &part.residuals, &part.used)));
        for (p, (scan, residuals, used)) in plates.enumerate() {
            let steps: Vec<u32> = scan.samples().iter().map(|s| s.step).collect();
            if let Some(structure) = harmonic_test(&steps, scan.steps_per_rev(), residuals, used)
                && structure.refused_at(opt.lack_of_fit_alpha)
            {
                return Err(CalibrationError::Structure {
                    scan: plate_name(p),
                    structure: Box::new(structure),
                    alpha: opt.lack_of_fit_alpha,
                });
            }
        }
    }
    let stddev_of = |i: usize| fit.covariance[(i, i)].max(0.0).sqrt();
    let tip_radius_stddev = stddev_of(layout::TIP_RADIUS);
    let (_, quarter_turns) = wrap_quarter_turn(fit.x[full::ALPHA0]);
    let ring_fit = match (fit.ring, ring) {
        (Some((center, residuals, used)), Some((ring_scan, spec))) => {
            let n_used = used.iter().filter(|&&u| u).count();
            if too_many(used.len() - n_used, used.len()) {
                return Err(CalibrationError::TooManyOutliers {
                    rejected: used.len() - n_used,
                    samples: used.len(),
                    scan: "ring-gauge",
                });
            }
            let ss: f64 = residuals.iter().zip(&used).filter(|(_, u)| **u).map(|(r, _)| r * r).sum();
            let rms = (ss / n_used.max(1) as f64).sqrt();
            let diameter = spec.diameter;
            if rms.is_nan() || rms > opt.max_rms_residual {
                return Err(CalibrationError::RingMismatch { rms, noise: None, diameter });
            }
            if let Some(noise) = neighbour_noise(ring_scan, &residuals, &used)
                && rms > opt.systematic_floor
                && rms > opt.max_lack_of_fit * noise
            {
                return Err(CalibrationError::RingMismatch { rms, noise: Some(noise), diameter });
            }
            let tip = fit.tip_radius;
            // A tip radius that is negative beyond its uncertainty, or larger than any
            // stylus: the ring's diameter (or the plate's size) does not fit the scans.
            if !(tip >= -(3.0 * tip_radius_stddev + 1e-6) && tip <= opt.max_tip_radius && tip < diameter / 4.0) {
                return Err(CalibrationError::TipRadiusImplausible {
                    radius: tip,
                    stddev: tip_radius_stddev,
                    diameter,
                });
            }
            Some(RingFit {
                center: rotate_quarter_turns(center, quarter_turns),
                rms_residual: rms,
                residuals: residuals.into_iter().zip(used).collect(),
            })
        }
        _ => None,
    };
    let x = wrap(fit.x);
    let (mounting, plate_center) = full::unpack(&x);
    let stddev = [layout::ALPHA0, layout::OFFSET, layout::DELTA_L].map(stddev_of);
    let scale_stddev = stddev_of(layout::SCALE);
    let named_covariance = fit.named.unwrap_or_else(|| DMatrix::from_fn(5, 5, |i, j| fit.covariance[(i, j)]));
    if !(named_covariance.iter().all(|s| s.is_finite()) && x.iter().all(|v| v.is_finite()) && fit.scale.is_finite()) {
        return Err(CalibrationError::Singular);
    }
    // Each later placement's centre turns with alpha0's quarter turns, then with its own.
    let placements: Vec<PlacementFit> = fit
        .placements
        .into_iter()
        .zip(placement_rms)
        .map(|(part, rms_residual)| {
            let (turn, own) = wrap_quarter_turn(part.turn);
            PlacementFit {
                turn,
                center: rotate_quarter_turns(part.center, quarter_turns - own),
                rms_residual,
                residuals: part.residuals.into_iter().zip(part.used).collect(),
            }
        })
        .collect();
    let plate_used: Vec<f64> = fit.residuals.iter().zip(&fit.used).filter(|(_, u)| **u).map(|(r, _)| *r).collect();
    let lag1 = noise_lag1(&plate_used)
        .filter(|phi| phi.abs() > 2.0 / (plate_used.len() as f64).sqrt())
        .map_or(0.0, |phi| phi.clamp(-0.95, 0.95));
    let more_used: usize = placements.iter().map(|p| p.residuals.iter().filter(|r| r.1).count()).sum();
    let more_rejected: usize = placements.iter().map(|p| p.residuals.iter().filter(|r| !r.1).count()).sum();
    Ok(Calibration {
        model: fit.model,
        mounting: mounting.with_scale(fit.scale),
        plate_center,
        stddev,
        covariance: fit.covariance,
        scale_stddev,
        tip_radius: fit.tip_radius,
        tip_radius_stddev,
        ring: ring_fit,
        scale_check,
        rms_residual: rms,
        iterations: fit.iterations,
        samples_used: used + more_used,
        samples_rejected: fit.rejected + more_rejected,
        termination: fit.termination,
        residuals: fit.residuals.into_iter().zip(fit.used).collect(),
        angle: fit.angle,
        named_covariance,
        placements,
        noise_lag1: lag1,
    })
}

/// The score test of the encoder scale (module docs): one Gauss-Newton step of the
/// encoder-scale model from the full model's parameters `x` at `k = 1`; its scale
/// component and that component's standard uncertainty. `model` holds the lengths the
/// fit saw (true lengths under the scale in force), so the result is relative to it.
/// A plate whose side is certified to `side_u` only adds that to the uncertainty (a
/// plate a little larger looks like an encoder reading a little short): the step's
/// sensitivity to the side, `-(JᵀJ)⁻¹ Jᵀ ∂r/∂S`, times `side_u` (as `inputs_of` does).
/// `noise_only`: the residuals may be taken for noise (a fit that rejected at most 1 % of
/// its samples), so that noise correlated along the trace widens the test.
pub fn scale_score(model: FullModel, x: &full::Params, side_u: f64, noise_only: bool) -> Option<ScaleEstimate> {
    let b = model.side_sensitivity(x, 0.0)?;
    score_test(&FullScaleModel::new(model), &full_scale::from_full(x, 1.0), full_scale::SCALE, &b, side_u, noise_only)
}

/// Whether the residuals of a fit that kept the samples `used` may be taken for noise,
/// correlated or not: it rejected at most [`MAX_NOISE_REJECTED`] of them. Noise, even
/// correlated, is Gaussian and leaves next to none beyond the outlier threshold; a misfit
/// (a ring gauge of another diameter than the one set, whose plate corners are then
/// fitted with the wrong tip) leaves its structure beyond it in places, and at every
/// harmonic, where the residuals' spectrum would take it for correlated noise.
fn noise_only(used: &[bool]) -> bool {
    let rejected = used.iter().filter(|&&u| !u).count();
    rejected as f64 <= MAX_NOISE_REJECTED * used.len() as f64
}

/// [`scale_score`] of any model that fits the scale, at its parameters `x` with `k = 1`
/// at index `k`; `b`: how each residual moves with the plate's side.
fn score_test<D: Dim>(
    model: &impl Problem<D>,
    x: &OVector<f64, D>,
    k: usize,
    b: &[f64],
    side_u: f64,
    noise_only: bool,
) -> Option<ScaleEstimate>
where
    DefaultAllocator: Allocator<D> + Allocator<D, D>,
{
    let ne = lm::normal_equations(model, x)?;
    let (n, p) = (ne.count, x.len());
    if n <= p {
        return None;
    }
    let inv = ne.jtj.clone().cholesky()?.inverse();
    let step = -(&inv * &ne.jtr);
    // σ̂² from the residuals after the step: ‖r‖² - gᵀ(JᵀJ)⁻¹g, the linearised cost.
    let ss = (2.0 * ne.cost - ne.jtr.dot(&(&inv * &ne.jtr))).max(0.0);
    let sigma2 = ss / (n - p) as f64;
    let side = inputs_of(model, x, &[Input { dr: Cow::Borrowed(b), u: side_u, own: None }], &[Some(k)]).ok()?[(0, 0)];
    // Noise correlated along the trace widens the estimate as it does the fit's
    // ([`correlated`]), its lag-1 correlation taken from the residuals *after* the step:
    // a wrong scale leaves structure at every harmonic of the plate's corners, which the
    // residuals at `x` would pass off as correlated noise, widening the very test meant to
    // catch it; the step takes it out, and what is left is the noise. Not when the
    // residuals are more than noise (`noise_only`): then the white-noise variance.
    let phi = noise_only
        .then(|| {
            let mut after = Vec::with_capacity(n);
            model.for_each_row(x, |r, j| after.push(r + j.dot(&step)));
            correlated_lag1(&after)
        })
        .flatten();
    let noise = match phi {
        Some(phi) => (&inv * ar1_information(model, x, phi, &ne.jtj) * &inv)[(k, k)],
        None => inv[(k, k)],
    };
    let var = noise * sigma2 + side;
    let est = ScaleEstimate { scale: 1.0 + step[k], stddev: var.max(0.0).sqrt() };
    (est.scale.is_finite() && est.stddev.is_finite() && est.stddev > 0.0).then_some(est)
}

/// The noise seen between neighbouring samples: `RMS(r_i - r_j) / √2` over used samples
/// one step apart. Blind to smooth (systematic) residuals, which it is there to expose.
fn neighbour_noise(scan: &Scan, residuals: &[f64], used: &[bool]) -> Option<f64> {
    let n = scan.steps_per_rev();
    let mut at_step: Vec<(u32, f64)> =
        scan.samples().iter().zip(residuals).zip(used).filter(|(_, u)| **u).map(|((s, r), _)| (s.step, *r)).collect();
    at_step.sort_unstable_by_key(|&(step, _)| step);
    let (mut ss, mut count) = (0.0, 0usize);
    let mut pair = |(_, a): (u32, f64), (_, b): (u32, f64)| {
        ss += (a - b) * (a - b);
        count += 1;
    };
    for w in at_step.windows(2) {
        if w[1].0 == w[0].0 + 1 {
            pair(w[0], w[1]);
        }
    }
    // The last step and step 0 are neighbours too.
    if let (Some(&first), Some(&last)) = (at_step.first(), at_step.last())
        && at_step.len() > 2
        && first.0 == 0
        && last.0 == n - 1
    {
        pair(last, first);
    }
    (count >= 10).then(|| (ss / (2.0 * count as f64)).sqrt())
}

/// `alpha0` into `(-π/4, π/4]`, the plate centre turned with it.
fn wrap(x: full::Params) -> full::Params {
    let (alpha0, q) = wrap_quarter_turn(x[full::ALPHA0]);
    let c = rotate_quarter_turns(Vector2::new(x[full::CX], x[full::CY]), q);
    full::Params::from([alpha0, x[full::OFFSET], x[full::DELTA_L], c.x, c.y])
}

/// Which samples to keep: `|r| <= k · 1.4826 · MAD(r)` (at least the floor).
fn inliers(residuals: &[f64], k: f64) -> Vec<bool> {
    let mut sorted: Vec<f64> = residuals.to_vec();
    let med = median(&mut sorted);
    let mut dev: Vec<f64> = residuals.iter().map(|r| (r - med).abs()).collect();
    let sigma = 1.4826 * median(&mut dev);
    let limit = (k * sigma).max(OUTLIER_FLOOR);
    residuals.iter().map(|r| (r - med).abs() <= limit).collect()
}

fn median(v: &mut [f64]) -> f64 {
    let mid = v.len() / 2;
    let (_, m, _) = v.select_nth_unstable_by(mid, f64::total_cmp);
    *m
}

/// A model over a subset of the plate scan's samples, for the rejection rounds.
trait Subset {
    /// The model of the samples for which `keep(index)` is true.
    fn subset(&self, keep: impl FnMut(usize) -> bool) -> Self;
}

impl Subset for FullModel {
    fn subset(&self, keep: impl FnMut(usize) -> bool) -> Self {
        self.retain(keep)
    }
}

impl Subset for FullScaleModel {
    fn subset(&self, keep: impl FnMut(usize) -> bool) -> Self {
        FullScaleModel::new(self.full().retain(keep))
    }
}

impl Subset for TurntableModel {
    fn subset(&self, keep: impl FnMut(usize) -> bool) -> Self {
        self.retain(keep)
    }
}

impl Subset for TipModel {
    fn subset(&self, keep: impl FnMut(usize) -> bool) -> Self {
        self.retain(keep)
    }
}

impl Subset for TipScaleModel {
    fn subset(&self, keep: impl FnMut(usize) -> bool) -> Self {
        TipScaleModel::new(self.tip().retain(keep))
    }
}

/// What the rejection rounds of a model fitted to every sample found.
struct Rounds<D: Dim>
where
    DefaultAllocator: Allocator<D> + Allocator<D, D>,
{
    x: OVector<f64, D>,
    covariance: OMatrix<f64, D, D>,
    /// Samples the fit used.
    active: Vec<bool>,
    /// Residual of every sample (used or not) at `x`.
    residuals: DVector<f64>,
    iterations: usize,
    termination: Termination,
}

/// The covariance of a least-squares fit under noise correlated along the trace (module
/// docs, step 5), or `None` when the residuals show no correlation (`|φ̂| ≤ 2/√n`, the
/// white-noise covariance `white` stands).
///
/// With AR(1) noise of lag-1 correlation `φ` between consecutive samples (stick-slip, an
/// encoder's interpolation error), `Cov(r_i, r_j) = σ² φ^|i-j|` and the estimate's covariance
/// is the sandwich `(JᵀJ)⁻¹ JᵀΣJ (JᵀJ)⁻¹`, not `σ²(JᵀJ)⁻¹`: at `φ = 0.8` the latter is 1.6 to
/// 3 times too small for the parameters that move every sample the same way (`dL`, the
/// scale). `φ̂` from the residuals' spectrum above harmonic 12 ([`noise_lag1`]), where a
/// misfit's smooth structure is not (a wrong ring gauge's residuals are correlated too, and
/// must still look wrong); `JᵀΣJ` in one pass by the
/// recursion `F_i = J_i + φ F_(i-1)`: `Σ_(j≤i) φ^(i-j) J_i J_jᵀ = Σ_i J_i F_iᵀ`, so
/// `JᵀΣJ/σ² = Σ_i (J_i F_iᵀ + F_i J_iᵀ - J_i J_iᵀ)`. `residuals`: the fit's, row by row;
/// `ne` its normal equations (`JᵀJ`, `σ̂²`) and `white` its covariance `σ̂²(JᵀJ)⁻¹`.
fn correlated<D: Dim>(
    model: &impl Problem<D>,
    x: &OVector<f64, D>,
    residuals: &[f64],
    ne: &lm::NormalEquations<D>,
    white: &OMatrix<f64, D, D>,
) -> Option<OMatrix<f64, D, D>>
where
    DefaultAllocator: Allocator<D> + Allocator<D, D>,
{
    let phi = correlated_lag1(residuals)?;
    let m = ar1_information(model, x, phi, &ne.jtj);
    // white = σ̂² A⁻¹ (σ̂² = ‖r‖²/(n - P), as lm::covariance): the sandwich σ̂² A⁻¹ M A⁻¹
    // = white M white / σ̂².
    let sigma2 = 2.0 * ne.cost / ne.count.saturating_sub(x.len()).max(1) as f64;
    let sandwich = white * m * white / sigma2;
    sandwich.iter().all(|v| v.is_finite()).then_some(sandwich)
}

/// The lag-1 correlation of the noise in `residuals` ([`noise_lag1`]), clamped to
/// ±0.95; `None` where it shows none (`|φ̂| ≤ 2/√n`: the white-noise covariance stands).
fn correlated_lag1(residuals: &[f64]) -> Option<f64> {
    let phi = noise_lag1(residuals)?;
    (phi.abs() > 2.0 / (residuals.len() as f64).sqrt()).then(|| phi.clamp(-0.95, 0.95))
}

/// `JᵀRJ`, `R_ij = φ^|i-j|` the correlation of AR(1) noise along the rows of `model` at
/// `x`, by the recursion `F_i = J_i + φ F_(i-1)`: `Σ_i (J_i F_iᵀ + F_i J_iᵀ - J_i J_iᵀ)`
/// ([`correlated`]); `jtj` is `JᵀJ`, the last sum.
fn ar1_information<D: Dim>(
    model: &impl Problem<D>,
    x: &OVector<f64, D>,
    phi: f64,
    jtj: &OMatrix<f64, D, D>,
) -> OMatrix<f64, D, D>
where
    DefaultAllocator: Allocator<D> + Allocator<D, D>,
{
    let (dim, _) = x.shape_generic();
    let mut forward = OVector::<f64, D>::zeros_generic(dim, nalgebra::Const::<1>);
    let mut m = OMatrix::<f64, D, D>::zeros_generic(dim, dim);
    model.for_each_row(x, |_, j| {
        forward *= phi;
        forward += j;
        m.ger(1.0, j, &forward, 1.0);
    });
    &m + m.transpose() - jtj
}

/// Fit, reject outliers, refit from where the fit stands, until the set of samples
/// stops changing (module docs, step 3).
fn fit_rounds<D: Dim, M: Problem<D> + Subset>(
    all: &M,
    x0: OVector<f64, D>,
    opt: &Options,
) -> Result<Rounds<D>, CalibrationError>
where
    DefaultAllocator: Allocator<D> + Allocator<D, D>,
{
    let mut active = vec![true; all.residual_count()];
    let mut x = x0;
    let mut iterations = 0;
    for round in 0..MAX_ROUNDS {
        let model = all.subset(|i| active[i]);
        if model.residual_count() < opt.min_samples {
            return Err(CalibrationError::TooFewSamples { got: model.residual_count(), need: opt.min_samples });
        }
        let rep = lm::minimize(&model, x, &opt.lm);
        iterations += rep.iterations;
        if !rep.termination.converged() {
            return Err(CalibrationError::NotConverged { termination: rep.termination, iterations });
        }
        x = rep.x.clone();
        let residuals = lm::residuals(all, &x).ok_or(CalibrationError::Singular)?;
        let mut keep = inliers(residuals.as_slice(), opt.outlier_threshold);
        if round >= FREE_ROUNDS {
            keep.iter_mut().zip(&active).for_each(|(k, a)| *k &= *a);
        }
        if keep == active || round + 1 == MAX_ROUNDS {
            let ne = rep.normal.as_ref().ok_or(CalibrationError::Singular)?;
            let white = lm::covariance(ne).ok_or(CalibrationError::Singular)?;
            // Noise correlated along the trace: the sandwich (module docs, step 5).
            let used: Vec<f64> = residuals.iter().zip(&active).filter(|(_, a)| **a).map(|(r, _)| *r).collect();
            let covariance = match correlated(&model, &x, &used, ne, &white) {
                Some(sandwich) => sandwich,
                None => white,
            };
            return Ok(Rounds { x, covariance, active, residuals, iterations, termination: rep.termination });
        }
        active = keep;
    }
    unreachable!("the last round returns")
}

impl Fit {
    /// A fit of every sample from its rejection rounds, the model's own parameters
    /// already turned into the full model's `x` and the scale; `tracer[i]`: where the
    /// model keeps [`Covariance`]'s parameter `i` (`None`: not fitted).
    fn from_rounds<D: Dim>(
        model: ModelKind,
        x: full::Params,
        scale: f64,
        tracer: [Option<usize>; 5],
        r: Rounds<D>,
    ) -> Fit
    where
        DefaultAllocator: Allocator<D> + Allocator<D, D>,
    {
        let mut covariance = Covariance::zeros();
        for (i, mi) in tracer.iter().enumerate() {
            for (j, mj) in tracer.iter().enumerate() {
                if let (Some(mi), Some(mj)) = (mi, mj) {
                    covariance[(i, j)] = r.covariance[(*mi, *mj)];
                }
            }
        }
        Fit {
            model,
            x,
            scale,
            covariance,
            rejected: r.active.iter().filter(|&&a| !a).count(),
            used: r.active,
            residuals: r.residuals.as_slice().to_vec(),
            iterations: r.iterations,
            termination: r.termination,
            tip_radius: 0.0,
            ring: None,
            angle: AngleError::NONE,
            named: None,
            placements: Vec::new(),
        }
    }
}

/// An input a fit takes as known: how each residual the fit used moves with it, its
/// standard uncertainty, and its own row in the covariance when the calibration reports it
/// (the tip radius, the scale), else `None`.
struct Input<'a> {
    dr: Cow<'a, [f64]>,
    u: f64,
    own: Option<usize>,
}

/// The type B part of the covariance the inputs a fit takes as known bring (GUM 4.3, 5.1),
/// in one pass over the samples the fit used. An input `A` (an artefact's certified size,
/// the tip radius or scale in force) moves the estimate as the normal equations `Jᵀr = 0`
/// hold at the minimum, `s = dx̂/dA = -(JᵀJ)⁻¹ Jᵀ ∂r/∂A` (`∂r/∂A` a value per row of
/// `model`); with `v = (s; 1)` (1 in the input's own row, its estimate being itself) it adds
/// `v vᵀ u²` for a standard uncertainty `u`, summed over the inputs (independent). `rows[i]`:
/// where the model keeps row `i` of the result (`None`: a zero row but an input's own).
/// Zero for inputs whose `u` is.
fn inputs_of<D: Dim>(
    model: &impl Problem<D>,
    x: &OVector<f64, D>,
    inputs: &[Input],
    rows: &[Option<usize>],
) -> Result<DMatrix<f64>, CalibrationError>
where
    DefaultAllocator: Allocator<D> + Allocator<D, D>,
{
    let mut term = DMatrix::zeros(rows.len(), rows.len());
    let inputs: Vec<&Input> = inputs.iter().filter(|i| i.u != 0.0).collect();
    if inputs.is_empty() {
        return Ok(term);
    }
    let (dim, _) = x.shape_generic();
    let mut jtj = OMatrix::<f64, D, D>::zeros_generic(dim, dim);
    let mut jtb = vec![OVector::<f64, D>::zeros_generic(dim, nalgebra::Const::<1>); inputs.len()];
    let mut row = 0;
    let ok = model.for_each_row(x, |_, j| {
        jtj.ger(1.0, j, j, 1.0);
        for (input, jtb) in inputs.iter().zip(jtb.iter_mut()) {
            jtb.axpy(input.dr.get(row).copied().unwrap_or(f64::NAN), j, 1.0);
        }
        row += 1;
    });
    let chol = ok.then_some(jtj).and_then(|m| m.cholesky()).ok_or(CalibrationError::Singular)?;
    for (input, jtb) in inputs.iter().zip(jtb) {
        let s = -chol.solve(&jtb);
        let v = DVector::from_fn(rows.len(), |i, _| match rows[i] {
            Some(m) => s[m],
            None if input.own == Some(i) => 1.0,
            None => 0.0,
        });
        term.ger(input.u * input.u, &v, &v, 1.0);
    }
    if term.iter().all(|v| v.is_finite()) { Ok(term) } else { Err(CalibrationError::Singular) }
}

/// [`inputs_of`] in the tracer's [`Covariance`] layout (`tracer` as in `Fit::from_rounds`).
fn inputs_in_layout<D: Dim>(
    model: &impl Problem<D>,
    x: &OVector<f64, D>,
    inputs: &[Input],
    tracer: [Option<usize>; 5],
) -> Result<Covariance, CalibrationError>
where
    DefaultAllocator: Allocator<D> + Allocator<D, D>,
{
    let term = inputs_of(model, x, inputs, &tracer)?;
    Ok(Covariance::from_fn(|i, j| term[(i, j)]))
}

/// The inputs a fit of `opt.model` takes as known, from each sample's derivatives
/// (`inputs`, of `q`; a residual `q/k - rho` moves by them over `k`): the plate's side and
/// corner radius, the ring's diameter when there is a ring, the tip radius and the scale
/// in force when the model does not fit them (`∂r/∂k₀ = -rho/k₀`: the lengths fitted are
/// `k₀` times those read).
fn known_inputs<'a>(opt: &Options, inputs: &[InputDerivatives], k: f64, ring: bool) -> [Input<'a>; 5] {
    let of = |f: &dyn Fn(&InputDerivatives) -> f64| -> Cow<'a, [f64]> { inputs.iter().map(f).collect() };
    let k0 = opt.scale;
    [
        Input { dr: of(&|d| d.side / k), u: opt.plate_side_uncertainty, own: None },
        Input { dr: of(&|d| d.corner / k), u: opt.corner_radius_uncertainty, own: None },
        Input { dr: of(&|d| d.diameter / k), u: if ring { opt.ring_diameter_uncertainty } else { 0.0 }, own: None },
        Input {
            dr: of(&|d| d.tip / k),
            u: if opt.model.fits_tip() { 0.0 } else { opt.tip_radius_uncertainty },
            own: Some(layout::TIP_RADIUS),
        },
        Input {
            dr: of(&|d| -d.rho / k0),
            u: if opt.model.fits_scale() { 0.0 } else { opt.scale_uncertainty },
            own: Some(layout::SCALE),
        },
    ]
}

fn fit_full(all: &FullModel, x0: full::Params, opt: &Options) -> Result<Fit, CalibrationError> {
    let r = fit_rounds(all, x0, opt)?;
    let tracer = [Some(full::ALPHA0), Some(full::OFFSET), Some(full::DELTA_L), None, None];
    let used = all.retain(|i| r.active[i]);
    let inputs = used.input_derivatives(&r.x, 0.0).ok_or(CalibrationError::Singular)?;
    let types_b = inputs_in_layout(&used, &r.x, &known_inputs(opt, &inputs, 1.0, false), tracer)?;
    let mut fit = Fit::from_rounds(ModelKind::Full, r.x, 1.0, tracer, r);
    fit.covariance += types_b;
    Ok(fit)
}

/// The encoder-scale model from the full model's start at `k = 1` (a start that is
/// good to the size error, which the start's `dL` mostly absorbs).
fn fit_full_scale(all: &FullModel, x0: full::Params, opt: &Options) -> Result<Fit, CalibrationError> {
    let r = fit_rounds(&FullScaleModel::new(all.clone()), full_scale::from_full(&x0, 1.0), opt)?;
    let (x, scale) = full_scale::to_full(&r.x);
    let tracer =
        [Some(full_scale::ALPHA0), Some(full_scale::OFFSET), Some(full_scale::DELTA_L), Some(full_scale::SCALE), None];
    // r = q/k - rho: ∂r/∂S = (∂q/∂S)/k.
    let used = all.retain(|i| r.active[i]);
    let inputs = used.input_derivatives(&x, 0.0).ok_or(CalibrationError::Singular)?;
    let types_b =
        inputs_in_layout(&FullScaleModel::new(used), &r.x, &known_inputs(opt, &inputs, scale, false), tracer)?;
    let mut fit = Fit::from_rounds(ModelKind::FullScale, x, scale, tracer, r);
    fit.covariance += types_b;
    Ok(fit)
}

/// `full_tip` and `full_scale_tip` ([`super::model::tip`]). The start: the full model
/// fitted to the plate with the tip radius in force `ρ₀` gives the mounting with the
/// tip's error in `dL` (`dL' ≈ dL + ρ - ρ₀`); through it the ring's samples lie on a
/// circle about its centre (their centroid) of radius `R ≈ D/2 - ρ - (ρ - ρ₀)`, so
/// `ρ ≈ (D/2 - R + ρ₀)/2`, and `dL = dL' - (ρ - ρ₀)`.
/// The tip models' start (the docs of [`fit_tip`]), and the iterations it took.
fn tip_start(
    scan: &Scan,
    ring_scan: &Scan,
    ring: &RingSpec,
    plate: &PlateSpec,
    opt: &Options,
) -> Result<(tip::Params, usize), CalibrationError> {
    let tip0 = opt.tip_radius;
    let grown = plate.grown(tip0);
    let plate_only = FullModel::from_scan(&grown, scan);
    let start = initial_guess(&plate_only, &grown).ok_or(CalibrationError::NoStart)?;
    let first = fit_rounds(&plate_only, start.x, opt)?;
    let (mounting, _) = full::unpack(&first.x);
    let points = correct(ring_scan, &mounting);
    let centroid = points.iter().sum::<Vector2<f64>>() / points.len() as f64;
    let radius = points.iter().map(|p| (p - centroid).norm()).sum::<f64>() / points.len() as f64;
    let tip = (ring.diameter / 2.0 - radius + tip0) / 2.0;
    let mut x0 = tip::from_full(&first.x, tip, centroid);
    x0[tip::DELTA_L] -= tip - tip0;
    Ok((x0, first.iterations))
}

fn fit_tip(
    scan: &Scan,
    ring_scan: &Scan,
    ring: &RingSpec,
    plate: &PlateSpec,
    opt: &Options,
) -> Result<Fit, CalibrationError> {
    let (x0, first_iterations) = tip_start(scan, ring_scan, ring, plate, opt)?;
    let model = TipModel::from_scans(FullModel::from_scan(plate, scan), ring, ring_scan);
    let n = scan.len();
    // The inputs taken as known, through the samples each fit used (∂r/∂A = (∂q/∂A)/k).
    let inputs = |used: &TipModel, x: &tip::Params| used.input_derivatives(x).ok_or(CalibrationError::Singular);
    let (x, scale, mut fit) = if opt.model.fits_scale() {
        let r = fit_rounds(&TipScaleModel::new(model.clone()), tip::with_scale(&x0, 1.0), opt)?;
        let (x, k) = tip::without_scale(&r.x);
        let at = |i: usize| if i < tip::SCALE { i } else { i + 1 };
        let tracer = [
            Some(at(tip::ALPHA0)),
            Some(at(tip::OFFSET)),
            Some(at(tip::DELTA_L)),
            Some(tip::SCALE),
            Some(at(tip::TIP_RADIUS)),
        ];
        let used = TipScaleModel::new(model.retain(|i| r.active[i]));
        let types_b = inputs_in_layout(&used, &r.x, &known_inputs(opt, &inputs(used.tip(), &x)?, k, true), tracer)?;
        let (x5, _, _) = tip::to_full(&x);
        let mut fit = Fit::from_rounds(ModelKind::FullScaleTip, x5, k, tracer, r);
        fit.covariance += types_b;
        (x, k, fit)
    } else {
        let r = fit_rounds(&model, x0, opt)?;
        let tracer = [Some(tip::ALPHA0), Some(tip::OFFSET), Some(tip::DELTA_L), None, Some(tip::TIP_RADIUS)];
        let used = model.retain(|i| r.active[i]);
        let types_b = inputs_in_layout(&used, &r.x, &known_inputs(opt, &inputs(&used, &r.x)?, 1.0, true), tracer)?;
        let (x, (x5, _, _)) = (r.x, tip::to_full(&r.x));
        let mut fit = Fit::from_rounds(ModelKind::FullTip, x5, 1.0, tracer, r);
        fit.covariance += types_b;
        (x, 1.0, fit)
    };
    let (_, tip_radius, ring_center) = tip::to_full(&x);
    let ring_residuals = fit.residuals.split_off(n);
    let ring_used = fit.used.split_off(n);
    fit.rejected = fit.used.iter().filter(|&&u| !u).count();
    fit.iterations += first_iterations;
    Ok(Fit { scale, tip_radius, ring: Some((ring_center, ring_residuals, ring_used)), ..fit })
}

/// A scale estimate in force's terms as one relative to the scale in force.
fn relative_scale(e: ScaleEstimate, opt: &Options) -> ScaleEstimate {
    ScaleEstimate { scale: e.scale / opt.scale, stddev: e.stddev / opt.scale }
}

/// A tip model's plate showing a scale off ([`CalibrationError::ScaleOff`], `off` the
/// estimate in force's terms) may be a ring whose groove is not the one entered: the
/// ring's contact factor `c = 1/sin(γ/2)` ([`crate::stylus`]) moves the fitted
/// tip, and the plate, grown by it, looks scaled. The scale the plate shows as a function
/// of `c`, `k(c)`, is found at the entered `c₀` (given) and `c₀ + 0.05` (one more fit),
/// and its root `k(c*) = 1` by two secant steps (a fit each); `u(c*) = u(k)/|k'|`.
/// The refusal names the groove when `c* ≥ 1` (a groove can have it), it differs from
/// `c₀` by more than 3 `u`, and at `c*` the scale agrees with the one in force; else
/// `None` (the scale it is). `scale_of(spec)`: the scale the plate shows (relative to the
/// one in force) fitted with the ring taken as `spec` (one placement's tip fit, or the
/// turntable's fit of several).
fn ring_groove_instead(
    ring: &RingSpec,
    opt: &Options,
    off: ScaleEstimate,
    scale_of: impl Fn(&RingSpec) -> Option<ScaleEstimate>,
) -> Option<CalibrationError> {
    let angle_of = |c: f64| (c >= 1.0).then(|| 2.0 * (1.0 / c).asin());
    let scale_at = |c: f64| -> Option<ScaleEstimate> { scale_of(&RingSpec::grooved(ring.diameter, angle_of(c)?)) };
    // The secant twice: k(c) bends a little over a tenth of c.
    let (mut a, mut ka) = (ring.contact_factor(), relative_scale(off, opt).scale);
    let (mut b, mut at) = (a + 0.05, scale_at(a + 0.05)?);
    let mut slope = 0.0;
    for _ in 0..2 {
        slope = (at.scale - ka) / (b - a);
        if !(slope.is_finite() && slope != 0.0) {
            return None;
        }
        let c = b + (1.0 - at.scale) / slope;
        (a, ka) = (b, at.scale);
        (b, at) = (c, scale_at(c)?);
    }
    let (c, c0) = (b, ring.contact_factor());
    let stddev_c = at.stddev / slope.abs();
    let off = (at.scale - 1.0).abs();
    let agrees = off <= opt.scale_tolerance || off <= opt.max_scale_sigma * at.stddev;
    if !(agrees && (c - c0).abs() > 3.0 * stddev_c) {
        return None;
    }
    // γ = 2 asin(1/c): dγ/dc = -2 / (c √(c² - 1)).
    let fits = angle_of(c)?;
    let stddev = stddev_c * 2.0 / (c * (c * c - 1.0).max(1e-12).sqrt());
    Some(CalibrationError::RingGroove { entered: ring.groove_angle, fits, stddev })
}

/// Variance inflation above which an angle harmonic is refused before the fit: its
/// coefficients' standard uncertainty ten times what it would be alone.
pub const MAX_INFLATION: f64 = 100.0;

/// Several placements, the angle harmonics, or both ([`super::model::turntable`]): each
/// placement's start from the full model's, the tip models' start from the first
/// placement and the ring; the harmonics the placements cannot separate refused; the fit
/// with its rejection rounds, its covariance named, the certificates through it; then
/// [`finish`], which checks every plate scan. `known_scale`: the scale the lengths were
/// multiplied by (the scale in force, for the models that do not fit it).
fn fit_turntable(
    plates: &[Scan],
    ring: Option<(&Scan, &RingSpec)>,
    plate: &PlateSpec,
    opt: &Options,
    known_scale: f64,
) -> Result<Calibration, CalibrationError> {
    let tip0 = opt.tip_radius;
    let grown = plate.grown(tip0);
    let mut starts = Vec::with_capacity(plates.len());
    for scan in plates {
        starts.push(initial_guess(&FullModel::from_scan(&grown, scan), &grown).ok_or(CalibrationError::NoStart)?.x);
    }
    let (mut tip_radius, mut ring_center, mut iterations) = (tip0, Vector2::zeros(), 0);
    if let Some((ring_scan, spec)) = ring {
        let (x0, its) = tip_start(&plates[0], ring_scan, spec, plate, opt)?;
        let (x5, tip, g) = tip::to_full(&x0);
        // The other placements' turns are against the first's start as the tip start has it.
        let turn0 = starts[0][full::ALPHA0] - x5[full::ALPHA0];
        starts.iter_mut().skip(1).for_each(|x| x[full::ALPHA0] -= turn0);
        starts[0] = x5;
        (tip_radius, ring_center, iterations) = (tip, g, its);
    }
    let seen = if ring.is_some() { *plate } else { grown };
    let refs: Vec<&Scan> = plates.iter().collect();
    let model =
        TurntableModel::new(&seen, &refs, ring.map(|(s, spec)| (spec, s)), opt.angle_harmonics, opt.model.fits_scale());
    let l = *model.layout();
    let x0 = turntable::start(&l, &starts, 1.0, tip_radius, ring_center);
    separable(&model, &x0, &starts)?;
    let r = fit_rounds(&model, x0, opt)?;
    // The named covariance: the tracer's five, then the coefficients; the certificates
    // through the samples the fit used (∂r/∂A = (∂q/∂A)/k).
    let rows = l.tracer();
    let mut named = DMatrix::from_fn(rows.len(), rows.len(), |i, j| match (rows[i], rows[j]) {
        (Some(a), Some(b)) => r.covariance[(a, b)],
        _ => 0.0,
    });
    let used = model.retain(|i| r.active[i]);
    let inputs = used.input_derivatives(&r.x).ok_or(CalibrationError::Singular)?;
    let k = l.scale().map_or(1.0, |i| r.x[i]);
    named += inputs_of(&used, &r.x, &known_inputs(opt, &inputs, k, ring.is_some()), &rows)?;
    // Residuals scan by scan: the plates' in turn, then the ring's.
    let mut start = 0;
    let mut take = |len: usize| {
        let part = (r.residuals.as_slice()[start..start + len].to_vec(), r.active[start..start + len].to_vec());
        start += len;
        part
    };
    let (first_residuals, first_used) = take(model.plate_len(0));
    let mut placements = Vec::with_capacity(plates.len() - 1);
    for p in 1..plates.len() {
        let (turn, c) = l.placement(p);
        let (residuals, used) = take(model.plate_len(p));
        placements.push(PlacementPart {
            turn: turn.map_or(0.0, |i| r.x[i]),
            center: Vector2::new(r.x[c], r.x[c + 1]),
            residuals,
            used,
        });
    }
    let ring_part = l.ring().map(|g| {
        let (residuals, used) = take(model.ring_len());
        (Vector2::new(r.x[g], r.x[g + 1]), residuals, used)
    });
    let scale = l.scale().map_or(1.0, |i| r.x[i]);
    // A coefficient beyond what a turntable can have (5.7°) is no angle error to correct.
    let coefficients = r.x.rows(l.harmonics(), 2 * l.orders.len()).iter().copied().collect();
    let angle = AngleError::new(l.orders, coefficients).map_err(|e| {
        CalibrationError::Model(format!(
            "the fitted angle error is not one a turntable has ({e}): check the plate scans"
        ))
    })?;
    let fit = Fit {
        model: opt.model,
        x: model.placement_params(&r.x, 0),
        scale: scale * known_scale,
        covariance: Covariance::from_fn(|i, j| named[(i, j)]),
        rejected: first_used.iter().filter(|&&u| !u).count(),
        used: first_used,
        residuals: first_residuals,
        iterations: r.iterations + iterations,
        termination: r.termination,
        tip_radius: l.tip().map_or(tip0, |i| r.x[i]),
        ring: ring_part,
        angle,
        named: Some(named),
        placements,
    };
    // The score test of the scale on every sample the fit used, the scale inserted.
    let score = |tested: &[bool]| {
        let with = used.with_scale(true);
        let x = used.insert_scale(&r.x, 1.0);
        let b: Vec<f64> = with.input_derivatives(&x)?.iter().map(|d| d.side).collect();
        score_test(&with, &x, 3, &b, opt.plate_side_uncertainty, noise_only(tested))
    };
    finish(&plates[0], &plates[1..], fit, ring, opt, score)
}

/// Refuse the harmonics the placements cannot separate ([`super::model::turntable`]): an
/// order that is a multiple of 4 needs a placement turned so that the error turns by at
/// least 45° against the plate (`|sin(hθ/2)| ≥ sin 22.5°`); any order whose variance
/// inflation at the start exceeds [`MAX_INFLATION`] is refused too.
fn separable(model: &TurntableModel, x0: &DVector<f64>, starts: &[full::Params]) -> Result<(), CalibrationError> {
    let l = model.layout();
    if l.orders.is_empty() {
        return Ok(());
    }
    let ne = lm::normal_equations(model, x0).ok_or(CalibrationError::Singular)?;
    let turns: Vec<f64> = starts.iter().map(|x| starts[0][full::ALPHA0] - x[full::ALPHA0]).collect();
    let min_turn = std::f64::consts::FRAC_PI_8.sin();
    for (order, inflation) in l.inflation(&ne.jtj).ok_or(CalibrationError::Singular)? {
        let symmetric = order % 4 == 0 && !turns.iter().any(|t| (f64::from(order) * t / 2.0).sin().abs() >= min_turn);
        if symmetric || inflation > MAX_INFLATION {
            return Err(CalibrationError::HarmonicInseparable { order, inflation, placements: starts.len() });
        }
    }
    Ok(())
}

fn fit_paper(
    scan: &Scan,
    plate: &PlateSpec,
    all: &FullModel,
    x0: full::Params,
    opt: &Options,
) -> Result<Fit, CalibrationError> {
    // Margin from the arcs when selecting flat samples: 1 mm, or 5 % of the flat.
    let margin = (1e-3f64).min(0.05 * (plate.side / 2.0 - plate.corner_radius));
    let mut active = vec![true; scan.len()];
    let mut x = x0;
    let mut iterations = 0;
    for round in 0..MAX_ROUNDS {
        let model =
            PaperModel::select(plate, scan, &x, margin, &active).map_err(|e| CalibrationError::Model(e.to_string()))?;
        let used: Vec<bool> = {
            let mut u = vec![false; scan.len()];
            model.used_samples().for_each(|i| u[i] = true);
            u
        };
        let rep = lm::minimize(&model, paper::Params::new(x[full::ALPHA0], x[full::OFFSET]), &opt.lm);
        iterations += rep.iterations;
        if !rep.termination.converged() {
            return Err(CalibrationError::NotConverged { termination: rep.termination, iterations });
        }
        let ad = rep.x;
        let dl = model.delta_l(&ad);
        let c = model.center(&ad);
        x = full::params(&Mounting::new(ad[0], ad[1], dl), c);
        let residuals = lm::residuals(all, &x).ok_or(CalibrationError::Singular)?;
        let residuals = residuals.as_slice().to_vec();
        // Outliers are judged on the raw samples the model used.
        let used_res: Vec<f64> = residuals.iter().zip(&used).filter(|(_, u)| **u).map(|(r, _)| *r).collect();
        let keep_used = inliers(&used_res, opt.outlier_threshold);
        let mut next = active.clone();
        let mut it = keep_used.into_iter();
        for i in 0..scan.len() {
            if used[i] {
                next[i] = it.next().unwrap_or(true);
            }
        }
        // Samples the model did not use stay eligible for the next selection.
        if round >= FREE_ROUNDS {
            next.iter_mut().zip(&active).for_each(|(k, a)| *k &= *a);
        }
        if next == active || round + 1 == MAX_ROUNDS {
            let n_used = used.iter().filter(|&&u| u).count();
            let ss: f64 = residuals.iter().zip(&used).filter(|(_, u)| **u).map(|(r, _)| r * r).sum();
            let sigma2 = ss / (n_used.saturating_sub(5).max(1)) as f64;
            let ne = rep.normal.ok_or(CalibrationError::Singular)?;
            let ad_dl = model.covariance(&ad, &ne, sigma2, scan.len()).ok_or(CalibrationError::Singular)?;
            let mut covariance = Covariance::zeros();
            covariance.fixed_view_mut::<3, 3>(layout::ALPHA0, layout::ALPHA0).copy_from(&ad_dl);
            // The plate's certificate: the reduced model's own sensitivity to the side,
            // by central differences of its estimator (the same samples, refitted from
            // where it stands with the side moved by ±1 µm; it has no Jacobian in S).
            let u = opt.plate_side_uncertainty;
            if u > 0.0 {
                let h = 1e-6;
                let moved = |dh: f64| -> Result<SVector<f64, 3>, CalibrationError> {
                    let plate = PlateSpec { side: plate.side + dh, ..*plate };
                    let m = PaperModel::select(&plate, scan, &x, margin, &active)
                        .map_err(|e| CalibrationError::Model(e.to_string()))?;
                    let rep = lm::minimize(&m, ad, &opt.lm);
                    Ok(SVector::<f64, 3>::new(rep.x[0], rep.x[1], m.delta_l(&rep.x)))
                };
                let s = (moved(h)? - moved(-h)?) / (2.0 * h);
                let term = s * s.transpose() * (u * u);
                let mut block = covariance.fixed_view_mut::<3, 3>(layout::ALPHA0, layout::ALPHA0);
                block += term;
            }
            return Ok(Fit {
                model: ModelKind::Paper,
                x,
                scale: 1.0,
                covariance,
                rejected: active.iter().filter(|&&a| !a).count(),
                used,
                residuals,
                iterations,
                termination: rep.termination,
                tip_radius: 0.0,
                ring: None,
                angle: AngleError::NONE,
                named: None,
                placements: Vec::new(),
            });
        }
        active = next;
    }
    unreachable!("the last round returns")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn covariance_values_refused_in_the_words_of_the_parameter() {
        let identity = covariance_values(&Covariance::identity());
        assert_eq!(covariance_from_values(&identity), Ok(Covariance::identity()));
        assert_eq!(covariance_from_values(&identity[..24]), Err(InvalidCovariance { values: 24 }));
        let mut negative = identity.clone();
        negative[0] = -1.0;
        let e = covariance_from_values(&negative).unwrap_err();
        assert_eq!(e, InvalidCovariance { values: 25 });
        assert_eq!(
            e.to_string(),
            "expected n×n finite values of a symmetric matrix with no negative variance, n = 5 and 2 more an angle harmonic (25, 49, 81, ...), got 25 values"
        );
        let seven = named_covariance_values(&DMatrix::identity(7, 7));
        assert_eq!(named_covariance_from_values(&seven), Ok(DMatrix::identity(7, 7)));
        assert_eq!(covariance_from_values(&seven), Ok(Covariance::identity()), "the five's block");
        assert!(named_covariance_from_values(&[0.0; 36]).is_err(), "n even: not the five and pairs");
    }
}
