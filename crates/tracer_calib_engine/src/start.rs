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
//! every true value within the tolerance of some seed.
//!
//! **Which seeds are refined.** Every seed gets the first solve (45 % margin); a seed
//! whose side assignment is wrong gives equations that contradict each other, and its
//! solve leaves a large residual. The lifted residual comes free from the normal
//! equations (`‖Az - b‖² = bᵀb - zᵀAᵀb` at the solution, `b = S/2`), as a length: its
//! RMS over the samples used ranks the seeds (these first solves take every other
//! sample: they only rank). Only the [`REFINED`] best are refined
//! to the end, and of those the one with the lowest full-model cost wins. The seed's
//! `dL` (the mean of `rho` less the mean exit distance) depends on `d` alone over a
//! whole revolution, so it is computed once for each `d`. Tested in `tests/engine.rs`
//! (`converges_across_the_whole_region`): every case of `alpha0 ∈ (-45°, 45°]`,
//! `|d| <= 20 mm` converges.

use nalgebra::{SMatrix, SVector, Vector2};

use super::geometry::rotate;
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

/// Seeds refined to the end, of the ranked first solves.
pub const REFINED: usize = 3;
/// The first solves, which only rank the seeds, take every `RANKING_STRIDE`-th sample.
const RANKING_STRIDE: usize = 2;

/// Search the seed grid; `None` if no seed gave a usable estimate.
pub fn initial_guess(model: &FullModel, plate: &PlateSpec) -> Option<Start> {
    let half = plate.side / 2.0;
    let flat_half = half - plate.corner_radius;
    // The first solve of every seed, ranked by its lifted residual.
    let mut ranked: Vec<(f64, Params)> = Vec::with_capacity(ALPHA_SEEDS_DEG.len() * OFFSET_SEEDS.len());
    for &d_frac in &OFFSET_SEEDS {
        let d = d_frac * plate.side;
        let dl = seed_delta_l(model, d);
        for &alpha_deg in &ALPHA_SEEDS_DEG {
            let seed = Params::from([alpha_deg.to_radians(), d, dl, 0.0, 0.0]);
            if let Some(first) = linear_solve(model, half, flat_half * (1.0 - MARGINS[0]), &seed, RANKING_STRIDE) {
                ranked.push((first.rms, first.x));
            }
        }
    }
    ranked.sort_by(|a, b| a.0.total_cmp(&b.0));
    let mut best: Option<Start> = None;
    for &(_, mut x) in ranked.iter().take(REFINED) {
        let refined = MARGINS[1..].iter().try_for_each(|&margin| {
            x = linear_solve(model, half, flat_half * (1.0 - margin), &x, 1)?.x;
            Some(())
        });
        if refined.is_none() {
            continue;
        }
        let Some(cost) = model.cost(&x) else { continue };
        if best.is_none_or(|b| cost < b.cost) {
            best = Some(Start { x, cost });
        }
    }
    best
}

/// The seed's `dL`: the mean length read less the mean exit distance of a plate centred
/// on the axis, with the rail `d` off it. Over a whole revolution the mean exit distance
/// does not depend on `alpha0` (the seed uses 0).
fn seed_delta_l(model: &FullModel, d: f64) -> f64 {
    let (mut sum, mut n) = (0.0, 0usize);
    let x = Params::from([0.0, d, 0.0, 0.0, 0.0]);
    if !model.for_each_prediction(&x, |s, t, _| {
        sum += s.rho - t;
        n += 1;
    }) {
        return 0.0;
    }
    sum / n.max(1) as f64
}

/// A linear solve's estimate, and the RMS of its lifted residual (metres).
struct Solve {
    x: Params,
    rms: f64,
}

/// One linear solve of the lifted flat-side equations (module docs), with samples
/// assigned to sides by where the estimate `x` puts them.
fn linear_solve(model: &FullModel, half: f64, flat_limit: f64, x: &Params, stride: usize) -> Option<Solve> {
    let cs_alpha = (x[0].cos(), x[0].sin());
    let (d, dl, c) = (x[1], x[2], Vector2::new(x[3], x[4]));
    // Upper triangle of AᵀA in a plain array (the compiler unrolls it), and Aᵀb / (S/2).
    let mut ata = [[0.0f64; 6]; 6];
    let mut at1 = [0.0f64; 6];
    let mut used = [0usize; 4];
    for s in model.samples().iter().step_by(stride) {
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
        let row = [s.rho * a, s.rho * b, -a, -b, -e.x, -e.y];
        for i in 0..6 {
            at1[i] += row[i];
            for j in i..6 {
                ata[i][j] += row[i] * row[j];
            }
        }
    }
    // Both sides of each axis are needed to tell the centre from dL.
    if used.iter().any(|&n| n < 2) {
        return None;
    }
    let ata = SMatrix::<f64, 6, 6>::from_fn(|i, j| if i <= j { ata[i][j] } else { ata[j][i] });
    let atb = SVector::<f64, 6>::from(at1) * half;
    let z = ata.cholesky()?.solve(&atb);
    let s2 = z[0] * z[0] + z[1] * z[1];
    if !(s2.is_finite() && s2 > 0.25 && s2 < 4.0) {
        return None;
    }
    // ‖Az - b‖² = bᵀb - zᵀAᵀb at the least-squares solution (rounding can make it
    // slightly negative for an exact fit).
    let n: usize = used.iter().sum();
    let rss = (n as f64 * half * half - z.dot(&atb)).max(0.0);
    let alpha0 = z[1].atan2(z[0]);
    let delta_l = (z[0] * z[2] + z[1] * z[3]) / s2;
    let offset = (z[1] * z[2] - z[0] * z[3]) / s2;
    let out = Params::from([alpha0, offset, delta_l, z[4], z[5]]);
    out.iter().all(|v| v.is_finite()).then_some(Solve { x: out, rms: (rss / n as f64).sqrt() })
}
