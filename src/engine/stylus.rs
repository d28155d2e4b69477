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

use nalgebra::Vector2;

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

/// Move each point of the tip centre's path (a corrected scan, in sample order) to the
/// surface the tip of radius `tip_radius` touched (module docs). `closed`: the scan
/// goes all the way round, so the first and last samples are neighbours. A point whose
/// normal cannot be found (coincident neighbours) stays.
pub fn touched_surface(path: &mut [Vector2<f64>], tip_radius: f64, traced: Traced, closed: bool) {
    if tip_radius == 0.0 || path.len() < 2 {
        return;
    }
    let shift = traced.sign() * tip_radius;
    let normals: Vec<Option<Vector2<f64>>> =
        (0..path.len()).map(|i| path_normal(path, i, NORMAL_SPAN, closed)).collect();
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
    fn no_tip_moves_nothing() {
        let mut c = circle(0.02, 10);
        let before = c.clone();
        touched_surface(&mut c, 0.0, Traced::Inside, true);
        assert_eq!(c, before);
    }
}
