//! The full model with the encoder scale: every raw sample, six parameters
//! `x = [alpha0, d, dL, k, cx, cy]`.
//!
//! An encoder whose scale is off (a wrong `meters_per_count`, a rail grown with heat)
//! reads `rho` where the true length along the rail is `k rho`
//! ([`crate::geometry`]: `P = (k rho - dL) u + d v`). With `q_n = t_n + dL` the
//! length the rail ray needs to leave the plate ([`FullModel::for_each_prediction`]),
//! the encoder should read
//!
//! ```text
//! rho_n(x) = q_n / k                          r_n = q_n / k - rho_n(measured)
//! ```
//!
//! (the residual is in encoder units, where the noise is). **Jacobian**, from the full
//! model's `∂q/∂(alpha0, d, dL, c)` (module docs of [`super::full`]):
//!
//! ```text
//! ∂r/∂(alpha0, d, dL, c) = ∂q/∂(alpha0, d, dL, c) / k
//! ∂r/∂k                  = -q / k²
//! ```
//!
//! **Identifiability.** A change of `k` stretches every length along the rail by the
//! same factor; `dL` shifts them all by the same amount. On a plate the two differ only
//! because the plate's radius varies with the angle (from `S/2` on the flats to near
//! `S/√2` towards the corners): the scale is found from that variation, with about
//! three times the uncertainty of `dL` alone, and only because the plate's size is
//! known (side, corner radius and scale together are exactly degenerate). The
//! Cramér-Rao bound at σ = 10 µm on one 400-sample scan of the 45 mm plate is about
//! 2·10⁻⁴ (5 µm on a 25 mm radius).

use nalgebra::SVector;

use super::full::{self, FullModel};
use crate::lm::Problem;

/// Parameter vector of the encoder-scale model.
pub type Params = SVector<f64, 6>;

/// Index of each parameter in [`Params`].
pub const ALPHA0: usize = 0;
pub const OFFSET: usize = 1;
pub const DELTA_L: usize = 2;
pub const SCALE: usize = 3;
pub const CX: usize = 4;
pub const CY: usize = 5;

/// The full model's parameters with encoder scale `k`.
pub fn from_full(x: &full::Params, k: f64) -> Params {
    Params::from([x[full::ALPHA0], x[full::OFFSET], x[full::DELTA_L], k, x[full::CX], x[full::CY]])
}

/// Split into the full model's parameters and the encoder scale.
pub fn to_full(x: &Params) -> (full::Params, f64) {
    (full::Params::from([x[ALPHA0], x[OFFSET], x[DELTA_L], x[CX], x[CY]]), x[SCALE])
}

/// The encoder-scale model of one plate scan: the full model's geometry, and `k`.
#[derive(Debug, Clone)]
pub struct FullScaleModel {
    full: FullModel,
}

impl FullScaleModel {
    pub fn new(full: FullModel) -> Self {
        FullScaleModel { full }
    }

    /// The full model of the same samples.
    pub fn full(&self) -> &FullModel {
        &self.full
    }
}

impl Problem<nalgebra::Const<6>> for FullScaleModel {
    fn residual_count(&self) -> usize {
        self.full.samples().len()
    }

    /// `r_n = q_n/k - rho_n` (module docs).
    #[inline]
    fn for_each_row(&self, x: &Params, mut row: impl FnMut(f64, &Params)) -> bool {
        let (x5, k) = to_full(x);
        if k.is_nan() || k <= 0.0 {
            return false;
        }
        let inv_k = 1.0 / k;
        self.full.for_each_prediction(&x5, |s, q, j| {
            let j6 = Params::from([
                j[full::ALPHA0] * inv_k,
                j[full::OFFSET] * inv_k,
                j[full::DELTA_L] * inv_k,
                -q * inv_k * inv_k,
                j[full::CX] * inv_k,
                j[full::CY] * inv_k,
            ]);
            row(q * inv_k - s.rho, &j6);
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::PlateSpec;
    use crate::lm::{differentiate_numerically, jacobian, residuals};
    use crate::model::full::TableSample;

    /// A noise-free scan of a tracer whose encoder reads 0.25 % long.
    fn model_and_truth() -> (FullModel, Params) {
        let plate = PlateSpec::default();
        let truth = Params::from([0.0349, 0.005, 0.002, 1.0 / 1.0025, 0.0008, -0.0005]);
        let m = FullModel::new(&plate, (0..400).map(|k| TableSample::new(k, 400, 0.0)).collect());
        let (x5, k) = to_full(&truth);
        let q = m.predict(&x5).unwrap();
        let samples = m.samples().iter().zip(q).map(|(s, q)| TableSample { rho: q / k, ..*s }).collect();
        (FullModel::new(&plate, samples), truth)
    }

    #[test]
    fn residuals_vanish_at_the_truth() {
        let (m, truth) = model_and_truth();
        let r = residuals(&FullScaleModel::new(m), &truth).unwrap();
        assert!(r.amax() < 1e-16, "{}", r.amax());
    }

    #[test]
    fn analytic_jacobian_matches_finite_differences() {
        let (m, truth) = model_and_truth();
        let model = FullScaleModel::new(m);
        let scale = Params::from([1e-2, 1e-3, 1e-3, 1.0, 1e-3, 1e-3]);
        for x in [
            truth,
            truth + Params::from([0.05, -0.003, 0.001, 0.01, 0.0004, 0.0011]),
            from_full(&full::Params::zeros(), 1.0),
        ] {
            let analytic = jacobian(&model, &x).unwrap();
            let numeric = differentiate_numerically(&x, &scale, |x| residuals(&model, x).unwrap());
            // As for the full model: a few samples may straddle a flat-arc tangent point.
            let bad = (0..analytic.nrows()).filter(|&i| (analytic.row(i) - numeric.row(i)).amax() > 1e-6).count();
            assert!(bad <= 2, "{bad} rows differ at {x:?}");
        }
    }

    #[test]
    fn a_scale_that_is_not_positive_cannot_be_evaluated() {
        let (m, truth) = model_and_truth();
        let mut x = truth;
        x[SCALE] = 0.0;
        assert!(residuals(&FullScaleModel::new(m), &x).is_none());
    }
}
