//! The stylus tip: a plate scan and a ring-gauge scan fitted together, the tip's radius
//! `ρ` with the mounting errors (`full_tip`, and `full_scale_tip` with the encoder scale).
//!
//! A contact tracer touches with a ball of radius `ρ`, and the encoder reads where the
//! ball's centre is. The centre follows the traced contour offset by `ρ` along its
//! normal: outward for what is traced from outside (the plate: a square of side
//! `S + 2ρ` with corners `r + ρ`), inward for what is traced from inside (a ring gauge
//! of diameter `D`: a circle of radius `D/2 - ρ`; of a ring with a V-groove of included
//! angle `γ`, `D` its groove bottom's diameter, `D/2 - ρ/sin(γ/2)`,
//! [`crate::stylus`]). From the plate alone `ρ` is nearly
//! the encoder zero `dL` (correlation -0.95: both lengthen every sample); the ring moves
//! the other way, so the two scans together pin both.
//!
//! Parameters `x = [alpha0, d, dL, ρ, cx, cy, gx, gy]` (`c` the plate's centre, `g` the
//! ring's), and `k` after `ρ` for `full_scale_tip`. Plate samples are those of
//! [`super::full`] with the plate grown by `ρ`
//! ([`FullModel::for_each_grown_prediction`]); a ring sample at rail angle `a` leaves the
//! circle `|X - g| = R`, `R = D/2 - cρ`, `c = 1/sin(γ/2)`, from inside, at
//!
//! ```text
//! p = d v - g      t = -p·u + sqrt((p·u)² - |p|² + R²)      q = t + dL
//! ```
//!
//! with the residual `r = q - rho` (`q/k - rho` with the scale, [`super::full_scale`]).
//!
//! **Jacobian.** As in [`super::full`], `N·(dX - dg) = dR` at the exit point `X` with
//! outward normal `N = (X - g)/R`, so the full model's row holds with `g` for `c`, and
//! `∂t/∂R = 1/(N·u)`, hence `∂q/∂ρ = -c/(N·u)` on the ring; on the grown plate
//! `∂q/∂ρ = +1/(N·u)`.

use nalgebra::{SVector, Vector2};

use super::InputDerivatives;
use super::full::{self, FullModel, TableSample};
use crate::geometry::rotate;
use crate::lm::Problem;
use crate::scan::Scan;
use crate::stylus::{PLAIN_BORE, groove_factor, valid_groove_angle};

/// Parameter vector of `full_tip`.
pub type Params = SVector<f64, 8>;
/// Parameter vector of `full_scale_tip`.
pub type ScaleParams = SVector<f64, 9>;

/// Index of each parameter in [`Params`].
pub const ALPHA0: usize = 0;
pub const OFFSET: usize = 1;
pub const DELTA_L: usize = 2;
pub const TIP_RADIUS: usize = 3;
pub const CX: usize = 4;
pub const CY: usize = 5;
pub const GX: usize = 6;
pub const GY: usize = 7;
/// Where [`ScaleParams`] keeps the encoder scale; the parameters after `ρ` move up one.
pub const SCALE: usize = 4;

/// The ring gauge's certified size.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct RingSpec {
    /// Inner diameter, metres: of the groove's bottom for a grooved ring.
    pub diameter: f64,
    /// Included angle of the ring's V-groove, rad; π (the default) a plain bore.
    #[serde(default = "plain_bore")]
    pub groove_angle: f64,
}

fn plain_bore() -> f64 {
    PLAIN_BORE
}

impl RingSpec {
    /// A plain bore of `diameter` (m).
    pub const fn plain(diameter: f64) -> Self {
        RingSpec { diameter, groove_angle: PLAIN_BORE }
    }

    /// A ring whose groove's bottom has `diameter` (m), included angle `groove_angle` (rad).
    pub const fn grooved(diameter: f64, groove_angle: f64) -> Self {
        RingSpec { diameter, groove_angle }
    }

