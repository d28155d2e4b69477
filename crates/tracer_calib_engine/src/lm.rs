//! Levenberg-Marquardt for small parameter vectors and many residuals.
//!
//! Minimises `F(x) = ½ Σ r_i(x)²`. One seam, [`Problem`]: a model streams its residuals
//! `r_i` with their Jacobian rows `J_i = ∂r_i/∂x`; everything else is here.
//!
//! # The iteration
//!
//! Per iteration the normal equations `JᵀJ`, `g = Jᵀr` are accumulated in **one pass**
//! over the residuals (`P×P`, never the `n×P` Jacobian), and the damped step solves
//!
//! ```text
//! (JᵀJ + μ D²) h = -g                      (Cholesky, P×P)
//! ```
//!
//! with Marquardt's scaling `D² = diag(JᵀJ)`, kept at its running maximum (Moré 1978),
//! which makes the step invariant to the units of the parameters (radians next to
//! metres here).
//!
//! **Step control** is the gain ratio of a trust-region method (Madsen, Nielsen &
//! Tingleff, *Methods for non-linear least squares problems*, 2004, alg. 3.16):
//!
//! ```text
//! ϱ = (F(x) - F(x+h)) / (L(0) - L(h)),    L(0) - L(h) = ½ hᵀ(μ D² h - g)
//! ```
//!
//! A step is taken only if it lowers `F` (`ϱ > 0`), so the cost never rises; on success
//! `μ ← μ·max(1/3, 1-(2ϱ-1)³)`, on failure `μ ← μ·ν, ν ← 2ν` (Nielsen's update, smooth,
//! without the ×10/÷10 oscillation). The seed paper adds an Armijo/Wolfe line search on
//! top of LM; with the gain ratio that is redundant: `μ` already sets the step length
//! and direction together (large `μ` → short gradient step, small → Gauss-Newton), a
//! rejected step costs one evaluation like a backtracking step does, and the sufficient
//! decrease the Armijo test asks for is the `ϱ > 0` test with a model-based reference.
//! Each trial point is evaluated with its normal equations in one pass, so an accepted
//! step (nearly all of them, near the solution) costs exactly one pass.
//!
//! # Termination
//!
//! - [`Termination::Uncertainty`]: the Gauss-Newton step to the minimum of the local
//!   quadratic model is smaller than `stol` standard uncertainties of the result,
//!   `gᵀ(JᵀJ)⁻¹g <= stol² σ̂²` (`σ̂² = ‖r‖²/(n-P)`): iterating further would move the
//!   answer by less than a small fraction of its own error bar (with noisy data, the
//!   test that stops first);
//! - [`Termination::Gradient`]: every column of `J` is nearly orthogonal to `r`,
//!   `max_j |g_j| / (‖J_j‖ ‖r‖) <= gtol` (MINPACK's scale-free test), or `r = 0`;
//! - [`Termination::Step`]: `‖D h‖ <= xtol (‖D x‖ + xtol)`;
//! - [`Termination::Cost`]: actual and predicted relative reduction both `<= ftol`;
//! - [`Termination::NoFurtherDecrease`]: `μ` grew past any useful size: no step lowers
//!   the cost in floating point (a minimum at machine precision);
//! - [`Termination::MaxIterations`], [`Termination::NonFinite`] (the start could not be
//!   evaluated): failures.
//!
//! The covariance of the result is `σ̂² (JᵀJ)⁻¹` with `σ̂² = ‖r‖²/(n-P)`
//! ([`covariance`]); with the true `σ` in place of `σ̂` at the true parameters, the same
//! matrix is the Cramér-Rao bound for Gaussian noise.

use nalgebra::allocator::Allocator;
use nalgebra::{Const, DMatrix, DVector, DefaultAllocator, Dim, OMatrix, OVector};

/// A least-squares problem: residuals and their Jacobian rows, streamed. `D` is the
/// number of parameters: `Const<P>` for a model of fixed size (the plate models), `Dyn`
/// for one whose size is chosen at run time (angle harmonics, several placements); the
/// solver is the same.
pub trait Problem<D: Dim>
where
    DefaultAllocator: Allocator<D>,
{
    /// How many residuals the problem has.
    fn residual_count(&self) -> usize;

    /// Calls `row(r_i, J_i)` for every residual at `x`, in a fixed order. Returns
    /// `false` (and may stop early) if the model cannot be evaluated at `x`.
    fn for_each_row(&self, x: &OVector<f64, D>, row: impl FnMut(f64, &OVector<f64, D>)) -> bool;
}

