//! The full model: every raw sample of the plate scan, flats and corner arcs.
//!
//! Parameters `x = [alpha0, d, dL, cx, cy]`. For sample `n` at step angle
//! `φ_n = 2π k_n / N` the rail angle is `a_n = alpha0 + φ_n`; the rail ray
//! `d v + t u` leaves the plate (centred at `c`) at distance `t_n`
//! ([`crate::shape::RoundedRect::exit_local`]), and the encoder should read
//!
//! ```text
//! rho_n(x) = t_n + dL                         r_n = rho_n(x) - rho_n(measured)
//! ```
//!
//! On a flat side with outward normal `e` this is the paper's eq. 3 generalised,
//! `rho = (S/2 + c·e - d (v·e)) / (u·e) + dL`.
//!
//! **Jacobian.** The exit point `X = d v + t u` stays on the contour `F(X - c) = 0`,
//! so `N·(dX - dc) = 0` with `N` the outward normal there. With `∂u/∂a = v`,
//! `∂v/∂a = -u`:
//!
//! ```text
//! ∂rho/∂alpha0 = -N·(t v - d u) / (N·u)
//! ∂rho/∂d      = -N·v / (N·u)
//! ∂rho/∂dL     = 1
//! ∂rho/∂c      =  N / (N·u)
//! ```
//!
//! valid for any smooth convex contour; it needs no case analysis beyond `N`.
//! The rail directions are a table of `(cos φ_n, sin φ_n)` rotated by `alpha0`
//! ([`crate::geometry::rotate`]): one `sin_cos` per evaluation, not per sample.

use nalgebra::{SVector, Vector2};

use super::{InputDerivatives, PlateSpec};
use crate::geometry::{Mounting, rotate, step_angle};
use crate::lm::Problem;
use crate::scan::Scan;
use crate::shape::{Hit, RoundedRect};

/// Parameter vector of the full model.
pub type Params = SVector<f64, 5>;

/// Index of each parameter in [`Params`].
pub const ALPHA0: usize = 0;
pub const OFFSET: usize = 1;
pub const DELTA_L: usize = 2;
pub const CX: usize = 3;
pub const CY: usize = 4;

/// Pack mounting errors and plate centre into a parameter vector.
pub fn params(m: &Mounting, center: Vector2<f64>) -> Params {
    Params::from([m.alpha0, m.offset, m.delta_l, center.x, center.y])
}

/// Unpack a parameter vector.
pub fn unpack(x: &Params) -> (Mounting, Vector2<f64>) {
    (Mounting::new(x[ALPHA0], x[OFFSET], x[DELTA_L]), Vector2::new(x[CX], x[CY]))
}

/// A precomputed sample: the step angle's cosine and sine, and the measured length.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TableSample {
    pub cos_phi: f64,
    pub sin_phi: f64,
    pub rho: f64,
}

impl TableSample {
    pub fn new(step: u32, steps_per_rev: u32, rho: f64) -> Self {
        let (s, c) = step_angle(step, steps_per_rev).sin_cos();
        TableSample { cos_phi: c, sin_phi: s, rho }
    }
}

/// The full model of one plate scan, as a least-squares problem.
#[derive(Debug, Clone)]
pub struct FullModel {
    plate: RoundedRect,
    samples: Vec<TableSample>,
}

impl FullModel {
    pub fn new(plate: &PlateSpec, samples: Vec<TableSample>) -> Self {
        FullModel { plate: plate.at(Vector2::zeros()), samples }
    }

    pub fn from_scan(plate: &PlateSpec, scan: &Scan) -> Self {
        let n = scan.steps_per_rev();
        Self::new(plate, scan.samples().iter().map(|s| TableSample::new(s.step, n, s.rho)).collect())
    }

    pub fn samples(&self) -> &[TableSample] {
        &self.samples
    }