    /// A ring a tracer can trace: a positive, finite diameter, a groove angle in `(0, π]`.
    pub fn validate(&self) -> Result<(), RingError> {
        if !(self.diameter.is_finite() && self.diameter > 0.0) {
            return Err(RingError::Diameter(self.diameter));
        }
        if !valid_groove_angle(self.groove_angle) {
            return Err(RingError::GrooveAngle(self.groove_angle));
        }
        Ok(())
    }

    /// `c = 1/sin(γ/2)`: how far the ball's centre sits from the ring's wall (its groove's
    /// bottom) per unit of tip radius.
    pub fn contact_factor(&self) -> f64 {
        groove_factor(self.groove_angle)
    }
}

/// A ring gauge that is not one ([`RingSpec::validate`]): which dimension is wrong.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
pub enum RingError {
    /// The diameter given, metres.
    #[error("the ring gauge's diameter must be a positive length in metres, got {0}")]
    Diameter(f64),
    /// The groove angle given, rad.
    #[error("the ring gauge's groove angle must be an included angle in (0, π] rad (π = a plain bore), got {0}")]
    GrooveAngle(f64),
}

/// `full_tip`'s parameters from the full model's and the tip radius and ring centre.
pub fn from_full(x: &full::Params, tip_radius: f64, ring_center: Vector2<f64>) -> Params {
    Params::from([
        x[full::ALPHA0],
        x[full::OFFSET],
        x[full::DELTA_L],
        tip_radius,
        x[full::CX],
        x[full::CY],
        ring_center.x,
        ring_center.y,
    ])
}

/// Split into the full model's parameters, the tip radius and the ring's centre.
pub fn to_full(x: &Params) -> (full::Params, f64, Vector2<f64>) {
    (full::Params::from([x[ALPHA0], x[OFFSET], x[DELTA_L], x[CX], x[CY]]), x[TIP_RADIUS], Vector2::new(x[GX], x[GY]))
}

/// `full_scale_tip`'s parameters: `full_tip`'s with the scale `k` after `ρ`.
pub fn with_scale(x: &Params, k: f64) -> ScaleParams {
    let mut out = ScaleParams::zeros();
    out.fixed_rows_mut::<SCALE>(0).copy_from(&x.fixed_rows::<SCALE>(0));
    out[SCALE] = k;
    out.fixed_rows_mut::<4>(SCALE + 1).copy_from(&x.fixed_rows::<4>(SCALE));
    out
}

/// Split `full_scale_tip`'s parameters into `full_tip`'s and the scale.
pub fn without_scale(x: &ScaleParams) -> (Params, f64) {
    let mut out = Params::zeros();
    out.fixed_rows_mut::<SCALE>(0).copy_from(&x.fixed_rows::<SCALE>(0));
    out.fixed_rows_mut::<4>(SCALE).copy_from(&x.fixed_rows::<4>(SCALE + 1));
    (out, x[SCALE])
}

/// A plate scan and a ring-gauge scan, as one least-squares problem (module docs):
/// the plate's samples first, then the ring's.
#[derive(Debug, Clone)]
pub struct TipModel {
    plate: FullModel,
    ring: Vec<TableSample>,
    ring_radius: f64,
    /// `c` of the module docs.
    ring_contact: f64,
}

impl TipModel {
    pub fn new(plate: FullModel, ring: &RingSpec, ring_samples: Vec<TableSample>) -> Self {
        TipModel { plate, ring: ring_samples, ring_radius: ring.diameter / 2.0, ring_contact: ring.contact_factor() }
    }

    /// The model of a plate's model and a ring-gauge scan.
    pub fn from_scans(plate: FullModel, ring: &RingSpec, ring_scan: &Scan) -> Self {
        let n = ring_scan.steps_per_rev();
        Self::new(plate, ring, ring_scan.samples().iter().map(|s| TableSample::new(s.step, n, s.rho)).collect())
    }

