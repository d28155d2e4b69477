//! The turntable model: the angle encoder's harmonics ([`crate::angle`]) and
//! several placements of the plate, with any of the other models' parameters.
//!
//! A placement is one scan of the plate, set down anew: its own centre `c_p` and its own
//! turn `θ_p` against the first (counter-clockwise: a square plate turned 22.5° between
//! two scans). The rail angle of sample `n` of placement `p` seen from the plate is
//!
//! ```text
//! a_pn = alpha0 - θ_p + φ_n + ε(φ_n),     θ_0 = 0
//! ```
//!
//! and the length the encoder should read is the full model's ([`super::full`]) at that
//! angle, with the plate grown by the tip (`full_tip`: the fitted `ρ`, [`super::tip`]); a
//! ring-gauge scan adds its samples as in [`super::tip`] (a circle: no turn of its own).
//! Residuals `r = q - rho`, or `q/k - rho` with the scale ([`super::full_scale`]).
//!
//! **Parameters**, a vector whose length depends on what is fitted ([`Layout`]):
//!
//! ```text
//! [alpha0, d, dL, (k), (ρ), c_h₁, s_h₁, ..., (θ_p,) cx_p, cy_p for each placement, (gx, gy)]
//! ```
//!
//! **Jacobian.** The angle enters only through `a`, so with the full model's row
//! `∂q/∂alpha0` at the sample, `∂q/∂θ_p = -∂q/∂alpha0` (its own placement's rows) and
//! `∂q/∂c_h = ∂q/∂alpha0 · cos hφ_n`, `∂q/∂s_h = ∂q/∂alpha0 · sin hφ_n`; the rest is the
//! full model's, the tip model's and the scale model's rows.
//!
//! **What one placement cannot tell.** A square plate's lengths repeat every quarter turn:
//! an angle error of order `h = 4, 8, ...` moves them as a change of the plate's own shape
//! would, and is nearly a combination of `alpha0` and `d` on every side (its variance
//! inflation is in the thousands). A second placement turned by `θ` sees the error turned
//! by `hθ` against the plate: 22.5° separates 4 and 8. [`Layout::inflation`] measures this
//! before the fit.

use nalgebra::{DMatrix, DVector, Vector2};

use super::full::{self, FullModel, TableSample};
use super::tip::{self, RingSpec, TipModel};
use super::{InputDerivatives, PlateSpec};
use crate::angle::HarmonicOrders;
use crate::geometry::rotate;
use crate::lm::Problem;
use crate::scan::Scan;

/// Where each parameter sits in the turntable model's vector (module docs).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Layout {
    pub orders: HarmonicOrders,
    /// The encoder scale `k` is fitted.
    pub scale: bool,
    /// The tip radius `ρ` is fitted, with a ring gauge's centre.
    pub tip: bool,
    /// Plate scans, at least one.
    pub placements: usize,
}

pub const ALPHA0: usize = 0;
pub const OFFSET: usize = 1;
pub const DELTA_L: usize = 2;

impl Layout {
    /// Index of `k`.
    pub fn scale(&self) -> Option<usize> {
        self.scale.then_some(3)
    }

    /// Index of `ρ`.
    pub fn tip(&self) -> Option<usize> {
        self.tip.then_some(3 + usize::from(self.scale))
    }

    /// Index of the first harmonic coefficient.
    pub fn harmonics(&self) -> usize {
        3 + usize::from(self.scale) + usize::from(self.tip)
    }

    /// Index of placement `p`'s turn (none for the first) and of its centre's x.
    pub fn placement(&self, p: usize) -> (Option<usize>, usize) {
        let first = self.harmonics() + 2 * self.orders.len();
        if p == 0 { (None, first) } else { (Some(first + 3 * p - 1), first + 3 * p) }
    }

    /// Index of the ring's centre's x.
    pub fn ring(&self) -> Option<usize> {
        self.tip.then(|| self.placement(self.placements - 1).1 + 2)
    }

    /// How many parameters.
    pub fn len(&self) -> usize {
        self.placement(self.placements - 1).1 + 2 + if self.tip { 2 } else { 0 }
    }

    pub fn is_empty(&self) -> bool {
        false
    }

