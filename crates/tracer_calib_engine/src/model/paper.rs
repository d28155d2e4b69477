//! The seed paper's reduced model (its eqs. 5-8).
//!
//! On the flat side `x = S/2 + cx` a sample reads `rho = l/cos a + d tan a + dL`
//! (eq. 3, `l = S/2 + cx`). The sample half a turn later (step `k + N/2`, angle
//! `a + π`) touches the opposite side, and their sum no longer depends on the plate's
//! position:
//!
//! ```text
//! s_k = rho_k + rho_{k+N/2} = g(a_k) + 2 dL,
//!   x-sides: g(a) = S/|cos a| + 2 d tan a
//!   y-sides: g(a) = S/|sin a| - 2 d cot a
//! ```
//!
//! The difference of neighbouring sums removes `dL` as well (eqs. 5-6):
//!
//! ```text
//! y_k = s_k - s_{k+1} = g(a_k) - g(a_{k+1}),      a_k = alpha0 + 2π k/N
//! ```
//!
//! which is fitted for `[alpha0, d]` by [`crate::lm`] (eq. 7). Then (eq. 8)
//!
//! ```text
//! dL = mean_k (s_k - g(a_k)) / 2
//! ```
//!
//! and, not in the paper but needed for residuals, the centre from the differences
//! `rho_k - rho_{k+N/2} = 2 cx / cos a_k` (x-sides), `2 cy / sin a_k` (y-sides), by
//! least squares.
//!
//! Only a pair whose four samples all lie on flats of the same axis obeys this; which
//! samples do is decided by the full model at the start estimate
//! ([`PaperModel::select`]). The model is exact on noise-free flat samples. It is
//! ill-conditioned (`corr(alpha0, d) ≈ -0.999` on a 45 mm plate): its error is about
//! five times the Cramér-Rao bound (see `examples/accuracy.rs`), which is why `full`
//! is the default.

use std::collections::HashMap;

use nalgebra::{DMatrix, SMatrix, SVector, Vector2};

use super::PlateSpec;
use super::full;
use crate::geometry::step_angle;
use crate::lm::{NormalEquations, Problem};
use crate::scan::Scan;
use crate::shape::Part;

/// `[alpha0, d]`.
pub type Params = SVector<f64, 2>;

/// Which pair of opposite sides a sum of opposite samples spans.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Axis {
    X,
    Y,
}

/// `g(a)` of the module docs and its derivatives `(∂g/∂a, ∂g/∂d)`.
#[inline]
pub fn sum_model(axis: Axis, a: f64, d: f64, side: f64) -> (f64, f64, f64) {
    let (s, c) = a.sin_cos();
    match axis {
        Axis::X => {
            let sec = 1.0 / c;
            let sgn = c.signum();
            (side * sgn * sec + 2.0 * d * s * sec, (side * sgn * s + 2.0 * d) * sec * sec, 2.0 * s * sec)
        }
        Axis::Y => {
            let csc = 1.0 / s;
            let sgn = s.signum();
            (side * sgn * csc - 2.0 * d * c * csc, (-side * sgn * c + 2.0 * d) * csc * csc, -2.0 * c * csc)
        }
    }
}

/// A usable sum of opposite samples: step `k < N/2` and `k + N/2`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OppositeSum {
    pub phi: f64,
    pub axis: Axis,
    /// `rho_k + rho_{k+N/2}`.
    pub sum: f64,
    /// `rho_k - rho_{k+N/2}`.
    pub diff: f64,
    /// Indices of the two samples in the scan.
    pub samples: [usize; 2],
}

/// The reduced model: differences of neighbouring opposite sums.
#[derive(Debug, Clone)]
pub struct PaperModel {
    side: f64,
    sums: Vec<OppositeSum>,
    /// Index pairs into `sums` of neighbouring steps on the same axis.
    pairs: Vec<[usize; 2]>,
}

/// Why the reduced model cannot be set up.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum SelectError {
    OddStepsPerRevolution(u32),
    TooFewPairs(usize),
}

impl std::fmt::Display for SelectError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::OddStepsPerRevolution(n) => {
                write!(f, "the paper model pairs opposite samples and needs an even steps_per_revolution, got {n}")
            }
            Self::TooFewPairs(n) => {
                write!(f, "only {n} usable neighbouring pairs of opposite samples on the plate's flats")
            }
        }
    }
}