/// `JᵀJ`, `Jᵀr` and the cost `½‖r‖²` at one point.
#[derive(Debug, Clone, PartialEq)]
pub struct NormalEquations<D: Dim>
where
    DefaultAllocator: Allocator<D> + Allocator<D, D>,
{
    pub jtj: OMatrix<f64, D, D>,
    pub jtr: OVector<f64, D>,
    /// `½ Σ r_i²`.
    pub cost: f64,
    /// Number of residuals summed.
    pub count: usize,
}

impl<D: Dim> Copy for NormalEquations<D>
where
    DefaultAllocator: Allocator<D> + Allocator<D, D>,
    OMatrix<f64, D, D>: Copy,
    OVector<f64, D>: Copy,
{
}

/// Accumulate the normal equations at `x` in one pass.
/// `None` if the model cannot be evaluated there or produced a non-finite number.
pub fn normal_equations<D: Dim>(problem: &impl Problem<D>, x: &OVector<f64, D>) -> Option<NormalEquations<D>>
where
    DefaultAllocator: Allocator<D> + Allocator<D, D>,
{
    let (dim, _) = x.shape_generic();
    let mut jtj = OMatrix::<f64, D, D>::zeros_generic(dim, dim);
    let mut jtr = OVector::<f64, D>::zeros_generic(dim, Const::<1>);
    let mut ss = 0.0;
    let mut count = 0;
    let ok = problem.for_each_row(x, |r, j| {
        // The whole rank-one update, column by column: for a fixed size the compiler
        // unrolls and vectorises it, which beats skipping the lower triangle.
        jtj.ger(1.0, j, j, 1.0);
        jtr.axpy(r, j, 1.0);
        ss += r * r;
        count += 1;
    });
    let finite = ss.is_finite() && jtr.iter().chain(jtj.iter()).all(|v| v.is_finite());
    (ok && finite).then_some(NormalEquations { jtj, jtr, cost: 0.5 * ss, count })
}

/// All residuals at `x` (for tests, plots and adapters; the solver never builds it).
pub fn residuals<D: Dim>(problem: &impl Problem<D>, x: &OVector<f64, D>) -> Option<DVector<f64>>
where
    DefaultAllocator: Allocator<D>,
{
    let mut r = Vec::with_capacity(problem.residual_count());
    problem.for_each_row(x, |ri, _| r.push(ri)).then(|| DVector::from_vec(r))
}

/// The full `n×P` Jacobian at `x` (for tests and adapters; the solver never builds it).
pub fn jacobian<D: Dim>(problem: &impl Problem<D>, x: &OVector<f64, D>) -> Option<DMatrix<f64>>
where
    DefaultAllocator: Allocator<D>,
{
    let n = problem.residual_count();
    let mut jac = DMatrix::zeros(n, x.len());
    let mut i = 0;
    let ok = problem.for_each_row(x, |_, j| {
        jac.row_mut(i).iter_mut().zip(j.iter()).for_each(|(a, b)| *a = *b);
        i += 1;
    });
    (ok && i == n).then_some(jac)
}

/// Central-difference Jacobian of `f` at `x`, step `h_j = eps·max(|x_j|, scale_j)`.
/// For checking analytic Jacobians in tests.
pub fn differentiate_numerically<D: Dim>(
    x: &OVector<f64, D>,
    scale: &OVector<f64, D>,
    mut f: impl FnMut(&OVector<f64, D>) -> DVector<f64>,
) -> DMatrix<f64>
where
    DefaultAllocator: Allocator<D>,
{
    let eps = 1e-6;
    let n = f(x).len();
    let mut jac = DMatrix::zeros(n, x.len());
    for j in 0..x.len() {
        let h = eps * x[j].abs().max(scale[j]);
        let (mut xp, mut xm) = (x.clone(), x.clone());
        xp[j] += h;
        xm[j] -= h;
        let col = (f(&xp) - f(&xm)) / (2.0 * h);
        jac.column_mut(j).copy_from(&col);
    }
    jac
}