    pub fn plate(&self) -> &FullModel {
        &self.plate
    }

    pub fn ring_samples(&self) -> &[TableSample] {
        &self.ring
    }

    /// Keep only the samples (plate's, then ring's) for which `keep(index)` is true.
    pub fn retain(&self, mut keep: impl FnMut(usize) -> bool) -> Self {
        let n = self.plate.samples().len();
        let plate = self.plate.retain(&mut keep);
        let ring = self.ring.iter().enumerate().filter(|(i, _)| keep(n + i)).map(|(_, s)| *s).collect();
        TipModel { plate, ring, ring_radius: self.ring_radius, ring_contact: self.ring_contact }
    }

    /// Calls `f(sample, q, ∂q/∂x)` for every sample, plate's then ring's (module docs);
    /// `false` (and an early stop) where a rail ray misses or grazes a contour, or the
    /// tip is not smaller than the ring.
    #[inline]
    pub fn for_each_prediction(&self, x: &Params, mut f: impl FnMut(&TableSample, f64, &Params)) -> bool {
        self.for_each_prediction_and_size(x, |s, q, j, _| f(s, q, j))
    }

    /// How every sample's length moves with the inputs taken as known at `x`
    /// ([`InputDerivatives`]), plate's samples then ring's (a plate sample does not move
    /// with `D`, a ring sample not with `S` or `r`; on the ring `∂q/∂D = 1/(2 N·u)`; the
    /// tip is fitted, its derivative left 0).
    pub fn input_derivatives(&self, x: &Params) -> Option<Vec<InputDerivatives>> {
        let mut out = Vec::with_capacity(self.residual_count());
        self.for_each_prediction_and_size(x, |_, _, _, d| out.push(d)).then_some(out)
    }

    /// [`Self::for_each_prediction`], `f` also getting the sample's [`InputDerivatives`].
    #[inline]
    fn for_each_prediction_and_size(
        &self,
        x: &Params,
        mut f: impl FnMut(&TableSample, f64, &Params, InputDerivatives),
    ) -> bool {
        let (x5, tip, g) = to_full(x);
        let plate = self.plate.for_each_grown_prediction(&x5, tip, |s, q, j, size| {
            let row = Params::from([
                j[full::ALPHA0],
                j[full::OFFSET],
                j[full::DELTA_L],
                size.grow,
                j[full::CX],
                j[full::CY],
                0.0,
                0.0,
            ]);
            f(s, q, &row, InputDerivatives { tip: 0.0, ..size.inputs(s.rho) })
        });
        if !plate {
            return false;
        }
        let c = self.ring_contact;
        let radius = self.ring_radius - c * tip;
        if radius.is_nan() || radius <= 0.0 {
            return false;
        }
        let cs_alpha = (x[ALPHA0].cos(), x[ALPHA0].sin());
        let d = x[OFFSET];
        for s in &self.ring {
            let (ca, sa) = rotate((s.cos_phi, s.sin_phi), cs_alpha);
            let u = Vector2::new(ca, sa);
            let v = Vector2::new(-sa, ca);
            let Some((t, n)) = ring_exit(v * d - g, u, radius) else { return false };
            let nu = n.dot(&u);
            if nu <= 1e-12 {
                return false;
            }
            let inv = 1.0 / nu;
            let row = Params::from([
                -n.dot(&(v * t - u * d)) * inv,
                -n.dot(&v) * inv,
                1.0,
                -c * inv,
                0.0,
                0.0,
                n.x * inv,
                n.y * inv,
            ]);
            f(
                s,
                t + x[DELTA_L],
                &row,
                InputDerivatives { diameter: 0.5 * inv, rho: s.rho, ..InputDerivatives::default() },
            );
        }
        true
    }
}