impl PaperModel {
    /// Select the sums and pairs the reduced model may use: both samples of a sum on
    /// opposite flats of one axis, at least `margin` (metres) from the arcs, as the
    /// full model puts them at `x` (a start estimate); `active[i]` false drops sample
    /// `i` (an outlier).
    pub fn select(
        plate: &PlateSpec,
        scan: &Scan,
        x: &full::Params,
        margin: f64,
        active: &[bool],
    ) -> Result<Self, SelectError> {
        let n = scan.steps_per_rev();
        if !n.is_multiple_of(2) {
            return Err(SelectError::OddStepsPerRevolution(n));
        }
        let half_turn = n / 2;
        let flat_limit = plate.side / 2.0 - plate.corner_radius - margin;
        let (m, c) = full::unpack(x);
        // Where each sample lands, by the full model at x.
        let mut axis_of = vec![None; scan.len()];
        for (i, s) in scan.samples().iter().enumerate() {
            if !active[i] {
                continue;
            }
            let a = m.alpha0 + step_angle(s.step, n);
            let (u, v) = crate::geometry::rail_frame(a);
            let Some(hit) = plate.at(c).exit_local(v * m.offset - c, u) else { continue };
            let q = v * m.offset + u * hit.t - c;
            axis_of[i] = match hit.part {
                Part::SideX { .. } if q.y.abs() <= flat_limit => Some(Axis::X),
                Part::SideY { .. } if q.x.abs() <= flat_limit => Some(Axis::Y),
                _ => None,
            };
        }
        let index_of: HashMap<u32, usize> = scan.samples().iter().enumerate().map(|(i, s)| (s.step, i)).collect();
        let mut sums = Vec::new();
        let mut sum_at_step = HashMap::new();
        for k in 0..half_turn {
            let (Some(&i), Some(&j)) = (index_of.get(&k), index_of.get(&(k + half_turn))) else { continue };
            let (Some(ai), Some(aj)) = (axis_of[i], axis_of[j]) else { continue };
            if ai != aj {
                continue;
            }
            let (ri, rj) = (scan.samples()[i].rho, scan.samples()[j].rho);
            sum_at_step.insert(k, sums.len());
            sums.push(OppositeSum { phi: step_angle(k, n), axis: ai, sum: ri + rj, diff: ri - rj, samples: [i, j] });
        }
        let mut pairs = Vec::new();
        for k in 0..half_turn.saturating_sub(1) {
            if let (Some(&p), Some(&q)) = (sum_at_step.get(&k), sum_at_step.get(&(k + 1)))
                && sums[p].axis == sums[q].axis
            {
                pairs.push([p, q]);
            }
        }
        if pairs.len() < 4 {
            return Err(SelectError::TooFewPairs(pairs.len()));
        }
        Ok(PaperModel { side: plate.side, sums, pairs })
    }

    pub fn sums(&self) -> &[OppositeSum] {
        &self.sums
    }

    pub fn pair_count(&self) -> usize {
        self.pairs.len()
    }

    /// Scan indices of every sample the model uses.
    pub fn used_samples(&self) -> impl Iterator<Item = usize> + '_ {
        self.sums.iter().flat_map(|s| s.samples)
    }

    /// Eq. 8: `dL = mean_k (s_k - g(a_k)) / 2`.
    pub fn delta_l(&self, x: &Params) -> f64 {
        let total: f64 = self.sums.iter().map(|s| s.sum - sum_model(s.axis, x[0] + s.phi, x[1], self.side).0).sum();
        total / (2.0 * self.sums.len() as f64)
    }

    /// The plate centre from the opposite differences (least squares), `(cx, cy)`.
    pub fn center(&self, x: &Params) -> Vector2<f64> {
        let (mut nx, mut dx, mut ny, mut dy) = (0.0, 0.0, 0.0, 0.0);
        for s in &self.sums {
            let (sn, cs) = (x[0] + s.phi).sin_cos();
            match s.axis {
                // diff = 2 cx / cos a  ->  cx = Σ(diff/cos a) / (2 Σ 1/cos² a)
                Axis::X => {
                    nx += s.diff / cs;
                    dx += 2.0 / (cs * cs);
                }
                Axis::Y => {
                    ny += s.diff / sn;
                    dy += 2.0 / (sn * sn);
                }
            }
        }
        let ratio = |n: f64, d: f64| if d > 0.0 { n / d } else { 0.0 };
        Vector2::new(ratio(nx, dx), ratio(ny, dy))
    }

    /// Covariance of `[alpha0, d, dL]` by linear error propagation from the raw samples
    /// (`sigma2` per sample): the pair residuals are correlated (neighbouring
    /// differences share a sum), so `σ² (JᵀJ)⁻¹` of the pairs would be wrong.
    /// `θ = G ρ` to first order with `G_{αd} = (JᵀJ)⁻¹ Jᵀ B` (`B` the ±1 map from raw
    /// samples to pair differences) and `G_{dL}` from eq. 8; `cov = σ² G Gᵀ`.
    pub fn covariance(
        &self,
        x: &Params,
        ne: &NormalEquations<nalgebra::U2>,
        sigma2: f64,
        sample_count: usize,
    ) -> Option<SMatrix<f64, 3, 3>> {
        let m = ne.jtj.try_inverse()?;
        let mut g = DMatrix::<f64>::zeros(3, sample_count);
        let mut k = 0;
        self.for_each_row(x, |_, j| {
            let w = m * j;
            let [p, q] = self.pairs[k];
            for (sum, sign) in [(p, 1.0), (q, -1.0)] {
                for &i in &self.sums[sum].samples {
                    g[(0, i)] += sign * w[0];
                    g[(1, i)] += sign * w[1];
                }
            }
            k += 1;
        });
        let nsums = self.sums.len() as f64;
        let mut mean_grad = Params::zeros();
        for s in &self.sums {
            let (_, ga, gd) = sum_model(s.axis, x[0] + s.phi, x[1], self.side);
            mean_grad += Params::new(ga, gd);
            for &i in &s.samples {
                g[(2, i)] += 0.5 / nsums;
            }
        }
        mean_grad /= 2.0 * nsums;
        for i in 0..sample_count {
            g[(2, i)] -= mean_grad[0] * g[(0, i)] + mean_grad[1] * g[(1, i)];
        }
        let cov = &g * g.transpose() * sigma2;
        Some(cov.fixed_view::<3, 3>(0, 0).into_owned())
    }
}