/// Solver settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Options {
    pub max_iterations: usize,
    /// Relative cost reduction below which the fit has converged.
    pub ftol: f64,
    /// Relative (scaled) step size below which the fit has converged.
    pub xtol: f64,
    /// Cosine between residual and Jacobian columns below which the fit has converged.
    pub gtol: f64,
    /// Distance to the minimum, in standard uncertainties of the result, below which
    /// the fit has converged (0 disables the test).
    pub stol: f64,
    /// Initial damping `μ₀` relative to `D²` (Nielsen's τ). Small values trust
    /// Gauss-Newton from the start; 1e-2 suits a start from a good initial guess.
    pub initial_damping: f64,
}

impl Default for Options {
    fn default() -> Self {
        Options { max_iterations: 100, ftol: 1e-12, xtol: 1e-10, gtol: 1e-10, stol: 1e-3, initial_damping: 1e-3 }
    }
}

/// Why the solver stopped.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Termination {
    Uncertainty,
    Gradient,
    Step,
    Cost,
    NoFurtherDecrease,
    MaxIterations,
    NonFinite,
}

impl Termination {
    /// Stopped at a minimum (as opposed to running out of iterations or numbers).
    pub fn converged(self) -> bool {
        matches!(self, Self::Uncertainty | Self::Gradient | Self::Step | Self::Cost | Self::NoFurtherDecrease)
    }

    pub fn describe(self) -> &'static str {
        match self {
            Self::Uncertainty => "converged (remaining step below the uncertainty)",
            Self::Gradient => "converged (gradient)",
            Self::Step => "converged (step)",
            Self::Cost => "converged (cost)",
            Self::NoFurtherDecrease => "converged (no further decrease at machine precision)",
            Self::MaxIterations => "did not converge within the iteration limit",
            Self::NonFinite => "the model could not be evaluated (non-finite value)",
        }
    }
}

/// What the solver found.
#[derive(Debug, Clone, PartialEq)]
pub struct Report<D: Dim>
where
    DefaultAllocator: Allocator<D> + Allocator<D, D>,
{
    pub x: OVector<f64, D>,
    pub termination: Termination,
    /// Iterations (steps tried).
    pub iterations: usize,
    /// Passes over the residuals (each gives residuals and normal equations).
    pub evaluations: usize,
    /// Normal equations at `x` (`None` only for [`Termination::NonFinite`]).
    pub normal: Option<NormalEquations<D>>,
}

impl<D: Dim> Copy for Report<D>
where
    DefaultAllocator: Allocator<D> + Allocator<D, D>,
    OMatrix<f64, D, D>: Copy,
    OVector<f64, D>: Copy,
{
}

impl<D: Dim> Report<D>
where
    DefaultAllocator: Allocator<D> + Allocator<D, D>,
{
    pub fn cost(&self) -> f64 {
        self.normal.as_ref().map_or(f64::INFINITY, |n| n.cost)
    }
}