/// Where the ray `p + t u` (`p` relative to the circle's centre, `u` a unit vector)
/// leaves the circle of radius `radius`: the far root `t` and the outward normal there.
#[inline]
pub fn ring_exit(p: Vector2<f64>, u: Vector2<f64>, radius: f64) -> Option<(f64, Vector2<f64>)> {
    let b = p.dot(&u);
    let disc = b * b - p.norm_squared() + radius * radius;
    if disc < 0.0 {
        return None;
    }
    let t = -b + disc.sqrt();
    (t > 0.0).then(|| (t, (p + u * t) / radius))
}

impl Problem<nalgebra::Const<8>> for TipModel {
    fn residual_count(&self) -> usize {
        self.plate.samples().len() + self.ring.len()
    }

    /// `r_n = q_n - rho_n`.
    #[inline]
    fn for_each_row(&self, x: &Params, mut row: impl FnMut(f64, &Params)) -> bool {
        self.for_each_prediction(x, |s, q, j| row(q - s.rho, j))
    }
}

/// `full_scale_tip`: [`TipModel`] with the encoder scale, `r = q/k - rho`.
#[derive(Debug, Clone)]
pub struct TipScaleModel {
    tip: TipModel,
}

impl TipScaleModel {
    pub fn new(tip: TipModel) -> Self {
        TipScaleModel { tip }
    }

    pub fn tip(&self) -> &TipModel {
        &self.tip
    }
}

impl Problem<nalgebra::Const<9>> for TipScaleModel {
    fn residual_count(&self) -> usize {
        self.tip.residual_count()
    }