    /// Where the tracer's parameters `[alpha0, d, dL, k, ρ]` are (`None`: not fitted),
    /// then every harmonic coefficient: the rows of the named covariance.
    pub fn tracer(&self) -> Vec<Option<usize>> {
        let h = self.harmonics();
        [Some(ALPHA0), Some(OFFSET), Some(DELTA_L), self.scale(), self.tip()]
            .into_iter()
            .chain((0..2 * self.orders.len()).map(|i| Some(h + i)))
            .collect()
    }

    /// The variance inflation of each harmonic coefficient, `[(JᵀJ)⁻¹]_jj [JᵀJ]_jj`: 1 for
    /// a coefficient the other parameters do not mimic, large for one they do (module
    /// docs); `None` where `JᵀJ` is singular.
    pub fn inflation(&self, jtj: &DMatrix<f64>) -> Option<Vec<(u32, f64)>> {
        // Scaled to unit diagonal first: the parameters' units differ by 1e4.
        let d = jtj.diagonal().map(|v| 1.0 / v.max(f64::MIN_POSITIVE).sqrt());
        let scaled = DMatrix::from_fn(jtj.nrows(), jtj.ncols(), |i, j| jtj[(i, j)] * d[i] * d[j]);
        let inv = scaled.cholesky()?.inverse();
        let h = self.harmonics();
        Some(
            self.orders
                .iter()
                .enumerate()
                .map(|(i, order)| (order, inv[(h + 2 * i, h + 2 * i)].max(inv[(h + 2 * i + 1, h + 2 * i + 1)])))
                .collect(),
        )
    }
}

/// One placement's samples: their step angles' table and each sample's harmonic basis.
#[derive(Debug, Clone)]
struct Placement {
    samples: Vec<TableSample>,
    /// `cos hφ, sin hφ` of every order, `2H` a sample.
    basis: Vec<f64>,
}

impl Placement {
    fn new(scan: &Scan, orders: HarmonicOrders) -> Self {
        let n = scan.steps_per_rev();
        let samples = scan.samples().iter().map(|s| TableSample::new(s.step, n, s.rho)).collect();
        let basis = scan.samples().iter().flat_map(|s| orders.basis(crate::geometry::step_angle(s.step, n))).collect();
        Placement { samples, basis }
    }

    fn retain(&self, width: usize, mut keep: impl FnMut(usize) -> bool) -> Self {
        let (mut samples, mut basis) = (Vec::new(), Vec::new());
        for (i, s) in self.samples.iter().enumerate() {
            if keep(i) {
                samples.push(*s);
                basis.extend_from_slice(&self.basis[i * width..(i + 1) * width]);
            }
        }
        Placement { samples, basis }
    }

    /// The samples with each step angle moved by `ε(φ)` for `coefficients`.
    fn turned(&self, coefficients: &[f64]) -> Vec<TableSample> {
        let width = coefficients.len();
        if width == 0 {
            return self.samples.clone();
        }
        self.samples
            .iter()
            .zip(self.basis.chunks_exact(width))
            .map(|(s, b)| {
                let e: f64 = b.iter().zip(coefficients).map(|(b, c)| b * c).sum();
                let (sin, cos) = e.sin_cos();
                let (c, s2) = rotate((s.cos_phi, s.sin_phi), (cos, sin));
                TableSample { cos_phi: c, sin_phi: s2, rho: s.rho }
            })
            .collect()
    }
}

/// The turntable model of some plate scans and perhaps a ring-gauge scan (module docs):
/// residuals plate by plate in scan order, then the ring's.
#[derive(Debug, Clone)]
pub struct TurntableModel {
    layout: Layout,
    /// The plate as the fit sees it: grown by the tip in force unless `ρ` is fitted.
    plate: PlateSpec,
    plates: Vec<Placement>,
    ring: Option<(RingSpec, Placement)>,
}

/// Which sample a row belongs to.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Source {
    Plate(usize),
    Ring,
}