    /// Keep only the samples for which `keep(index)` is true.
    pub fn retain(&self, mut keep: impl FnMut(usize) -> bool) -> Self {
        let samples = self.samples.iter().enumerate().filter(|(i, _)| keep(*i)).map(|(_, s)| *s).collect();
        FullModel { plate: self.plate, samples }
    }

    /// Calls `f(sample, rail u, rail v, hit)` for each sample at `x`; `false` if a
    /// rail ray misses the plate (the parameters are far off).
    #[inline]
    fn for_each_hit(&self, x: &Params, mut f: impl FnMut(&TableSample, Vector2<f64>, Vector2<f64>, Hit)) -> bool {
        let cs_alpha = (x[ALPHA0].cos(), x[ALPHA0].sin());
        let d = x[OFFSET];
        let c = Vector2::new(x[CX], x[CY]);
        for s in &self.samples {
            let (ca, sa) = rotate((s.cos_phi, s.sin_phi), cs_alpha);
            let u = Vector2::new(ca, sa);
            let v = Vector2::new(-sa, ca);
            match self.plate.exit_local(v * d - c, u) {
                Some(hit) if hit.t > 0.0 => f(s, u, v, hit),
                _ => return false,
            }
        }
        true
    }

    /// The cost `½ Σ r²` at `x` (no Jacobian accumulated); `None` where the model cannot
    /// be evaluated.
    pub fn cost(&self, x: &Params) -> Option<f64> {
        let mut ss = 0.0;
        (self.for_each_prediction(x, |s, q, _| ss += (q - s.rho) * (q - s.rho)) && ss.is_finite()).then_some(0.5 * ss)
    }

    /// The encoder lengths the model predicts at `x` (the forward model).
    pub fn predict(&self, x: &Params) -> Option<Vec<f64>> {
        let mut out = Vec::with_capacity(self.samples.len());
        self.for_each_hit(x, |_, _, _, hit| out.push(hit.t + x[DELTA_L])).then_some(out)
    }
}

/// One Jacobian row `∂rho/∂x` at a hit (module docs).
#[inline]
pub fn rho_gradient(hit: &Hit, u: Vector2<f64>, v: Vector2<f64>, d: f64) -> Option<Params> {
    let n = hit.normal;
    let nu = n.dot(&u);
    if nu <= 1e-12 {
        return None; // grazing: the ray runs along the edge
    }
    let inv = 1.0 / nu;
    Some(Params::from([-n.dot(&(v * hit.t - u * d)) * inv, -n.dot(&v) * inv, 1.0, n.x * inv, n.y * inv]))
}

impl FullModel {
    /// Calls `f(sample, q, ∂q/∂x)` for every sample at `x`, where `q = t + dL` is the
    /// length along the rail the encoder should read (with a true scale): the forward
    /// model and its gradient, shared by [`FullModel`] (`r = q - rho`) and the
    /// encoder-scale model ([`super::full_scale`], `r = q/k - rho`). `false` (and an
    /// early stop) if a rail ray misses the plate or grazes it.
    ///
    /// A flat hit, by far the most common, is done inline with one division: leaving
    /// through the side `x = ±S/2` (normal `N = (sx, 0)`, `N·u = |ux|`),
    /// `t = (S/2 - sx p_x)/|ux|` and the gradient of the module docs with `N`
    /// substituted; which wall the ray reaches first is decided by cross-multiplying
    /// the two distances. Corners go through [`RoundedRect::exit_local`] and
    /// [`rho_gradient`].
    #[inline]
    pub fn for_each_prediction(&self, x: &Params, mut f: impl FnMut(&TableSample, f64, &Params)) -> bool {
        self.for_each_grown_prediction(x, 0.0, |s, q, j, _| f(s, q, j))
    }

    /// `∂q/∂S` of every sample at `x` with the plate grown by `g`: how the lengths move
    /// with the plate's side `S` (its certificate's uncertainty enters the covariance
    /// through it, [`crate::calibrate`](mod@crate::calibrate)); `None` where the model cannot be
    /// evaluated.
    pub fn side_sensitivity(&self, x: &Params, g: f64) -> Option<Vec<f64>> {
        let mut out = Vec::with_capacity(self.samples.len());
        self.for_each_grown_prediction(x, g, |_, _, _, d| out.push(d.side)).then_some(out)
    }