/// Minimise `½‖r(x)‖²` from `x0`.
pub fn minimize<D: Dim>(problem: &impl Problem<D>, x0: OVector<f64, D>, opt: &Options) -> Report<D>
where
    DefaultAllocator: Allocator<D> + Allocator<D, D>,
{
    let p = x0.len();
    let mut x = x0;
    let mut evaluations = 1;
    let Some(mut ne) = normal_equations(problem, &x) else {
        return Report { x, termination: Termination::NonFinite, iterations: 0, evaluations, normal: None };
    };
    let mut d2 = ne.jtj.diagonal().map(|v| v.max(f64::MIN_POSITIVE));
    let mut mu = opt.initial_damping;
    let mut nu = 2.0;
    let finish = |x, termination, iterations, evaluations, ne| Report {
        x,
        termination,
        iterations,
        evaluations,
        normal: Some(ne),
    };

    for iteration in 1..=opt.max_iterations {
        if gradient_converged(&ne, opt.gtol) {
            return finish(x, Termination::Gradient, iteration - 1, evaluations, ne);
        }
        if within_uncertainty(&ne, opt.stol) {
            return finish(x, Termination::Uncertainty, iteration - 1, evaluations, ne);
        }
        let mut a = ne.jtj.clone();
        for i in 0..p {
            a[(i, i)] += mu * d2[i];
        }
        let Some(chol) = a.cholesky() else {
            mu *= nu;
            nu *= 2.0;
            continue;
        };
        let h = chol.solve(&(-&ne.jtr));
        let dh = h.component_mul(&d2.map(f64::sqrt)).norm();
        let dx = x.component_mul(&d2.map(f64::sqrt)).norm();
        if dh <= opt.xtol * (dx + opt.xtol) {
            return finish(x, Termination::Step, iteration, evaluations, ne);
        }
        let predicted = 0.5 * h.dot(&(h.component_mul(&d2) * mu - &ne.jtr));
        let x_new = &x + h;
        evaluations += 1;
        let trial = normal_equations(problem, &x_new);
        let actual = trial.as_ref().map_or(f64::NEG_INFINITY, |t| ne.cost - t.cost);
        let gain = actual / predicted;
        if let (Some(t), true) = (trial, gain > 0.0 && predicted > 0.0) {
            let old_cost = ne.cost;
            x = x_new;
            ne = t;
            for i in 0..p {
                d2[i] = d2[i].max(ne.jtj[(i, i)]);
            }
            mu *= (1.0 - (2.0 * gain - 1.0).powi(3)).max(1.0 / 3.0);
            nu = 2.0;
            if actual <= opt.ftol * old_cost && predicted <= opt.ftol * old_cost {
                return finish(x, Termination::Cost, iteration, evaluations, ne);
            }
        } else {
            mu *= nu;
            nu *= 2.0;
            if mu > 1e30 {
                return finish(x, Termination::NoFurtherDecrease, iteration, evaluations, ne);
            }
        }
    }
    let termination =
        if gradient_converged(&ne, opt.gtol) { Termination::Gradient } else { Termination::MaxIterations };
    finish(x, termination, opt.max_iterations, evaluations, ne)
}

/// The Gauss-Newton step's length in standard uncertainties: `gᵀ(JᵀJ)⁻¹g <= stol² σ̂²`.
fn within_uncertainty<D: Dim>(ne: &NormalEquations<D>, stol: f64) -> bool
where
    DefaultAllocator: Allocator<D> + Allocator<D, D>,
{
    let p = ne.jtr.len();
    if stol <= 0.0 || ne.count <= p {
        return false;
    }
    let sigma2 = 2.0 * ne.cost / (ne.count - p) as f64;
    match ne.jtj.clone().cholesky() {
        Some(c) => ne.jtr.dot(&c.solve(&ne.jtr)) <= stol * stol * sigma2,
        None => false,
    }
}

/// MINPACK's scale-free gradient test: `max_j |g_j| / (‖J_j‖ ‖r‖) <= gtol`.
fn gradient_converged<D: Dim>(ne: &NormalEquations<D>, gtol: f64) -> bool
where
    DefaultAllocator: Allocator<D> + Allocator<D, D>,
{
    if ne.cost == 0.0 {
        return true;
    }
    let rnorm = (2.0 * ne.cost).sqrt();
    (0..ne.jtr.len()).all(|j| {
        let cn = ne.jtj[(j, j)].sqrt();
        cn == 0.0 || ne.jtr[j].abs() / (cn * rnorm) <= gtol
    })
}