impl TurntableModel {
    /// The model of `plates` (one a placement) and, for a tip model, the ring gauge.
    /// `plate` is the plate as the fit sees it (grown by the tip in force when `ρ` is not
    /// fitted); `layout.placements` and `layout.tip` follow the scans given.
    pub fn new(
        plate: &PlateSpec,
        plates: &[&Scan],
        ring: Option<(&RingSpec, &Scan)>,
        orders: HarmonicOrders,
        scale: bool,
    ) -> Self {
        let layout = Layout { orders, scale, tip: ring.is_some(), placements: plates.len().max(1) };
        TurntableModel {
            layout,
            plate: *plate,
            plates: plates.iter().map(|s| Placement::new(s, orders)).collect(),
            ring: ring.map(|(spec, scan)| (*spec, Placement::new(scan, orders))),
        }
    }

    pub fn layout(&self) -> &Layout {
        &self.layout
    }

    /// Samples of placement `p`.
    pub fn plate_len(&self, p: usize) -> usize {
        self.plates[p].samples.len()
    }

    /// Samples of the ring.
    pub fn ring_len(&self) -> usize {
        self.ring.as_ref().map_or(0, |(_, r)| r.samples.len())
    }

    /// The same scans with the scale fitted too (or not): for the score test of the scale.
    pub fn with_scale(&self, scale: bool) -> Self {
        TurntableModel { layout: Layout { scale, ..self.layout }, ..self.clone() }
    }

    /// `x` of this layout with `k` inserted at its place (for [`Self::with_scale`]).
    pub fn insert_scale(&self, x: &DVector<f64>, k: f64) -> DVector<f64> {
        x.clone().insert_row(3, k)
    }

    /// Keep only the samples (plates', then ring's) for which `keep(index)` is true.
    pub fn retain(&self, mut keep: impl FnMut(usize) -> bool) -> Self {
        let width = 2 * self.layout.orders.len();
        let mut start = 0;
        let mut plates = Vec::with_capacity(self.plates.len());
        for p in &self.plates {
            plates.push(p.retain(width, |i| keep(start + i)));
            start += p.samples.len();
        }
        let ring = self.ring.as_ref().map(|(spec, r)| (*spec, r.retain(width, |i| keep(start + i))));
        TurntableModel { plates, ring, ..self.clone() }
    }

    /// Placement `p`'s full-model parameters `[alpha0 - θ_p, d, dL, cx_p, cy_p]`.
    pub fn placement_params(&self, x: &DVector<f64>, p: usize) -> full::Params {
        let (turn, c) = self.layout.placement(p);
        let theta = turn.map_or(0.0, |i| x[i]);
        full::Params::from([x[ALPHA0] - theta, x[OFFSET], x[DELTA_L], x[c], x[c + 1]])
    }

    /// Calls `f(source, q, ∂q/∂x, inputs)` for every sample at `x` (module docs);
    /// `false` (and an early stop) where a rail ray misses or grazes a contour.
    pub fn for_each_prediction(
        &self,
        x: &DVector<f64>,
        mut f: impl FnMut(Source, &TableSample, f64, &DVector<f64>, InputDerivatives),
    ) -> bool {
        let l = &self.layout;
        let (h0, width) = (l.harmonics(), 2 * l.orders.len());
        let coefficients: Vec<f64> = x.rows(h0, width).iter().copied().collect();
        let grow = l.tip().map_or(0.0, |i| x[i]);
        let mut row = DVector::zeros(l.len());
        for (p, placement) in self.plates.iter().enumerate() {
            let model = FullModel::new(&self.plate, placement.turned(&coefficients));
            let (turn, c) = l.placement(p);
            let mut basis = placement.basis.chunks_exact(width.max(1));
            let ok = model.for_each_grown_prediction(&self.placement_params(x, p), grow, |s, q, j, size| {
                row.fill(0.0);
                let da = j[full::ALPHA0];
                row[ALPHA0] = da;
                row[OFFSET] = j[full::OFFSET];
                row[DELTA_L] = j[full::DELTA_L];
                if let Some(i) = l.tip() {
                    row[i] = size.grow;
                }
                if width > 0 {
                    for (k, b) in basis.next().unwrap_or(&[]).iter().enumerate() {
                        row[h0 + k] = da * b;
                    }
                }
                if let Some(i) = turn {
                    row[i] = -da;
                }
                row[c] = j[full::CX];
                row[c + 1] = j[full::CY];
                f(Source::Plate(p), s, q, &row, size.inputs(s.rho));
            });
            if !ok {
                return false;
            }
        }
        let Some((spec, ring)) = &self.ring else { return true };
        let (Some(g), Some(rho)) = (l.ring(), l.tip()) else { return false };
        let model = TipModel::new(FullModel::new(&self.plate, vec![]), spec, ring.turned(&coefficients));
        let x8 = tip::Params::from([x[ALPHA0], x[OFFSET], x[DELTA_L], x[rho], 0.0, 0.0, x[g], x[g + 1]]);
        let mut basis = ring.basis.chunks_exact(width.max(1));
        let mut inputs = model.input_derivatives(&x8).into_iter().flatten();
        model.for_each_prediction(&x8, |s, q, j| {
            row.fill(0.0);
            let da = j[tip::ALPHA0];
            row[ALPHA0] = da;
            row[OFFSET] = j[tip::OFFSET];
            row[DELTA_L] = j[tip::DELTA_L];
            row[rho] = j[tip::TIP_RADIUS];
            if width > 0 {
                for (k, b) in basis.next().unwrap_or(&[]).iter().enumerate() {
                    row[h0 + k] = da * b;
                }
            }
            row[g] = j[tip::GX];
            row[g + 1] = j[tip::GY];
            let nan = InputDerivatives { diameter: f64::NAN, ..InputDerivatives::default() };
            f(Source::Ring, s, q, &row, inputs.next().unwrap_or(nan));
        })
    }