impl Problem<nalgebra::Const<2>> for PaperModel {
    fn residual_count(&self) -> usize {
        self.pairs.len()
    }

    fn for_each_row(&self, x: &Params, mut row: impl FnMut(f64, &Params)) -> bool {
        for &[p, q] in &self.pairs {
            let (sp, sq) = (&self.sums[p], &self.sums[q]);
            let (gp, gap, gdp) = sum_model(sp.axis, x[0] + sp.phi, x[1], self.side);
            let (gq, gaq, gdq) = sum_model(sq.axis, x[0] + sq.phi, x[1], self.side);
            let r = (gp - gq) - (sp.sum - sq.sum);
            if !r.is_finite() {
                return false;
            }
            row(r, &Params::new(gap - gaq, gdp - gdq));
        }
        true
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::Mounting;
    use crate::lm::{differentiate_numerically, jacobian, residuals};
    use approx::assert_relative_eq;

    #[test]
    fn sum_model_derivatives() {
        for axis in [Axis::X, Axis::Y] {
            for a in [0.3, 2.0, -1.2, 4.0] {
                let (_, ga, gd) = sum_model(axis, a, 0.004, 0.045);
                let h = 1e-7;
                let na = (sum_model(axis, a + h, 0.004, 0.045).0 - sum_model(axis, a - h, 0.004, 0.045).0) / (2.0 * h);
                let nd = (sum_model(axis, a, 0.004 + h, 0.045).0 - sum_model(axis, a, 0.004 - h, 0.045).0) / (2.0 * h);
                assert_relative_eq!(ga, na, max_relative = 1e-6);
                assert_relative_eq!(gd, nd, max_relative = 1e-6);
            }
        }
    }

    #[test]
    fn exact_on_noise_free_flats_and_jacobian_checks() {
        let plate = PlateSpec::default();
        let m = Mounting::new(0.0349, 0.005, 0.002);
        let c = Vector2::new(0.0008, -0.0005);
        let steps: Vec<u32> = (0..400).collect();
        let rho: Vec<f64> = steps.iter().map(|&k| full::plate_rho(&plate, &m, c, k, 400).unwrap()).collect();
        let scan = Scan::new(400, &steps, &rho).unwrap();
        let truth_full = full::params(&m, c);
        let model = PaperModel::select(&plate, &scan, &truth_full, 0.001, &[true; 400]).unwrap();
        let truth = Params::new(m.alpha0, m.offset);
        assert!(residuals(&model, &truth).unwrap().amax() < 1e-15);
        assert_relative_eq!(model.delta_l(&truth), m.delta_l, epsilon = 1e-15);
        assert_relative_eq!(model.center(&truth), c, epsilon = 1e-15);
        let x = truth + Params::new(0.01, -0.001);
        let num = differentiate_numerically(&x, &Params::new(1e-2, 1e-3), |x| residuals(&model, x).unwrap());
        assert_relative_eq!(jacobian(&model, &x).unwrap(), num, epsilon = 1e-6);
    }
}
