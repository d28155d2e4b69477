//! The stylus tip: from the path of its centre to the surface it touched.
//!
//! The encoder reads where the centre of the probe's ball tip (radius `ρ`) is, so a
//! corrected scan ([`super::correct`](mod@super::correct)) is the path of that centre: the traced contour
//! offset by `ρ` along its normal, outward when the tip traces from outside (a plate, a
//! lens), inward when it traces from inside (a frame's groove, a ring gauge). The
//! surface is the path moved back, `X = C - s ρ N`, `s = +1` from outside and `-1`
//! from inside, with `N` the path's outward unit normal (the offset curves of a smooth
//! contour share their normals).
//!
//! **The normal.** The rail turns counter-clockwise with the step, so a contour about
//! the axis is traversed counter-clockwise in sample order, and the outward normal of
//! the tangent `T = C_{i+h} - C_{i-h}` is `(T_y, -T_x)/|T|`. The chord spans `h =`
//! [`NORMAL_SPAN`] samples either side, so that the encoder's noise `σ` tilts `N` by
//! about `σ/(h Δs)` (`Δs` the sample spacing): at 10 µm on a 45 mm plate, 5 mrad, which
//! moves `X` along the contour by `5 µm` per millimetre of `ρ` and across it by nothing
//! that counts (`ρ (1 - cos)`). Near the ends of a scan that does not go all the way
//! round the chord is one-sided.
//!
//! A chord tilts where the curvature changes within it: on a flat running into a frame's
//! corner by `τ ≈ κ h Δs / 4`, sliding the point `ρ τ` along the contour and shortening a
//! 52 × 32 mm frame's circumference by 4-5 µm at a 1.3 mm offset (a 1 mm ball in a 100°
//! groove). A path that goes all the way round takes its normals from its smooth instead
//! (`r(θ)` of [`NORMAL_HARMONICS`] harmonics, [`super::smooth`]), `N ∝ r e_r - r' e_θ`:
//! continuous through a corner, its noise averaged over the turn (the C error 0.3 µm).
//!
//! **The groove.** A frame's rim, and a grooved ring gauge, hold the lens's bevel in a
//! V-groove of included angle `γ`. The ball touches both flanks, not the bottom: in the
//! groove's cross-section each flank is a line through the bottom at `γ/2` from the
//! groove's axis, and a ball of radius `ρ` on that axis touches it when its centre is at
//! `w` from the bottom with `w sin(γ/2) = ρ`. So the centre follows the groove's bottom
//! offset by
//!
//! ```text
//! o = ρ / sin(γ/2)            (γ = π: a plain bore, o = ρ)
//! ```
//!
//! ([`contact_offset`]), and the bottom, where the bevel's apex sits and what an edger
//! needs, is the path moved back by `o`. An angle known to `u_γ` moves it by
//! `∂o/∂γ u_γ = -ρ cos(γ/2) / (2 sin²(γ/2)) u_γ` ([`contact_offset_per_groove_angle`]):
//! 3.7 µm a degree for a 0.5 mm ball in a 110° groove.

use nalgebra::Vector2;
use std::f64::consts::TAU;

use super::correct::PolarContour;
use super::smooth::Smooth;

/// How far the centre of a ball of radius `tip_radius` sits from the bottom of a
/// V-groove of included angle `groove_angle` (rad) when it touches both flanks:
/// `ρ / sin(γ/2)` (module docs). `γ = π` is a plain bore: `ρ`.
pub fn contact_offset(tip_radius: f64, groove_angle: f64) -> f64 {
    tip_radius * groove_factor(groove_angle)
}

/// `1 / sin(γ/2)`: the contact offset per unit of tip radius ([`contact_offset`]).
pub fn groove_factor(groove_angle: f64) -> f64 {
    if groove_angle == PLAIN_BORE { 1.0 } else { 1.0 / (0.5 * groove_angle).sin() }
}

/// `∂o/∂γ = -ρ cos(γ/2) / (2 sin²(γ/2))`: how the contact offset moves with the groove
/// angle (module docs).
pub fn contact_offset_per_groove_angle(tip_radius: f64, groove_angle: f64) -> f64 {
    let (s, c) = (0.5 * groove_angle).sin_cos();
    -tip_radius * c / (2.0 * s * s)
}