    /// Every sample's [`InputDerivatives`] at `x` with the plate grown by `g` (a ring's
    /// diameter: none).
    pub fn input_derivatives(&self, x: &Params, g: f64) -> Option<Vec<InputDerivatives>> {
        let mut out = Vec::with_capacity(self.samples.len());
        self.for_each_grown_prediction(x, g, |s, _, _, d| out.push(d.inputs(s.rho))).then_some(out)
    }

    /// [`Self::for_each_prediction`] of the plate grown by `g` all round (side `S + 2g`,
    /// corners `r + g`: the contour the centre of a tip of radius `g` follows when it
    /// traces the plate from outside, [`super::tip`]); `f` also gets the sample's
    /// [`SizeDerivatives`].
    #[inline]
    pub fn for_each_grown_prediction(
        &self,
        x: &Params,
        g: f64,
        mut f: impl FnMut(&TableSample, f64, &Params, SizeDerivatives),
    ) -> bool {
        let cs_alpha = (x[ALPHA0].cos(), x[ALPHA0].sin());
        let (d, dl) = (x[OFFSET], x[DELTA_L]);
        let c = Vector2::new(x[CX], x[CY]);
        let plate = RoundedRect {
            half_w: self.plate.half_w + g,
            half_h: self.plate.half_h + g,
            radius: self.plate.radius + g,
            ..self.plate
        };
        let (hw, hh) = (plate.half_w, plate.half_h);
        let (inner_w, inner_h) = (hw - plate.radius, hh - plate.radius);
        for s in &self.samples {
            let (ca, sa) = rotate((s.cos_phi, s.sin_phi), cs_alpha);
            let u = Vector2::new(ca, sa);
            let v = Vector2::new(-sa, ca);
            let p = v * d - c;
            let (sx, sy) = (1f64.copysign(ca), 1f64.copysign(sa));
            let (ax, ay) = (ca.abs(), sa.abs());
            // Distances to the x and y walls, along each axis.
            let (wx, wy) = (hw - sx * p.x, hh - sy * p.y);
            if wx * ay <= wy * ax {
                let inv = 1.0 / ax;
                let t = wx * inv;
                if (p.y + t * sa).abs() <= inner_h && t > 0.0 {
                    let j = Params::from([-sx * (t * v.x - d * ca) * inv, -sx * v.x * inv, 1.0, sx * inv, 0.0]);
                    f(s, t + dl, &j, SizeDerivatives { grow: inv, side: 0.5 * inv });
                    continue;
                }
            } else {
                let inv = 1.0 / ay;
                let t = wy * inv;
                if (p.x + t * ca).abs() <= inner_w && t > 0.0 {
                    let j = Params::from([-sy * (t * v.y - d * sa) * inv, -sy * v.y * inv, 1.0, 0.0, sy * inv]);
                    f(s, t + dl, &j, SizeDerivatives { grow: inv, side: 0.5 * inv });
                    continue;
                }
            }
            match plate.exit_local(p, u) {
                Some(hit) if hit.t > 0.0 => match rho_gradient(&hit, u, v, d) {
                    Some(j) => {
                        let inv = 1.0 / hit.normal.dot(&u);
                        let side = 0.5 * (hit.normal.x.abs() + hit.normal.y.abs()) * inv;
                        f(s, hit.t + dl, &j, SizeDerivatives { grow: inv, side })
                    }
                    None => return false,
                },
                _ => return false,
            }
        }
        true
    }
}

/// How a sample's length `q` moves with the plate's size.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SizeDerivatives {
    /// `∂q/∂g = 1/(N·u)`, the plate grown by `g` all round (the contour moves by `dg`
    /// along its normal, `N·dX = dg`).
    pub grow: f64,
    /// `∂q/∂S`, the side alone (corner radius kept): a flat moves by `dS/2`, a corner's
    /// centre by `(±dS/2, ±dS/2)`, so `(|N_x| + |N_y|)/(2 N·u)`.
    pub side: f64,
}