/// Covariance `σ̂² (JᵀJ)⁻¹` of the fitted parameters, `σ̂² = ‖r‖² / (n - P)`.
/// `None` if `JᵀJ` is singular or there are no degrees of freedom left.
pub fn covariance<D: Dim>(ne: &NormalEquations<D>) -> Option<OMatrix<f64, D, D>>
where
    DefaultAllocator: Allocator<D> + Allocator<D, D>,
{
    let p = ne.jtr.len();
    if ne.count <= p {
        return None;
    }
    let sigma2 = 2.0 * ne.cost / (ne.count - p) as f64;
    ne.jtj.clone().cholesky().map(|c| c.inverse() * sigma2)
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;
    use nalgebra::SVector;
    use nalgebra::Vector2;

    /// Rosenbrock as least squares: r = (10 (y - x²), 1 - x), minimum at (1, 1).
    struct Rosenbrock;
    impl Problem<nalgebra::U2> for Rosenbrock {
        fn residual_count(&self) -> usize {
            2
        }
        fn for_each_row(&self, x: &Vector2<f64>, mut row: impl FnMut(f64, &Vector2<f64>)) -> bool {
            row(10.0 * (x[1] - x[0] * x[0]), &Vector2::new(-20.0 * x[0], 10.0));
            row(1.0 - x[0], &Vector2::new(-1.0, 0.0));
            true
        }
    }

    #[test]
    fn rosenbrock_from_the_classic_start() {
        let rep = minimize(&Rosenbrock, Vector2::new(-1.2, 1.0), &Options::default());
        assert!(rep.termination.converged(), "{:?}", rep.termination);
        assert_relative_eq!(rep.x, Vector2::new(1.0, 1.0), epsilon = 1e-9);
        assert!(rep.iterations < 60, "{}", rep.iterations);
    }

    /// Exponential decay with noise: the covariance matches the textbook value, and
    /// the normal equations match the explicit Jacobian.
    struct Decay {
        t: Vec<f64>,
        y: Vec<f64>,
    }
    impl Problem<nalgebra::U2> for Decay {
        fn residual_count(&self) -> usize {
            self.t.len()
        }
        fn for_each_row(&self, x: &Vector2<f64>, mut row: impl FnMut(f64, &Vector2<f64>)) -> bool {
            for (&t, &y) in self.t.iter().zip(&self.y) {
                let e = (-x[1] * t).exp();
                row(x[0] * e - y, &Vector2::new(e, -x[0] * t * e));
            }
            true
        }
    }

    #[test]
    fn normal_equations_agree_with_the_jacobian_and_numeric_derivatives() {
        let t: Vec<f64> = (0..30).map(|i| i as f64 * 0.1).collect();
        let y = t
            .iter()
            .enumerate()
            .map(|(i, t)| 2.0 * (-0.7 * t).exp() + 0.01 * ((i * 7919) % 13) as f64 / 13.0)
            .collect();
        let p = Decay { t, y };
        let x = Vector2::new(1.5, 0.5);
        let ne = normal_equations(&p, &x).unwrap();
        let j = jacobian(&p, &x).unwrap();
        let r = residuals(&p, &x).unwrap();
        assert_relative_eq!(ne.jtj, (j.transpose() * &j).fixed_view::<2, 2>(0, 0).into_owned(), epsilon = 1e-12);
        assert_relative_eq!(ne.cost, 0.5 * r.norm_squared(), epsilon = 1e-12);
        let num = differentiate_numerically(&x, &Vector2::new(1.0, 1.0), |x| residuals(&p, x).unwrap());
        assert_relative_eq!(num, j, epsilon = 1e-7);

        let rep = minimize(&p, x, &Options::default());
        assert!(rep.termination.converged());
        let cov = covariance(&rep.normal.unwrap()).unwrap();
        let j = jacobian(&p, &rep.x).unwrap();
        let r = residuals(&p, &rep.x).unwrap();
        let want = (j.transpose() * &j).try_inverse().unwrap() * (r.norm_squared() / 28.0);
        assert_relative_eq!(cov, want.fixed_view::<2, 2>(0, 0).into_owned(), max_relative = 1e-9);
    }

    /// A model that cannot be evaluated at the start reports NonFinite; one that cannot
    /// be evaluated at a trial point just rejects the step.
    struct Sqrt;
    impl Problem<nalgebra::U1> for Sqrt {
        fn residual_count(&self) -> usize {
            1
        }
        fn for_each_row(&self, x: &SVector<f64, 1>, mut row: impl FnMut(f64, &SVector<f64, 1>)) -> bool {
            if x[0] < 0.0 {
                return false;
            }
            row(x[0].sqrt() - 0.1, &SVector::<f64, 1>::new(0.5 / x[0].sqrt()));
            true
        }
    }

    #[test]
    fn unevaluable_points() {
        let rep = minimize(&Sqrt, SVector::<f64, 1>::new(-1.0), &Options::default());
        assert_eq!(rep.termination, Termination::NonFinite);
        assert!(!rep.termination.converged());
        let rep =
            minimize(&Sqrt, SVector::<f64, 1>::new(4.0), &Options { initial_damping: 1e-8, ..Options::default() });
        assert!(rep.termination.converged(), "{:?}", rep.termination);
        assert_relative_eq!(rep.x[0], 0.01, epsilon = 1e-10);
    }
}
