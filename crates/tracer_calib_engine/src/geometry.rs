//! Tracer geometry: where the probe really is, given what the encoders say.
//!
//! The rail turns counter-clockwise about the rotation axis O, the origin of the output
//! frame. At a sample taken at angle step `k` of `N` steps per revolution the rail angle
//! is
//!
//! ```text
//! a = alpha0 + 2π k / N                                            (rail angle)
//! ```
//!
//! With `u = (cos a, sin a)` the rail direction and `v = (-sin a, cos a)` its left
//! normal, a rail mounted `d` off the axis is the line `{ t u + d v }`. The encoder
//! reads `rho = counts × meters_per_count`; its scale may be off by a factor `k` (a wrong
//! `meters_per_count`, a rail grown with heat) and its zero by `dL` along the rail, so
//! `k rho = t + dL` and the probe touched
//!
//! ```text
//! P = (k rho - dL) u + d v                                         (probe point)
//! |P| = sqrt(d² + (k rho - dL)²),   angle(P) = a + atan2(d, k rho - dL)
//! ```
//!
//! The seed paper's eq. 1 writes the same with the opposite sign of `d` and `k = 1`; its
//! eq. 3 (the one the calibration rests on) matches this convention. With
//! `alpha0 = d = dL = 0`, `k = 1` this is the naive reading `(rho cos a, rho sin a)`.

use nalgebra::Vector2;
use std::f64::consts::{FRAC_PI_2, FRAC_PI_4, TAU};

/// The mounting errors of a tracer, and its encoder scale: what the calibration finds.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Mounting {
    /// Rail angle at step 0, radians.
    pub alpha0: f64,
    /// Signed perpendicular distance `d` of the rail line from the axis, metres
    /// (positive: the rail lies to the left of the axis, seen along the rail).
    pub offset: f64,
    /// Encoder zero offset `dL` along the rail, metres.
    pub delta_l: f64,
    /// Encoder scale `k`: the true length along the rail is `k × counts × meters_per_count`.
    /// 1 unless fitted (model `full_scale`).
    #[serde(default = "unit_scale")]
    pub scale: f64,
}

fn unit_scale() -> f64 {
    1.0
}

impl Default for Mounting {
    fn default() -> Self {
        Mounting::IDEAL
    }
}

impl Mounting {
    /// No mounting error and a true encoder scale: the naive reading.
    pub const IDEAL: Mounting = Mounting { alpha0: 0.0, offset: 0.0, delta_l: 0.0, scale: 1.0 };

    /// The three mounting errors, with a true encoder scale (`k = 1`).
    pub const fn new(alpha0: f64, offset: f64, delta_l: f64) -> Self {
        Mounting { alpha0, offset, delta_l, scale: 1.0 }
    }

    /// The same mounting with encoder scale `k`.
    pub const fn with_scale(self, scale: f64) -> Self {
        Mounting { scale, ..self }
    }

    /// The length along the rail from the foot of the axis' perpendicular to the probe,
    /// `t = k rho - dL`, for an encoder length `rho`.
    #[inline]
    pub fn rail_length(&self, rho: f64) -> f64 {
        self.scale * rho - self.delta_l
    }
}

/// Angle of step `step` of `steps_per_rev`, without `alpha0`: `2π k / N`.
#[inline]
pub fn step_angle(step: u32, steps_per_rev: u32) -> f64 {
    TAU * f64::from(step) / f64::from(steps_per_rev)
}

/// Rail angle `a = alpha0 + 2π k / N`.
#[inline]
pub fn rail_angle(alpha0: f64, step: u32, steps_per_rev: u32) -> f64 {
    alpha0 + step_angle(step, steps_per_rev)
}

/// Rail direction `u` and its left normal `v` at rail angle `a`.
#[inline]
pub fn rail_frame(a: f64) -> (Vector2<f64>, Vector2<f64>) {
    let (s, c) = a.sin_cos();
    (Vector2::new(c, s), Vector2::new(-s, c))
}

/// The point the probe touched: `P = (k rho - dL) u + d v`.
#[inline]
pub fn probe_point(rho: f64, a: f64, m: &Mounting) -> Vector2<f64> {
    let (u, v) = rail_frame(a);
    probe_point_in_frame(rho, u, v, m)
}

/// `P = (k rho - dL) u + d v` with the rail frame already known.
#[inline]
pub fn probe_point_in_frame(rho: f64, u: Vector2<f64>, v: Vector2<f64>, m: &Mounting) -> Vector2<f64> {
    u * m.rail_length(rho) + v * m.offset
}

/// The encoder length a probe at `P` would read: the inverse of [`probe_point`]
/// along the rail, `rho = (P·u + dL) / k` (the component `P·v` must equal `d`).
#[inline]
pub fn encoder_length(p: Vector2<f64>, a: f64, m: &Mounting) -> f64 {
    let (u, _) = rail_frame(a);
    (p.dot(&u) + m.delta_l) / m.scale
}

