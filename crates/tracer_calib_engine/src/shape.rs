//! Convex contours the probe can touch, and where a rail ray leaves them.
//!
//! The probe runs along the rail ray `p0 + t u` (`p0 = d v`, see [`super::geometry`])
//! from inside the contour outwards and stops on its edge: the **exit** (far)
//! intersection of the ray with the convex contour. A shape answers that distance `t`
//! and the outward unit normal `N` there; `N` is all the calibration Jacobian needs
//! (see [`super::model::full`]).
//!
//! Shapes are given in the output frame: a centre and extents, axes parallel to the
//! frame's (the calibration plate) or rotated (lens outlines for the simulator).

use nalgebra::Vector2;

/// Where a ray leaves a contour.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Hit {
    /// Distance along the (unit) ray direction from the ray origin.
    pub t: f64,
    /// Outward unit normal of the contour at the exit point.
    pub normal: Vector2<f64>,
    /// Which part of the contour was hit (for shapes with distinct parts).
    pub part: Part,
}

/// The part of a contour a ray leaves through.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Part {
    /// A flat side with outward normal `±x` (`sign` is +1 or -1).
    SideX { sign: i8 },
    /// A flat side with outward normal `±y`.
    SideY { sign: i8 },
    /// A rounded corner, in the quadrant `(sx, sy)`.
    Corner { sx: i8, sy: i8 },
    /// A smooth curve (no distinct parts).
    Curve,
}

/// A closed convex contour.
pub trait Shape {
    /// The exit of the ray `origin + t dir` (`dir` a unit vector), or `None` if the
    /// line misses the contour or leaves it behind the origin.
    fn exit(&self, origin: Vector2<f64>, dir: Vector2<f64>) -> Option<Hit>;
}

/// A rectangle with rounded corners, sides parallel to the frame's axes: the
/// calibration plate (a square, `half_w == half_h`) and a common frame shape.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RoundedRect {
    pub center: Vector2<f64>,
    /// Half the width (along x), metres.
    pub half_w: f64,
    /// Half the height (along y), metres.
    pub half_h: f64,
    /// Corner radius, `0 <= radius <= min(half_w, half_h)`.
    pub radius: f64,
}

impl RoundedRect {
    /// The calibration plate: a square of side `side` with corners of radius
    /// `corner_radius`, centred at `center`.
    pub fn plate(side: f64, corner_radius: f64, center: Vector2<f64>) -> Self {
        RoundedRect { center, half_w: side / 2.0, half_h: side / 2.0, radius: corner_radius }
    }

    /// The exit of the ray `p + t u`, with `p` relative to the centre.
    ///
    /// The ray first leaves the bounding box through side x (`t_x <= t_y`) or side y.
    /// If that point lies on the flat part of the side (`|y| <= half_h - r`), it is the
    /// exit. Otherwise the ray leaves through the corner arc of that quadrant: the
    /// far root of `|p + t u - k|² = r²` with `k` the arc's centre, i.e.
    /// `t = -w·u + sqrt((w·u)² - |w|² + r²)`, `w = p - k`. (Between the shape and its
    /// box lie four disjoint corner pieces, so box exit and shape exit share a corner.)
    #[inline]
    pub fn exit_local(&self, p: Vector2<f64>, u: Vector2<f64>) -> Option<Hit> {
        let tx = axis_exit(p.x, u.x, self.half_w);
        let ty = axis_exit(p.y, u.y, self.half_h);
        let (t_box, on_x) = if tx <= ty { (tx, true) } else { (ty, false) };
        if !t_box.is_finite() {
            return None;
        }
        let q = p + u * t_box;
        let (inner_w, inner_h) = (self.half_w - self.radius, self.half_h - self.radius);
        if on_x {
            if q.y.abs() <= inner_h {
                let s = sign(u.x);
                return Some(Hit { t: t_box, normal: Vector2::new(f64::from(s), 0.0), part: Part::SideX { sign: s } });
            }
        } else if q.x.abs() <= inner_w {
            let s = sign(u.y);
            return Some(Hit { t: t_box, normal: Vector2::new(0.0, f64::from(s)), part: Part::SideY { sign: s } });
        }
        // Corner arc of the quadrant the box exit lies in.
        let (sx, sy) = (sign(q.x), sign(q.y));
        let k = Vector2::new(f64::from(sx) * inner_w, f64::from(sy) * inner_h);
        let w = p - k;
        let b = w.dot(&u);
        let disc = b * b - w.norm_squared() + self.radius * self.radius;
        if disc < 0.0 || self.radius <= 0.0 {
            // The line passes the corner outside its arc: only possible from an origin
            // outside the plate, or (r = 0) exactly through a sharp corner.
            if self.radius <= 0.0 {
                return Some(Hit {
                    t: t_box,
                    normal: if on_x { Vector2::new(f64::from(sx), 0.0) } else { Vector2::new(0.0, f64::from(sy)) },
                    part: Part::Corner { sx, sy },
                });
            }
            return None;
        }
        let t = -b + disc.sqrt();
        let normal = (w + u * t) / self.radius;
        Some(Hit { t, normal, part: Part::Corner { sx, sy } })
    }
}

