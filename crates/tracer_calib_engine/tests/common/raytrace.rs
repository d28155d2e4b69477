//! A tracer simulated from its physics, written apart from the engine: no function of
//! `tracer_calib_engine` computes a length here (the engine's own simulator,
//! `engine::simulate`, shares the engine's geometry and shapes; this one shares nothing
//! but the convention of docs/model.md and the `Scan` it hands over).
//!
//! A turntable turns the rail to `a_k = alpha0 + φ_k + ε(φ_k)`, `φ_k = 2πk/N`, the angle
//! encoder's error `ε(φ) = Σ c_h cos hφ + s_h sin hφ`; the rail is the line `d v + t u`
//! (`u = (cos a, sin a)`, `v = (-sin a, cos a)`); a ball of radius `ρ` on it is pushed onto
//! the shape, inward from outside (a plate, a lens) or outward from inside (a ring gauge, a
//! frame's bore), and stops where its centre is `ρ` from the surface: the far root of
//! `sdf(d v + t u) = ±ρ` along the rail, found by bisection on the shape's signed distance
//! function. The encoder reads `(t + dL)/k` plus noise that is AR(1) along the trace
//! (marginal `σ`, lag-1 `φ`), rounded to whole counts when a count's length is given.
//!
//! A height channel ([`HeightChannel`], [`Tracer::trace_3d`]) reads the ball's height along
//! the axis. The ball sits at the height of the groove's bottom it touches (the groove's
//! bisector horizontal), the shape's nearest point to the ball's centre, where the
//! artefact's surface (a plane, a frame's sphere) gives the height in the holder; the
//! holder is tilted against the axis by `τ_x`, `τ_y`, so the reading is
//! `z_0 + x tan τ_x + y tan τ_y + surface(bottom)` at the ball's centre `(x, y)`, plus
//! white noise, rounded to whole counts when a count's length is given.

use nalgebra::Vector2;
use rand::Rng;
use rand_distr::{Distribution, StandardNormal};
use tracer_calib_engine::scan::Scan;

/// A closed convex shape by its signed distance (negative inside).
pub trait Sdf {
    fn sdf(&self, p: Vector2<f64>) -> f64;
}

/// A rectangle `2 hw × 2 hh` with corners rounded to `r`, centred at `c`, turned by `turn`.
#[derive(Debug, Clone, Copy)]
pub struct RoundedBox {
    pub c: Vector2<f64>,
    pub hw: f64,
    pub hh: f64,
    pub r: f64,
    pub turn: f64,
}

impl Sdf for RoundedBox {
    fn sdf(&self, p: Vector2<f64>) -> f64 {
        let (s, c) = (-self.turn).sin_cos();
        let d = p - self.c;
        let local = Vector2::new(c * d.x - s * d.y, s * d.x + c * d.y);
        let q = Vector2::new(local.x.abs() - (self.hw - self.r), local.y.abs() - (self.hh - self.r));
        let outside = Vector2::new(q.x.max(0.0), q.y.max(0.0)).norm();
        outside + q.x.max(q.y).min(0.0) - self.r
    }
}

impl RoundedBox {
    /// Circumference, box width, box height and FED (twice the farthest point from the
    /// box centre) of the unturned shape.
    pub fn figures(&self) -> [f64; 4] {
        let (a, b, r) = (self.hw - self.r, self.hh - self.r, self.r);
        [4.0 * (a + b) + std::f64::consts::TAU * r, 2.0 * self.hw, 2.0 * self.hh, 2.0 * ((a * a + b * b).sqrt() + r)]
    }
}

/// A circle of radius `r` about `c`.
#[derive(Debug, Clone, Copy)]
pub struct Circle {
    pub c: Vector2<f64>,
    pub r: f64,
}

impl Sdf for Circle {
    fn sdf(&self, p: Vector2<f64>) -> f64 {
        (p - self.c).norm() - self.r
    }
}

/// The tracer: its mounting, its angle encoder's error, its stylus and its noise.
#[derive(Debug, Clone)]
pub struct Tracer {
    pub alpha0: f64,
    pub d: f64,
    pub dl: f64,
    pub k: f64,
    /// `(h, c_h, s_h)`, radians.
    pub angle: Vec<(u32, f64, f64)>,
    /// The ball's radius.
    pub ball: f64,
    pub sigma: f64,
    pub lag1: f64,
    /// A count's length; 0: not rounded.
    pub count: f64,
    pub steps: u32,
}

impl Tracer {
    /// The tracer of docs/model.md's truth (alpha0 2°, d 5 mm, dL 2 mm, exact scale and
    /// angle, white noise), 400 steps a turn, with a ball of radius `ball`, noise `sigma`
    /// and counts of `count` (0: not rounded).
    #[allow(dead_code)] // not every test takes it
    pub fn typical(ball: f64, sigma: f64, count: f64) -> Tracer {
        Tracer {
            alpha0: 2f64.to_radians(),
            d: 0.005,
            dl: 0.002,
            k: 1.0,
            angle: Vec::new(),
            ball,
            sigma,
            lag1: 0.0,
            count,
            steps: 400,
        }
    }

    fn rail(&self, k: u32) -> (Vector2<f64>, Vector2<f64>) {
        let phi = std::f64::consts::TAU * f64::from(k) / f64::from(self.steps);
        let eps: f64 =
            self.angle.iter().map(|&(h, c, s)| c * (f64::from(h) * phi).cos() + s * (f64::from(h) * phi).sin()).sum();
        let a = self.alpha0 + phi + eps;
        let u = Vector2::new(a.cos(), a.sin());
        (u, Vector2::new(-u.y, u.x))
    }