/// The V-groove of what a tip traces from inside (a frame's rim, a ring gauge): its
/// included angle and that angle's standard uncertainty, rad. The default is a plain
/// bore, known exactly.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Groove {
    /// Included angle `γ`, rad; [`PLAIN_BORE`] (π) for none.
    pub angle: f64,
    /// Standard uncertainty of `angle`, rad (the angle the cell assumes for frames whose
    /// groove it does not measure).
    pub uncertainty: f64,
}

impl Default for Groove {
    fn default() -> Self {
        Groove { angle: PLAIN_BORE, uncertainty: 0.0 }
    }
}

impl Groove {
    /// A groove of included angle `angle` (rad), known to `uncertainty` (rad).
    pub const fn new(angle: f64, uncertainty: f64) -> Self {
        Groove { angle, uncertainty }
    }

    /// `1 / sin(γ/2)` ([`groove_factor`]).
    pub fn factor(&self) -> f64 {
        groove_factor(self.angle)
    }
}

/// The included angle of a plain bore: no groove, the ball touches the wall.
pub const PLAIN_BORE: f64 = std::f64::consts::PI;

/// Is `groove_angle` an included angle a groove can have, `0 < γ ≤ π` (rad)?
pub fn valid_groove_angle(groove_angle: f64) -> bool {
    groove_angle > 0.0 && groove_angle <= PLAIN_BORE
}

/// Samples either side of a point whose chord gives its normal.
pub const NORMAL_SPAN: usize = 3;

/// Which side of the contour the tip traces from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Traced {
    /// From outside: a calibration plate, a lens, an unknown target.
    Outside,
    /// From inside: a frame's groove, a ring gauge.
    Inside,
}

impl Traced {
    /// `s` of the module docs.
    fn sign(self) -> f64 {
        match self {
            Traced::Outside => 1.0,
            Traced::Inside => -1.0,
        }
    }
}

/// The outward unit normal of the path at point `i` (module docs), from the chord
/// between its neighbours `span` samples away, taken round the end when `closed`.
pub fn path_normal(path: &[Vector2<f64>], i: usize, span: usize, closed: bool) -> Option<Vector2<f64>> {
    let n = path.len();
    if n < 2 {
        return None;
    }
    let (a, b) = if closed {
        let h = span.min((n - 1) / 2).max(1);
        ((i + n - h) % n, (i + h) % n)
    } else {
        (i.saturating_sub(span), (i + span).min(n - 1))
    };
    let t = path[b] - path[a];
    Vector2::new(t.y, -t.x).try_normalize(0.0)
}

/// Harmonics of the smooth whose normals a closed path takes (module docs).
pub const NORMAL_HARMONICS: usize = 80;

/// The path's smooth, `r(θ)` of [`NORMAL_HARMONICS`] harmonics fitted to its radii
/// resampled at as many equal angles as it has points: for a path that goes round the
/// axis with at least 64 points, no gap wider than a tenth of a turn.
fn smooth_of(path: &[Vector2<f64>]) -> Option<Smooth> {
    if path.len() < 64 {
        return None;
    }
    let mut polar = PolarContour::with_capacity(path.len());
    path.iter().for_each(|p| polar.push(*p));
    Smooth::fit(&polar.resample(path.len(), TAU / 10.0)?, NORMAL_HARMONICS)
}

/// The smooth's outward unit normal at the angle of `p`: `(r e_r - r' e_θ)/|·|`.
fn smooth_normal(smooth: &Smooth, p: Vector2<f64>) -> Option<Vector2<f64>> {
    let theta = p.y.atan2(p.x);
    let (r, rp) = smooth.at(theta);
    let (sin, cos) = theta.sin_cos();
    (Vector2::new(cos, sin) * r - Vector2::new(-sin, cos) * rp).try_normalize(0.0)
}