impl RoundedRect {
    /// Its exact size figures `[circumference, A, B, FED]` ([`super::size`]): the box is
    /// the rectangle, the FED twice the distance from the centre to a corner's far point.
    pub fn exact_sizes(&self) -> [f64; 4] {
        let (w, h, r) = (2.0 * self.half_w, 2.0 * self.half_h, self.radius);
        let fed = 2.0 * ((self.half_w - r).hypot(self.half_h - r) + r);
        [2.0 * (w + h) - 8.0 * r + std::f64::consts::TAU * r, w, h, fed]
    }
}

impl Shape for RoundedRect {
    fn exit(&self, origin: Vector2<f64>, dir: Vector2<f64>) -> Option<Hit> {
        self.exit_local(origin - self.center, dir).filter(|h| h.t >= 0.0)
    }
}

/// Distance along a 1-D ray `p + t u` to the wall of `[-h, h]` it moves towards.
#[inline]
fn axis_exit(p: f64, u: f64, h: f64) -> f64 {
    if u > 0.0 {
        (h - p) / u
    } else if u < 0.0 {
        (-h - p) / u
    } else {
        f64::INFINITY
    }
}

#[inline]
fn sign(x: f64) -> i8 {
    if x < 0.0 { -1 } else { 1 }
}

/// An ellipse with semi-axes `a` (along its own x) and `b`, rotated by `angle`:
/// the usual lens outline in tests and the simulator.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Ellipse {
    pub center: Vector2<f64>,
    pub a: f64,
    pub b: f64,
    pub angle: f64,
}

impl Ellipse {
    /// Its size figures `[circumference, A, B, FED]` ([`super::size`]): the circumference
    /// by Ramanujan's second approximation (relative error about `3h⁵/2¹⁷`, `h` below:
    /// 1e-10 for a 50×30 mm ellipse), the box of the rotated ellipse and its long axis.
    pub fn exact_sizes(&self) -> [f64; 4] {
        let (a, b, phi) = (self.a, self.b, self.angle);
        let h = ((a - b) / (a + b)).powi(2);
        let circumference = std::f64::consts::PI * (a + b) * (1.0 + 3.0 * h / (10.0 + (4.0 - 3.0 * h).sqrt()));
        let width = 2.0 * (a * a * phi.cos().powi(2) + b * b * phi.sin().powi(2)).sqrt();
        let height = 2.0 * (a * a * phi.sin().powi(2) + b * b * phi.cos().powi(2)).sqrt();
        [circumference, width, height, 2.0 * a.max(b)]
    }
}