    /// Where the ball's centre stops on rail `k`: the far root of `sdf = side ρ`, or in a
    /// groove of included angle `groove` (rad, π a plain bore) of the centre's distance
    /// from a flank `= ρ` (module docs).
    fn stop(&self, shape: &impl Sdf, k: u32, side: f64, groove: f64) -> f64 {
        let (u, v) = self.rail(k);
        let flank = Vector2::new((0.5 * groove).cos(), (0.5 * groove).sin());
        let from_flank = |depth: f64| {
            let p = Vector2::new(depth, 0.0);
            (p - flank * p.dot(&flank)).norm().copysign(depth)
        };
        let f = |t: f64| {
            let sdf = shape.sdf(v * self.d + u * t);
            if side < 0.0 { self.ball - from_flank(-sdf) } else { sdf - self.ball }
        };
        // The rail passes near the axis, inside every shape here: `t = 0` is inside the
        // contour the ball's centre follows, `t = 1 m` far outside.
        let (mut lo, mut hi) = (0.0, 1.0);
        assert!(f(lo) < 0.0 && f(hi) > 0.0, "rail {k} does not cross the shape");
        for _ in 0..80 {
            let mid = 0.5 * (lo + hi);
            if f(mid) < 0.0 { lo = mid } else { hi = mid }
        }
        0.5 * (lo + hi)
    }

    /// One revolution over `shape`, traced from outside (`inside = false`) or inside.
    #[allow(dead_code)] // not every test traces without heights
    pub fn trace(&self, shape: &impl Sdf, inside: bool, rng: &mut impl Rng) -> Scan {
        self.trace_groove(shape, inside, std::f64::consts::PI, rng)
    }

    /// [`Self::trace`], from inside in a V-groove of included angle `groove` (rad).
    #[allow(dead_code)] // not every test traces without heights
    pub fn trace_groove(&self, shape: &impl Sdf, inside: bool, groove: f64, rng: &mut impl Rng) -> Scan {
        self.trace_centres(shape, inside, groove, rng).0
    }

    /// [`Self::trace_groove`] with the height channel `heights` over an artefact whose
    /// height in the holder at `p` is `surface(p)` (module docs): the scan and each
    /// sample's height reading, and where the ball's centre was.
    #[allow(dead_code)] // tests/height.rs's alone
    pub fn trace_3d(
        &self,
        shape: &impl Sdf,
        inside: bool,
        groove: f64,
        surface: impl Fn(Vector2<f64>) -> f64,
        heights: &HeightChannel,
        rng: &mut impl Rng,
    ) -> (Scan, Vec<f64>, Vec<Vector2<f64>>) {
        let (scan, centres) = self.trace_centres(shape, inside, groove, rng);
        let slopes = Vector2::new(heights.tilt[0].tan(), heights.tilt[1].tan());
        let h = 1e-7;
        let read = centres
            .iter()
            .map(|&c| {
                // The groove's bottom: the shape's nearest point, along the distance's gradient.
                let grad = Vector2::new(
                    shape.sdf(c + Vector2::new(h, 0.0)) - shape.sdf(c - Vector2::new(h, 0.0)),
                    shape.sdf(c + Vector2::new(0.0, h)) - shape.sdf(c - Vector2::new(0.0, h)),
                )
                .normalize();
                let bottom = c - grad * shape.sdf(c);
                let z: f64 = StandardNormal.sample(rng);
                let read = heights.zero + c.dot(&slopes) + surface(bottom) + heights.sigma * z;
                if heights.count > 0.0 { (read / heights.count).round() * heights.count } else { read }
            })
            .collect();
        (scan, read, centres)
    }

    /// One revolution and where the ball's centre stopped on each rail.
    fn trace_centres(
        &self,
        shape: &impl Sdf,
        inside: bool,
        groove: f64,
        rng: &mut impl Rng,
    ) -> (Scan, Vec<Vector2<f64>>) {
        let side = if inside { -1.0 } else { 1.0 };
        let innovation = (1.0 - self.lag1 * self.lag1).sqrt();
        let mut e: f64 = StandardNormal.sample(rng);
        let steps: Vec<u32> = (0..self.steps).collect();
        let mut centres = Vec::with_capacity(steps.len());
        let rho: Vec<f64> = steps
            .iter()
            .map(|&k| {
                if k > 0 {
                    let z: f64 = StandardNormal.sample(rng);
                    e = self.lag1 * e + innovation * z;
                }
                let t = self.stop(shape, k, side, groove);
                let (u, v) = self.rail(k);
                centres.push(v * self.d + u * t);
                let read = (t + self.dl) / self.k + self.sigma * e;
                if self.count > 0.0 { (read / self.count).round() * self.count } else { read }
            })
            .collect();
        (Scan::new(self.steps, &steps, &rho).expect("a whole revolution"), centres)
    }
}

/// A height encoder and the holder it reads against (module docs).
#[allow(dead_code)] // tests/height.rs's alone
#[derive(Debug, Clone, Copy)]
pub struct HeightChannel {
    /// The holder's plane's height where the axis meets it, `z_0`.
    pub zero: f64,
    /// `τ_x`, `τ_y`, rad.
    pub tilt: [f64; 2],
    pub sigma: f64,
    /// A count's length; 0: not rounded.
    pub count: f64,
}