    /// How every sample's length moves with the inputs taken as known at `x`
    /// ([`InputDerivatives`], of `q`: a residual `q/k - rho` moves by them over `k`),
    /// plates' samples then ring's.
    pub fn input_derivatives(&self, x: &DVector<f64>) -> Option<Vec<InputDerivatives>> {
        let mut out = Vec::with_capacity(self.residual_count());
        self.for_each_prediction(x, |_, _, _, _, d| out.push(d)).then_some(out)
    }
}

impl Problem<nalgebra::Dyn> for TurntableModel {
    fn residual_count(&self) -> usize {
        self.plates.iter().map(|p| p.samples.len()).sum::<usize>() + self.ring_len()
    }

    /// `r = q - rho`, or `q/k - rho` with `∂r/∂k = -q/k²` and the rest `∂q/∂x / k`.
    fn for_each_row(&self, x: &DVector<f64>, mut row: impl FnMut(f64, &DVector<f64>)) -> bool {
        match self.layout.scale() {
            None => self.for_each_prediction(x, |_, s, q, j, _| row(q - s.rho, j)),
            Some(i) => {
                let k = x[i];
                if k.is_nan() || k <= 0.0 {
                    return false;
                }
                let mut scaled = DVector::zeros(x.len());
                self.for_each_prediction(x, |_, s, q, j, _| {
                    scaled.copy_from(j);
                    scaled /= k;
                    scaled[i] = -q / (k * k);
                    row(q / k - s.rho, &scaled);
                })
            }
        }
    }
}