    /// `r_n = q_n/k - rho_n`; `∂r/∂k = -q/k²`, the rest `∂q/∂x / k`.
    #[inline]
    fn for_each_row(&self, x: &ScaleParams, mut row: impl FnMut(f64, &ScaleParams)) -> bool {
        let (x8, k) = without_scale(x);
        if k.is_nan() || k <= 0.0 {
            return false;
        }
        let inv_k = 1.0 / k;
        self.tip.for_each_prediction(&x8, |s, q, j| {
            let mut j9 = with_scale(&(j * inv_k), 0.0);
            j9[SCALE] = -q * inv_k * inv_k;
            row(q * inv_k - s.rho, &j9);
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::PlateSpec;
    use crate::lm::{differentiate_numerically, jacobian, residuals};

    const RING: RingSpec = RingSpec::plain(0.040);

    #[test]
    fn a_ring_without_a_diameter_is_refused() {
        assert_eq!(RING.validate(), Ok(()));
        let e = RingSpec::plain(-1.0).validate().unwrap_err();
        assert_eq!(e, RingError::Diameter(-1.0));
        assert_eq!(e.to_string(), "the ring gauge's diameter must be a positive length in metres, got -1");
        assert!(matches!(RingSpec::plain(f64::NAN).validate(), Err(RingError::Diameter(d)) if d.is_nan()));
        let e = RingSpec::grooved(0.04, 4.0).validate().unwrap_err();
        assert_eq!(
            e.to_string(),
            "the ring gauge's groove angle must be an included angle in (0, π] rad (π = a plain bore), got 4"
        );
        assert_eq!(RingSpec::grooved(0.04, 2.0).validate(), Ok(()));
    }

    /// A noise-free plate and ring scan of a tracer with a 0.5 mm tip.
    fn model_and_truth() -> (TipModel, Params) {
        model_and_truth_in(&RING)
    }

    /// [`model_and_truth`] with the ring `ring`.
    fn model_and_truth_in(ring: &RingSpec) -> (TipModel, Params) {
        let plate = PlateSpec::default();
        let truth = Params::from([0.0349, 0.005, 0.002, 0.0005, 0.0008, -0.0005, -0.0006, 0.0004]);
        let blank = || (0..400).map(|k| TableSample::new(k, 400, 0.0)).collect::<Vec<_>>();
        let m = TipModel::new(FullModel::new(&plate, blank()), ring, blank());
        let mut rho = Vec::new();
        assert!(m.for_each_prediction(&truth, |_, q, _| rho.push(q)));
        let (p, r) = rho.split_at(400);
        let with = |s: &[TableSample], rho: &[f64]| -> Vec<TableSample> {
            s.iter().zip(rho).map(|(s, &rho)| TableSample { rho, ..*s }).collect()
        };
        let m = TipModel::new(FullModel::new(&plate, with(m.plate.samples(), p)), ring, with(&m.ring, r));
        (m, truth)
    }

    #[test]
    fn residuals_vanish_at_the_truth() {
        let (m, truth) = model_and_truth();
        assert!(residuals(&m, &truth).unwrap().amax() < 1e-16);
    }

    #[test]
    fn ring_sample_is_the_circle_shrunk_by_the_tip() {
        // Rail through the axis (d = 0), ring centred on it: every sample reads D/2 - ρ + dL.
        let m =
            TipModel::new(FullModel::new(&PlateSpec::default(), vec![]), &RING, vec![TableSample::new(7, 400, 0.0)]);
        let x = Params::from([0.1, 0.0, 0.002, 0.0003, 0.0, 0.0, 0.0, 0.0]);
        let mut q = vec![];
        m.for_each_prediction(&x, |_, qi, _| q.push(qi));
        approx::assert_relative_eq!(q[0], 0.020 - 0.0003 + 0.002, epsilon = 1e-15);
        // In a 120° groove the ball's centre sits ρ/sin 60° from the groove's bottom.
        let ring = RingSpec::grooved(0.040, 120f64.to_radians());
        let m =
            TipModel::new(FullModel::new(&PlateSpec::default(), vec![]), &ring, vec![TableSample::new(7, 400, 0.0)]);
        m.for_each_prediction(&x, |_, qi, _| q[0] = qi);
        approx::assert_relative_eq!(q[0], 0.020 - 0.0003 / 60f64.to_radians().sin() + 0.002, epsilon = 1e-15);
    }

    #[test]
    fn analytic_jacobians_match_finite_differences() {
        let (grooved, truth) = model_and_truth_in(&RingSpec::grooved(0.040, 1.9));
        assert!(residuals(&grooved, &truth).unwrap().amax() < 1e-16);
        for m in [model_and_truth().0, grooved] {
            jacobians_match(m, truth);
        }
    }

    fn jacobians_match(m: TipModel, truth: Params) {
        let step = Params::from([1e-2, 1e-3, 1e-3, 1e-4, 1e-3, 1e-3, 1e-3, 1e-3]);
        let off = truth + Params::from([0.03, -0.002, 0.001, 0.0002, 0.0004, 0.0011, -0.0003, 0.0002]);
        for x in [truth, off] {
            let analytic = jacobian(&m, &x).unwrap();
            let numeric = differentiate_numerically(&x, &step, |x| residuals(&m, x).unwrap());
            let bad = (0..analytic.nrows()).filter(|&i| (analytic.row(i) - numeric.row(i)).amax() > 1e-6).count();
            assert!(bad <= 2, "{bad} rows differ at {x:?}");
        }
        let scaled = TipScaleModel::new(m);
        let x = with_scale(&off, 1.002);
        let step9 = with_scale(&step, 1e-4);
        let analytic = jacobian(&scaled, &x).unwrap();
        let numeric = differentiate_numerically(&x, &step9, |x| residuals(&scaled, x).unwrap());
        let bad = (0..analytic.nrows()).filter(|&i| (analytic.row(i) - numeric.row(i)).amax() > 1e-6).count();
        assert!(bad <= 2, "{bad} rows of full_scale_tip differ");
    }

    #[test]
    fn scale_parameters_round_trip() {
        let x = Params::from([1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0]);
        let s = with_scale(&x, 9.0);
        assert_eq!(s.as_slice(), &[1.0, 2.0, 3.0, 4.0, 9.0, 5.0, 6.0, 7.0, 8.0]);
        assert_eq!(without_scale(&s), (x, 9.0));
    }
}