impl SizeDerivatives {
    /// The plate's inputs for a sample that read `rho` ([`InputDerivatives`]).
    pub fn inputs(&self, rho: f64) -> InputDerivatives {
        InputDerivatives { side: self.side, corner: self.grow - 2.0 * self.side, diameter: 0.0, tip: self.grow, rho }
    }
}

impl Problem<nalgebra::Const<5>> for FullModel {
    fn residual_count(&self) -> usize {
        self.samples.len()
    }

    /// `r_n = q_n - rho_n` with `q = t + dL` ([`FullModel::for_each_prediction`]).
    #[inline]
    fn for_each_row(&self, x: &Params, mut row: impl FnMut(f64, &Params)) -> bool {
        self.for_each_prediction(x, |s, q, j| row(q - s.rho, j))
    }
}

/// The encoder length a tracer with mounting `m` reads on the plate centred at
/// `center`, at step `step` of `steps_per_rev` (noise-free): the simulator's and
/// the tests' ground truth.
pub fn plate_rho(plate: &PlateSpec, m: &Mounting, center: Vector2<f64>, step: u32, steps_per_rev: u32) -> Option<f64> {
    let model = FullModel::new(plate, vec![TableSample::new(step, steps_per_rev, 0.0)]);
    model.predict(&params(m, center)).map(|r| r[0])
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::lm::{differentiate_numerically, jacobian, residuals};
    use approx::assert_relative_eq;

    fn model_and_truth() -> (FullModel, Params) {
        let plate = PlateSpec::default();
        let truth = Params::from([0.0349, 0.005, 0.002, 0.0008, -0.0005]);
        let m = FullModel::new(&plate, (0..400).map(|k| TableSample::new(k, 400, 0.0)).collect());
        let rho = m.predict(&truth).unwrap();
        let samples = m.samples.iter().zip(rho).map(|(s, rho)| TableSample { rho, ..*s }).collect();
        (FullModel::new(&plate, samples), truth)
    }

    #[test]
    fn residuals_vanish_at_the_truth() {
        let (m, truth) = model_and_truth();
        let r = residuals(&m, &truth).unwrap();
        assert!(r.amax() < 1e-16, "{}", r.amax());
    }

    #[test]
    fn analytic_jacobian_matches_finite_differences() {
        let (m, truth) = model_and_truth();
        let scale = Params::from([1e-2, 1e-3, 1e-3, 1e-3, 1e-3]);
        for x in [truth, truth + Params::from([0.05, -0.003, 0.001, 0.0004, 0.0011]), Params::zeros()] {
            let analytic = jacobian(&m, &x).unwrap();
            let numeric = differentiate_numerically(&x, &scale, |x| residuals(&m, x).unwrap());
            // Central differences of a piecewise-smooth model: exact to ~1e-8 away from
            // the tangent points between flats and arcs; a few samples may straddle one.
            let mut bad = 0;
            for i in 0..analytic.nrows() {
                let diff = (analytic.row(i) - numeric.row(i)).amax();
                if diff > 1e-6 {
                    bad += 1;
                }
            }
            assert!(bad <= 2, "{bad} rows differ at {x:?}");
            assert_relative_eq!(analytic.column(DELTA_L).amax(), 1.0);
        }
    }

    #[test]
    fn flat_sample_matches_paper_eq3() {
        let plate = PlateSpec::default();
        let m = Mounting::new(0.03, 0.005, 0.002);
        let c = Vector2::new(0.0008, -0.0005);
        let a = 0.03 + step_angle(10, 400);
        let rho = plate_rho(&plate, &m, c, 10, 400).unwrap();
        let l = 0.0225 + c.x;
        assert_relative_eq!(rho, l / a.cos() + 0.005 * a.tan() + 0.002, epsilon = 1e-15);
    }
}