/// The start of the turntable model: every placement's full-model start (its own
/// `alpha0` and centre: `θ_p` the first's less its own), the first's `d` and `dL`, the scale and tip
/// given, no angle error, and the ring's centre given.
pub fn start(
    layout: &Layout,
    placements: &[full::Params],
    scale: f64,
    tip_radius: f64,
    ring_center: Vector2<f64>,
) -> DVector<f64> {
    let mut x = DVector::zeros(layout.len());
    let first = placements[0];
    x[ALPHA0] = first[full::ALPHA0];
    x[OFFSET] = first[full::OFFSET];
    x[DELTA_L] = first[full::DELTA_L];
    if let Some(i) = layout.scale() {
        x[i] = scale;
    }
    if let Some(i) = layout.tip() {
        x[i] = tip_radius;
    }
    for (p, xp) in placements.iter().enumerate() {
        let (turn, c) = layout.placement(p);
        if let Some(i) = turn {
            x[i] = first[full::ALPHA0] - xp[full::ALPHA0];
        }
        x[c] = xp[full::CX];
        x[c + 1] = xp[full::CY];
    }
    if let Some(g) = layout.ring() {
        x[g] = ring_center.x;
        x[g + 1] = ring_center.y;
    }
    x
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::Mounting;
    use crate::lm::{differentiate_numerically, jacobian, normal_equations, residuals};
    use crate::scan::Sample;

    const PLATE: PlateSpec = PlateSpec { side: 0.045, corner_radius: 0.003 };

    fn blank() -> Scan {
        Scan::from_samples(400, (0..400).map(|step| Sample { step, rho: 0.0 }).collect()).unwrap()
    }

    /// Two placements (the second turned 22.5°), harmonics 1, 2, 4, a ring; lengths
    /// from the model itself at `truth`.
    fn model_and_truth(scale: bool) -> (TurntableModel, DVector<f64>) {
        let orders = HarmonicOrders::new(&[1, 2, 4]).unwrap();
        let ring = RingSpec::plain(0.04);
        let b = blank();
        let m = TurntableModel::new(&PLATE, &[&b, &b], Some((&ring, &b)), orders, scale);
        let l = *m.layout();
        let mut x = start(
            &l,
            &[
                full::params(&Mounting::new(0.0349, 0.005, 0.002), Vector2::new(0.0008, -0.0005)),
                full::params(
                    &Mounting::new(0.0349 - std::f64::consts::FRAC_PI_8, 0.005, 0.002),
                    Vector2::new(-0.0004, 0.0003),
                ),
            ],
            1.001,
            0.0005,
            Vector2::new(-0.0006, 0.0004),
        );
        let h = l.harmonics();
        x.rows_mut(h, 6).copy_from_slice(&[8.7e-4, -3e-4, 3.5e-4, 1e-4, 1e-4, -5e-5]);
        let mut rho = Vec::new();
        let k = if scale { 1.001 } else { 1.0 };
        assert!(m.for_each_prediction(&x, |_, _, q, _, _| rho.push(q / k)));
        let mut it = rho.into_iter();
        let mut with = |p: &Placement| Placement {
            samples: p.samples.iter().map(|s| TableSample { rho: it.next().unwrap(), ..*s }).collect(),
            basis: p.basis.clone(),
        };
        let plates = m.plates.iter().map(&mut with).collect();
        let ring = m.ring.as_ref().map(|(spec, r)| (*spec, with(r)));
        (TurntableModel { plates, ring, ..m }, x)
    }

    #[test]
    fn residuals_vanish_at_the_truth_and_the_jacobian_is_the_derivative() {
        for scale in [false, true] {
            let (m, truth) = model_and_truth(scale);
            assert!(residuals(&m, &truth).unwrap().amax() < 1e-15);
            let mut off = truth.clone();
            off[ALPHA0] += 0.01;
            off[OFFSET] -= 0.001;
            off[m.layout().harmonics()] += 2e-4;
            let step = DVector::from_element(truth.len(), 1e-4);
            for x in [truth, off] {
                let analytic = jacobian(&m, &x).unwrap();
                let numeric = differentiate_numerically(&x, &step, |x| residuals(&m, x).unwrap());
                let bad = (0..analytic.nrows()).filter(|&i| (analytic.row(i) - numeric.row(i)).amax() > 1e-6).count();
                assert!(bad <= 4, "{bad} rows differ (scale {scale})");
            }
        }
    }

    #[test]
    fn one_placement_cannot_tell_order_four_two_can() {
        let orders = HarmonicOrders::new(&[1, 2, 4]).unwrap();
        let b = blank();
        let inflation = |turns: &[f64]| {
            let scans: Vec<&Scan> = turns.iter().map(|_| &b).collect();
            let m = TurntableModel::new(&PLATE, &scans, None, orders, false);
            let xs: Vec<full::Params> = turns
                .iter()
                .map(|t| full::params(&Mounting::new(0.02 + t, 0.003, 0.001), Vector2::new(0.0005, 0.0002)))
                .collect();
            let x = start(m.layout(), &xs, 1.0, 0.0, Vector2::zeros());
            let ne = normal_equations(&m, &x).unwrap();
            m.layout().inflation(&ne.jtj).unwrap()
        };
        // One placement: order 4's coefficients have 16 times the variance they would have
        // alone (44 times with the rail through the axis); turned 22.5°, 3.
        let one = inflation(&[0.0]);
        let two = inflation(&[0.0, 22.5f64.to_radians()]);
        assert!(one[0].1 < 1.5 && one[1].1 < 1.5, "{one:?}");
        assert!(one[2].1 > 10.0, "{one:?}");
        assert!(two.iter().all(|(_, v)| *v < 4.0), "{two:?}");
    }
}