impl Shape for Ellipse {
    /// In the ellipse's own frame, `(x/a)² + (y/b)² = 1` along `p + t u` is a quadratic
    /// `A t² + 2 B t + C = 0`; the exit is its larger root.
    fn exit(&self, origin: Vector2<f64>, dir: Vector2<f64>) -> Option<Hit> {
        let (s, c) = self.angle.sin_cos();
        let to_local = |w: Vector2<f64>| Vector2::new(c * w.x + s * w.y, -s * w.x + c * w.y);
        let p = to_local(origin - self.center);
        let u = to_local(dir);
        let (ia2, ib2) = (1.0 / (self.a * self.a), 1.0 / (self.b * self.b));
        let qa = u.x * u.x * ia2 + u.y * u.y * ib2;
        let qb = p.x * u.x * ia2 + p.y * u.y * ib2;
        let qc = p.x * p.x * ia2 + p.y * p.y * ib2 - 1.0;
        let disc = qb * qb - qa * qc;
        if disc < 0.0 {
            return None;
        }
        let t = (-qb + disc.sqrt()) / qa;
        if t < 0.0 {
            return None;
        }
        let q = p + u * t;
        let n_local = Vector2::new(q.x * ia2, q.y * ib2).normalize();
        let normal = Vector2::new(c * n_local.x - s * n_local.y, s * n_local.x + c * n_local.y);
        Some(Hit { t, normal, part: Part::Curve })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;
    use std::f64::consts::TAU;

    fn plate() -> RoundedRect {
        RoundedRect::plate(0.045, 0.003, Vector2::new(0.0008, -0.0005))
    }

    /// The exit point lies on the contour, the normal is a unit vector, and the point
    /// is the far one: a little further along the ray is outside.
    #[test]
    fn exit_point_is_on_the_rounded_square() {
        let sq = plate();
        let origin = Vector2::new(0.001, 0.004);
        let (mut flats, mut corners) = (0, 0);
        for k in 0..3600 {
            let a = TAU * k as f64 / 3600.0;
            let u = Vector2::new(a.cos(), a.sin());
            let hit = sq.exit(origin, u).unwrap();
            let q = origin + u * hit.t - sq.center;
            // Signed distance of the rounded square at q.
            let inner = Vector2::new(sq.half_w - sq.radius, sq.half_h - sq.radius);
            let dq = Vector2::new(q.x.abs() - inner.x, q.y.abs() - inner.y);
            let outside = Vector2::new(dq.x.max(0.0), dq.y.max(0.0)).norm();
            let sdf = outside + dq.x.max(dq.y).min(0.0) - sq.radius;
            assert!(sdf.abs() < 1e-15, "k={k} sdf={sdf}");
            assert_relative_eq!(hit.normal.norm(), 1.0, epsilon = 1e-12);
            assert!(hit.normal.dot(&u) > 0.0);
            match hit.part {
                Part::Corner { .. } => corners += 1,
                _ => flats += 1,
            }
        }
        assert!(flats > 3000 && corners > 100, "{flats} {corners}");
    }

    #[test]
    fn flat_side_matches_paper_eq3() {
        // rho = l / cos a + d tan a + dL on the side x = l (here without dL).
        let sq = plate();
        let (d, a) = (0.005_f64, 0.2_f64);
        let u = Vector2::new(a.cos(), a.sin());
        let v = Vector2::new(-a.sin(), a.cos());
        let hit = sq.exit(v * d, u).unwrap();
        let l = 0.0225 + sq.center.x;
        assert_eq!(hit.part, Part::SideX { sign: 1 });
        assert_relative_eq!(hit.t, l / a.cos() + d * a.tan(), epsilon = 1e-15);
    }

    #[test]
    fn ellipse_exit_is_on_the_ellipse() {
        let e = Ellipse { center: Vector2::new(0.001, -0.002), a: 0.025, b: 0.015, angle: 0.3 };
        let origin = Vector2::new(0.0, 0.003);
        for k in 0..360 {
            let a = TAU * k as f64 / 360.0;
            let u = Vector2::new(a.cos(), a.sin());
            let hit = e.exit(origin, u).unwrap();
            let q = origin + u * hit.t - e.center;
            let (s, c) = e.angle.sin_cos();
            let (x, y) = (c * q.x + s * q.y, -s * q.x + c * q.y);
            assert_relative_eq!((x / e.a).powi(2) + (y / e.b).powi(2), 1.0, epsilon = 1e-12);
        }
    }
}
