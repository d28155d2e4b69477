//! A start for the full model that converges from any mounting error in range.
//!
//! The full model is non-linear in `alpha0` (and in which part of the plate each
//! sample touches), but on a flat side it is **linear** once `cos alpha0`, `sin alpha0`
//! and their products with `d`, `dL` are taken as unknowns. On the side with outward
//! normal `e` the touched point satisfies `P·e = S/2 + c·e`; writing
//! `P = (rho - dL) u + d v`, `u = R(alpha0) u₀` (`u₀ = (cos φ, sin φ)`), and
//! `A = u₀·e`, `B = u₀ × e`:
//!
//! ```text
//! rho A X1 + rho B X2 - A Y1 - B Y2 - c·e = S/2
//! X = (cos alpha0, sin alpha0),   Y1 = dL X1 + d X2,   Y2 = dL X2 - d X1
//! ```
//!
//! six unknowns `z = (X1, X2, Y1, Y2, cx, cy)`, one linear least-squares solve, from
//! which `alpha0 = atan2(X2, X1)`, `dL = (X·Y)/|X|²`, `d = (X2 Y1 - X1 Y2)/|X|²`.
//!
//! What it needs is to know which side each sample touched. From a seed of
//! `(alpha0, d)`, the samples are corrected with the current estimate and assigned to
//! the side they then lie on; only those well inside a flat (a margin from the corner
//! arcs that shrinks as the estimate improves: 45 %, 25 %, 10 % of the flat's half
//! length) enter the solve. A seed grid of 15° in `alpha0` and `S/4.5` in `d` keeps
//! every true value within the tolerance of some seed; the candidate with the lowest
//! full-model cost wins. Tested in `tests/engine.rs` (`converges_across_the_whole_region`): every case of
//! `alpha0 ∈ (-45°, 45°]`, `|d| <= 20 mm` converges.

use nalgebra::{SMatrix, SVector, Vector2};

use super::geometry::rotate;
use super::lm::normal_equations;
use super::model::PlateSpec;
use super::model::full::{FullModel, Params};

/// Seeds of `alpha0`, degrees.
const ALPHA_SEEDS_DEG: [f64; 6] = [-37.5, -22.5, -7.5, 7.5, 22.5, 37.5];
/// Seeds of `d`, as fractions of the plate side.
const OFFSET_SEEDS: [f64; 4] = [-1.0 / 3.0, -1.0 / 9.0, 1.0 / 9.0, 1.0 / 3.0];
/// Margins from the arcs, as fractions of the flat's half length, per refinement.
const MARGINS: [f64; 3] = [0.45, 0.25, 0.10];

/// The best start found, and its full-model cost.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Start {
    pub x: Params,
    pub cost: f64,
}

/// Search the seed grid; `None` if no seed gave a usable estimate.
pub fn initial_guess(model: &FullModel, plate: &PlateSpec) -> Option<Start> {
    let mut best: Option<Start> = None;
    for &alpha_deg in &ALPHA_SEEDS_DEG {
        for &d_frac in &OFFSET_SEEDS {
            let seed = seed_params(model, alpha_deg.to_radians(), d_frac * plate.side);
            let Some(x) = refine(model, plate, seed) else { continue };
            let Some(ne) = normal_equations(model, &x) else { continue };
            if best.is_none_or(|b| ne.cost < b.cost) {
                best = Some(Start { x, cost: ne.cost });
            }
        }
    }
    best
}

/// A seed with the plate centred on the axis and `dL` matching the mean length.
fn seed_params(model: &FullModel, alpha0: f64, d: f64) -> Params {
    let x = Params::from([alpha0, d, 0.0, 0.0, 0.0]);
    let dl = model.predict(&x).map_or(0.0, |pred| {
        let n = pred.len().max(1) as f64;
        model.samples().iter().zip(pred).map(|(s, p)| s.rho - p).sum::<f64>() / n
    });
    Params::from([alpha0, d, dl, 0.0, 0.0])
}

/// Alternate side assignment and the linear solve, with shrinking margins.
fn refine(model: &FullModel, plate: &PlateSpec, mut x: Params) -> Option<Params> {
    let half = plate.side / 2.0;
    let flat_half = half - plate.corner_radius;
    for &margin in &MARGINS {
        x = linear_solve(model, half, flat_half * (1.0 - margin), &x)?;
    }
    Some(x)
}

/// One linear solve of the lifted flat-side equations (module docs), with samples
/// assigned to sides by where the estimate `x` puts them.
fn linear_solve(model: &FullModel, half: f64, flat_limit: f64, x: &Params) -> Option<Params> {
    let cs_alpha = (x[0].cos(), x[0].sin());
    let (d, dl, c) = (x[1], x[2], Vector2::new(x[3], x[4]));
    let mut ata = SMatrix::<f64, 6, 6>::zeros();
    let mut atb = SVector::<f64, 6>::zeros();
    let mut used = [0usize; 4];
    for s in model.samples() {
        let (ca, sa) = rotate((s.cos_phi, s.sin_phi), cs_alpha);
        let q = Vector2::new(ca, sa) * (s.rho - dl) + Vector2::new(-sa, ca) * d - c;
        let (e, along, side) = if q.x.abs() >= q.y.abs() {
            (Vector2::new(q.x.signum(), 0.0), q.y, if q.x >= 0.0 { 0 } else { 1 })
        } else {
            (Vector2::new(0.0, q.y.signum()), q.x, if q.y >= 0.0 { 2 } else { 3 })
        };
        if along.abs() > flat_limit {
            continue;
        }
        used[side] += 1;
        let a = s.cos_phi * e.x + s.sin_phi * e.y;
        let b = s.cos_phi * e.y - s.sin_phi * e.x;
        let row = SVector::<f64, 6>::from([s.rho * a, s.rho * b, -a, -b, -e.x, -e.y]);
        ata += row * row.transpose();
        atb += row * half;
    }
    // Both sides of each axis are needed to tell the centre from dL.
    if used.iter().any(|&n| n < 2) {
        return None;
    }
    let z = ata.cholesky()?.solve(&atb);
    let s2 = z[0] * z[0] + z[1] * z[1];
    if !(s2.is_finite() && s2 > 0.25 && s2 < 4.0) {
        return None;
    }
    let alpha0 = z[1].atan2(z[0]);
    let delta_l = (z[0] * z[2] + z[1] * z[3]) / s2;
    let offset = (z[1] * z[2] - z[0] * z[3]) / s2;
    let out = Params::from([alpha0, offset, delta_l, z[4], z[5]]);
    out.iter().all(|v| v.is_finite()).then_some(out)
}