/// Move each point of the tip centre's path (a corrected scan, in sample order) to the
/// surface the tip of radius `tip_radius` touched (module docs). `closed`: the scan
/// goes all the way round, so the first and last samples are neighbours. A point whose
/// normal cannot be found (coincident neighbours) stays.
pub fn touched_surface(path: &mut [Vector2<f64>], tip_radius: f64, traced: Traced, closed: bool) {
    if tip_radius == 0.0 || path.len() < 2 {
        return;
    }
    let shift = traced.sign() * tip_radius;
    let smooth = if closed { smooth_of(path) } else { None };
    let normals: Vec<Option<Vector2<f64>>> = (0..path.len())
        .map(|i| match &smooth {
            Some(smooth) => smooth_normal(smooth, path[i]),
            None => path_normal(path, i, NORMAL_SPAN, closed),
        })
        .collect();
    for (p, n) in path.iter_mut().zip(normals) {
        if let Some(n) = n {
            *p -= n * shift;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::TAU;

    fn circle(r: f64, n: usize) -> Vec<Vector2<f64>> {
        (0..n)
            .map(|k| Vector2::new(r * (TAU * k as f64 / n as f64).cos(), r * (TAU * k as f64 / n as f64).sin()))
            .collect()
    }

    #[test]
    fn a_circle_traced_from_outside_shrinks_and_from_inside_grows_by_the_tip() {
        let mut out = circle(0.020, 400);
        touched_surface(&mut out, 0.0005, Traced::Outside, true);
        assert!(out.iter().all(|p| (p.norm() - 0.0195).abs() < 1e-12));
        let mut inside = circle(0.020, 400);
        touched_surface(&mut inside, 0.0005, Traced::Inside, true);
        assert!(inside.iter().all(|p| (p.norm() - 0.0205).abs() < 1e-12));
    }

    #[test]
    fn an_open_arc_uses_one_sided_chords_at_its_ends() {
        let mut arc = circle(0.020, 400)[..100].to_vec();
        touched_surface(&mut arc, 0.0005, Traced::Outside, false);
        // One-sided chords tilt the normal by half the chord's angle at the very ends.
        assert!(arc.iter().all(|p| (p.norm() - 0.0195).abs() < 1e-6), "{:?}", arc[0].norm());
    }

    #[test]
    fn a_ball_in_a_groove_sits_off_its_bottom_by_rho_over_sin_half_the_angle() {
        // The ball touches both flanks: solve `w sin(γ/2) = ρ` by bisection on the
        // distance from (w, 0) to the flank through the origin at γ/2 from the axis.
        let (rho, gamma) = (0.0005, 116f64.to_radians());
        let flank = Vector2::new((0.5 * gamma).cos(), (0.5 * gamma).sin());
        let distance = |w: f64| (Vector2::new(w, 0.0) - flank * w * flank.x).norm();
        let (mut lo, mut hi) = (0.0, 0.01);
        for _ in 0..200 {
            let mid = 0.5 * (lo + hi);
            if distance(mid) < rho { lo = mid } else { hi = mid }
        }
        assert!((contact_offset(rho, gamma) - lo).abs() < 1e-15, "{} vs {lo}", contact_offset(rho, gamma));
        assert_eq!(contact_offset(rho, PLAIN_BORE), rho);
        let h = 1e-6;
        let numeric = (contact_offset(rho, gamma + h) - contact_offset(rho, gamma - h)) / (2.0 * h);
        assert!((contact_offset_per_groove_angle(rho, gamma) - numeric).abs() < 1e-9);
        // 3.7 µm a degree for a 0.5 mm ball in a 110° groove (module docs).
        let per_degree = contact_offset_per_groove_angle(rho, 110f64.to_radians()).abs() * 1f64.to_radians();
        assert!((per_degree - 3.7e-6).abs() < 0.05e-6, "{per_degree}");
        assert!(valid_groove_angle(PLAIN_BORE) && valid_groove_angle(1.9));
        assert!(!valid_groove_angle(0.0) && !valid_groove_angle(3.2) && !valid_groove_angle(f64::NAN));
    }

    #[test]
    fn no_tip_moves_nothing() {
        let mut c = circle(0.02, 10);
        let before = c.clone();
        touched_surface(&mut c, 0.0, Traced::Inside, true);
        assert_eq!(c, before);
    }
}