/// `(cos, sin)` of `phi + alpha` from `(cos phi, sin phi)`: a rotation, four products,
/// no trigonometric call. Used to evaluate a whole revolution at a new `alpha0` from a
/// table of the step angles.
#[inline]
pub fn rotate(cs_phi: (f64, f64), cs_alpha: (f64, f64)) -> (f64, f64) {
    let (cp, sp) = cs_phi;
    let (ca, sa) = cs_alpha;
    (ca * cp - sa * sp, sa * cp + ca * sp)
}

/// Map an angle into `(-π/4, π/4]`, returning the mapped angle and how many quarter
/// turns `q` were added (`mapped = angle + q π/2`).
///
/// A square plate is symmetric under quarter turns, so `alpha0` is only defined modulo
/// `π/2` (the plate's rotation and `alpha0` are one parameter); we report it here.
pub fn wrap_quarter_turn(angle: f64) -> (f64, i64) {
    let q = -((angle - FRAC_PI_4) / FRAC_PI_2).ceil();
    let mut mapped = angle + q * FRAC_PI_2;
    // Guard the half-open boundary against rounding.
    let mut q = q as i64;
    if mapped <= -FRAC_PI_4 {
        mapped += FRAC_PI_2;
        q += 1;
    } else if mapped > FRAC_PI_4 {
        mapped -= FRAC_PI_2;
        q -= 1;
    }
    (mapped, q)
}

/// Rotate a vector by `q` quarter turns counter-clockwise (exact, no rounding).
pub fn rotate_quarter_turns(p: Vector2<f64>, q: i64) -> Vector2<f64> {
    match q.rem_euclid(4) {
        0 => p,
        1 => Vector2::new(-p.y, p.x),
        2 => -p,
        _ => Vector2::new(p.y, -p.x),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    #[test]
    fn ideal_mounting_is_the_naive_reading() {
        let a = 0.7;
        let p = probe_point(0.02, a, &Mounting::IDEAL);
        assert_relative_eq!(p, Vector2::new(0.02 * a.cos(), 0.02 * a.sin()), epsilon = 1e-15);
    }

    #[test]
    fn probe_point_polar_form() {
        let m = Mounting::new(0.1, 0.005, 0.002);
        let (rho, a) = (0.03, 1.3);
        let p = probe_point(rho, a, &m);
        assert_relative_eq!(p.norm(), (0.005f64.powi(2) + 0.028f64.powi(2)).sqrt(), epsilon = 1e-15);
        assert_relative_eq!(p.y.atan2(p.x), a + 0.005f64.atan2(0.028), epsilon = 1e-12);
        assert_relative_eq!(encoder_length(p, a, &m), rho, epsilon = 1e-15);
    }

    #[test]
    fn encoder_scale_stretches_the_length_along_the_rail() {
        let m = Mounting::new(0.1, 0.005, 0.002).with_scale(1.0025);
        let (rho, a) = (0.03, 1.3);
        let p = probe_point(rho, a, &m);
        let t = 1.0025 * 0.03 - 0.002;
        assert_relative_eq!(p.norm(), (0.005f64.powi(2) + t * t).sqrt(), epsilon = 1e-15);
        assert_relative_eq!(encoder_length(p, a, &m), rho, epsilon = 1e-15);
    }

    #[test]
    fn rotation_table_matches_trig() {
        let (phi, alpha) = (2.1_f64, -0.4_f64);
        let (c, s) = rotate((phi.cos(), phi.sin()), (alpha.cos(), alpha.sin()));
        assert_relative_eq!(c, (phi + alpha).cos(), epsilon = 1e-15);
        assert_relative_eq!(s, (phi + alpha).sin(), epsilon = 1e-15);
    }

    #[test]
    fn quarter_turn_wrap_is_half_open() {
        for &(x, want) in &[
            (0.0, 0.0),
            (FRAC_PI_4, FRAC_PI_4),
            (-FRAC_PI_4, FRAC_PI_4),
            (1.0, 1.0 - FRAC_PI_2),
            (-3.0, -3.0 + FRAC_PI_2 * 2.0),
            (7.0, 7.0 - 4.0 * FRAC_PI_2),
        ] {
            let (m, q) = wrap_quarter_turn(x);
            assert_relative_eq!(m, want, epsilon = 1e-12);
            assert_relative_eq!(m, x + q as f64 * FRAC_PI_2, epsilon = 1e-12);
            assert!(m > -FRAC_PI_4 && m <= FRAC_PI_4 + 1e-15);
        }
        assert_eq!(rotate_quarter_turns(Vector2::new(1.0, 2.0), 1), Vector2::new(-2.0, 1.0));
        assert_eq!(rotate_quarter_turns(Vector2::new(1.0, 2.0), -1), Vector2::new(2.0, -1.0));
    }
}
