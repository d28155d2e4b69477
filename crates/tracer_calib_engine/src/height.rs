//! The height channel: the turntable axis's tilt against the frame holder, and a frame's
//! third dimension (its curve and the groove's length in 3-D).
//!
//! A tracer with a height encoder reads, with every sample, the stylus's height `h` along
//! the turntable's axis. The ball sits in the groove with its centre at the groove
//! bottom's height (the groove's bisector is taken horizontal: a lens's edge is parallel
//! to the axis), so `h` is the groove bottom's height as the axis sees it.
//!
//! **The axis's tilt** ([`fit_axis_tilt`]). The frame holder's plane, which the flat
//! artefacts (the plate, a ring gauge) lie in, is tilted against the plane square to the
//! axis by two small angles `τ_x`, `τ_y`: a flat artefact's heights are
//!
//! ```text
//! h_i = z_a + x_i tan τ_x + y_i tan τ_y + ε_i
//! ```
//!
//! (`z_a` the artefact's own height, `(x_i, y_i)` where the sample's ball sat, corrected).
//! One common tilt and one height per artefact are linear least squares; their covariance
//! `σ̂² (AᵀA)⁻¹`, with `σ̂²` the residuals' variance, is the Cramér-Rao bound of white
//! Gaussian height noise. A point's height above the holder's plane (the first artefact's,
//! the plate's) is then `z = h - z_0 - x tan τ_x - y tan τ_y` ([`AxisTilt::height_above`]).
//! (The tilt foreshortens the contour in the plane by `1 - cos τ`: 1.5 ppm at 0.1°, left
//! out.)
//!
//! **The frame's curve** ([`Sphere`]). A frame's groove lies on a sphere (its base curve);
//! the sphere through the groove's points is fitted in the algebraic form
//!
//! ```text
//! 2z = κ (x² + y² + z²) + D x + E y + G,
//! ```
//!
//! linear in `κ, D, E, G` and well posed for a flat frame (`κ = 0`, a plane). Its
//! curvature is `1/R = |κ| / √(1 + (D² + E²)/4 - Gκ)`, and the frame curve, as the
//! standard's FCRV states it, `530 mm / R` dioptres ([`Sphere::frame_curve`]).
//!
//! **The 3-D length** ([`Frame3d`]). Along the groove, `θ ↦ (r cos θ, r sin θ, z(θ))` with
//! `r(θ)` the contour's smooth ([`super::smooth`]) and `z(θ)` the sphere at that point plus a
//! Fourier series of [`RESIDUAL_HARMONICS`] harmonics fitted to the heights' residuals
//! about the sphere (what is not spherical: a toric frame, a twist). The length is
//!
//! ```text
//! L₃ = ∮ √(r² + r'² + z'²) dθ,   z' = ∇S · (r' cos θ - r sin θ, r' sin θ + r cos θ) + z_res',
//! ```
//!
//! taken on the same grid as the circumference in the plane ([`super::size::Sizes`]), so
//! that a flat frame's `L₃` is its `C` to the last bit: the plane's circumference comes
//! from a finer smooth with its noise's lengthening taken off
//! ([`super::size::noise_lengthening`]), and `L₃` takes the same change, times `∂L₃/∂L₂`
//! (below), over its grid's own `∮ √(r² + r'²) dθ`.
//!
//! **Its uncertainty** ([`Frame3d::circumference_u95`]). Three independent parts, to first
//! order: the plane's (a radial change `δr` moves `L₃` by `∮ (r δr + r' δr')/s₃` where
//! `s₃ = √(r² + r'² + z'²)`; for the calibration's changes, which move the contour nearly
//! along itself in scale, that is `L₂`'s change times `∮ (r² + r'²)/s₃ / L₂`, applied to
//! the size module's `U95(C)`); the tilt's (`δL₃ = ∮ z' δz'/s₃`, `δz' = -δs · dp/dθ`, so a
//! gradient `g = -∮ z' (dp/dθ)/s₃ dθ` against the slopes' covariance); and the heights'
//! noise (each harmonic coefficient of `z` has variance `2σ_h²/N`, its response
//! `∮ z' k (-sin kθ, cos kθ)/s₃ dθ`). `σ_h` is the height residuals' scatter after the
//! sphere and the series, never below the height count's `q/√12`.

use super::size::Sizes;
use super::smooth::{GRID, grid_unit};
use nalgebra::{DMatrix, DVector, Matrix2, Matrix4, Vector2, Vector4};
use std::f64::consts::TAU;

/// Harmonics of the heights' residuals about the frame's sphere in `z(θ)`.
pub const RESIDUAL_HARMONICS: usize = 8;

/// `530 mm`: a sphere of radius `R` metres has the curve `FRAME_CURVE_METRES / R` dioptres
/// (the lens makers' index 1.53, as the standard's FCRV).
pub const FRAME_CURVE_METRES: f64 = 0.530;

/// The turntable axis's tilt against the frame holder's plane (module docs).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AxisTilt {
    /// The holder's plane's height where the axis meets it, `z_0`, metres.
    pub height_zero: f64,
    /// `τ_x`, `τ_y`, rad.
    pub angles: [f64; 2],
    /// Their covariance, row-major 2×2, rad².
    pub covariance: [f64; 4],
}

impl AxisTilt {
    /// No tilt, no offset: heights as read.
    pub const NONE: AxisTilt = AxisTilt { height_zero: 0.0, angles: [0.0; 2], covariance: [0.0; 4] };

    /// `tan τ_x`, `tan τ_y`: the plane's slopes.
    pub fn slopes(&self) -> Vector2<f64> {
        Vector2::new(self.angles[0].tan(), self.angles[1].tan())
    }

    /// The slopes' covariance, `J Σ_τ J` with `J = diag(1 + tan² τ)`.
    pub fn slope_covariance(&self) -> Matrix2<f64> {
        let j = Matrix2::from_diagonal(&self.slopes().map(|s| 1.0 + s * s));
        j * Matrix2::from_row_slice(&self.covariance) * j
    }

    /// The height above the holder's plane of a point at `p` read `h` along the axis:
    /// `h - z_0 - p · (tan τ_x, tan τ_y)`.
    pub fn height_above(&self, p: &Vector2<f64>, h: f64) -> f64 {
        h - self.height_zero - p.dot(&self.slopes())
    }
}

/// Why the tilt could not be fitted.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TiltError {
    /// Fewer heights than parameters and one for the noise.
    TooFew { heights: usize, needed: usize },
    /// The points do not span the plane (all on a line).
    Singular,
}

impl std::fmt::Display for TiltError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            TiltError::TooFew { heights, needed } => {
                write!(f, "{heights} heights on the flat artefacts; the axis's tilt needs at least {needed}")
            }
            TiltError::Singular => write!(f, "the flat artefacts' points lie on a line: no tilt can be fitted"),
        }
    }
}

impl std::error::Error for TiltError {}

/// The common tilt of flat artefacts each given as its points (where the ball sat) and
/// their heights, with a height of its own (module docs); `height_zero` is the first
/// artefact's.
pub fn fit_axis_tilt(artefacts: &[(&[Vector2<f64>], &[f64])]) -> Result<AxisTilt, TiltError> {
    let m = artefacts.len();
    let p = 2 + m;
    let n: usize = artefacts.iter().map(|(pts, h)| pts.len().min(h.len())).sum();
    if m == 0 || n <= p {
        return Err(TiltError::TooFew { heights: n, needed: p + 1 });
    }
    // The normal equations `AᵀA β = Aᵀh`, rows `(x, y, e_a)`.
    let mut ata = DMatrix::<f64>::zeros(p, p);
    let mut ath = DVector::<f64>::zeros(p);
    let mut row = DVector::<f64>::zeros(p);
    for (a, (points, heights)) in artefacts.iter().enumerate() {
        for (pt, h) in points.iter().zip(heights.iter()) {
            row.fill(0.0);
            row[0] = pt.x;
            row[1] = pt.y;
            row[2 + a] = 1.0;
            ata.ger(1.0, &row, &row, 1.0);
            ath.axpy(*h, &row, 1.0);
        }
    }
    let chol = ata.cholesky().ok_or(TiltError::Singular)?;
    let beta = chol.solve(&ath);
    let rss: f64 = artefacts
        .iter()
        .enumerate()
        .flat_map(|(a, (points, heights))| {
            let beta = &beta;
            points.iter().zip(heights.iter()).map(move |(pt, h)| h - beta[0] * pt.x - beta[1] * pt.y - beta[2 + a])
        })
        .map(|r| r * r)
        .sum();
    let sigma2 = rss / (n - p) as f64;
    let inv = chol.inverse();
    if !(beta.iter().all(|b| b.is_finite()) && sigma2.is_finite()) {
        return Err(TiltError::Singular);
    }
    // The angles' covariance from the slopes': `dτ = ds / (1 + s²)`; exactly symmetric (the
    // inverse's two off-diagonal entries, and the products taken in either order, may differ
    // in the last bit, and a covariance that is not symmetric is refused as a parameter).
    let c = [1.0 / (1.0 + beta[0] * beta[0]), 1.0 / (1.0 + beta[1] * beta[1])];
    let off = sigma2 * (0.5 * (inv[(0, 1)] + inv[(1, 0)])) * (c[0] * c[1]);
    let covariance = [sigma2 * inv[(0, 0)] * (c[0] * c[0]), off, off, sigma2 * inv[(1, 1)] * (c[1] * c[1])];
    Ok(AxisTilt { height_zero: beta[2], angles: [beta[0].atan(), beta[1].atan()], covariance })
}

/// The sphere (or plane) `2z = κ(x² + y² + z²) + Dx + Ey + G` (module docs).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sphere {
    /// `κ`, `D`, `E`, `G`.
    pub coefficients: [f64; 4],
}

impl Sphere {
    /// The least-squares sphere through `points` at heights `z`; `None` for fewer than 5
    /// points or points that do not fix it (all on a line).
    pub fn fit(points: &[Vector2<f64>], z: &[f64]) -> Option<Sphere> {
        if points.len().min(z.len()) < 5 {
            return None;
        }
        let mut ata = Matrix4::<f64>::zeros();
        let mut atb = Vector4::<f64>::zeros();
        for (p, z) in points.iter().zip(z) {
            let row = Vector4::new(p.norm_squared() + z * z, p.x, p.y, 1.0);
            ata.ger(1.0, &row, &row, 1.0);
            atb.axpy(2.0 * z, &row, 1.0);
        }
        // Columns of very different sizes (m², m, 1): scaled to one before solving.
        let scale = Vector4::from_fn(|i, _| ata[(i, i)].sqrt().max(f64::MIN_POSITIVE).recip());
        let scaled = Matrix4::from_fn(|i, j| ata[(i, j)] * scale[i] * scale[j]);
        let x = scaled.cholesky()?.solve(&atb.component_mul(&scale)).component_mul(&scale);
        x.iter().all(|c| c.is_finite()).then(|| Sphere { coefficients: [x[0], x[1], x[2], x[3]] })
    }

    /// `1/R` (0 for a plane).
    pub fn curvature(&self) -> f64 {
        let [k, d, e, g] = self.coefficients;
        let q = 1.0 + (d * d + e * e) / 4.0 - g * k;
        if q > 0.0 { k.abs() / q.sqrt() } else { 0.0 }
    }

    /// The frame curve, dioptres: `530 mm / R`.
    pub fn frame_curve(&self) -> f64 {
        FRAME_CURVE_METRES * self.curvature()
    }

    /// The sphere's height over `p` (the branch through the plane `2z = Dx + Ey + G` as
    /// `κ → 0`: `z = q / (1 + √(1 - κq))`, `q = κ|p|² + Dx + Ey + G`) and its slopes
    /// `∂z/∂(x, y) = (2κx + D, 2κy + E) / (2 - 2κz)`.
    pub fn at(&self, p: &Vector2<f64>) -> (f64, Vector2<f64>) {
        let [k, d, e, g] = self.coefficients;
        let q = k * p.norm_squared() + d * p.x + e * p.y + g;
        let z = q / (1.0 + (1.0 - k * q).max(0.0).sqrt());
        let den = 2.0 - 2.0 * k * z;
        (z, Vector2::new(2.0 * k * p.x + d, 2.0 * k * p.y + e) / den)
    }
}

/// A frame's third dimension: its sphere, and along the groove its height's slope
/// `z'(θ)` on the grid (module docs).
#[derive(Debug, Clone, PartialEq)]
pub struct Frame3d {
    pub sphere: Sphere,
    /// The groove's length in 3-D, `L₃`, metres.
    pub circumference: f64,
    /// The heights' noise `σ_h` about the sphere and the series, metres.
    pub height_noise: f64,
    /// Heights the figures were taken from, `N`.
    heights: usize,
    /// `z'` on the grid.
    slope: Vec<f64>,
    /// `s₃ = √(r² + r'² + z'²)` on the grid.
    arc: Vec<f64>,
    /// `dp/dθ` on the grid.
    tangent: Vec<Vector2<f64>>,
    /// `(r² + r'²)/s₃` on the grid.
    along_plane: Vec<f64>,
}

impl Frame3d {
    /// The 3-D figures of a closed contour whose plane figures are `sizes`, from its
    /// surface `points` and their `heights` above the holder's plane (one per point);
    /// `quantum`: the height count's size (the noise's floor `q/√12`). `None` without
    /// enough heights to fit the sphere and the series.
    pub fn of(sizes: &Sizes, points: &[Vector2<f64>], heights: &[f64], quantum: f64) -> Option<Frame3d> {
        let n = points.len().min(heights.len());
        let (points, heights) = (&points[..n], &heights[..n]);
        let terms = 2 * RESIDUAL_HARMONICS + 1;
        if n < 4 + terms + 8 {
            return None;
        }
        let sphere = Sphere::fit(points, heights)?;
        // The residuals about the sphere as a Fourier series in each point's own angle.
        let mut ata = DMatrix::<f64>::zeros(terms, terms);
        let mut atb = DVector::<f64>::zeros(terms);
        let mut row = DVector::<f64>::zeros(terms);
        let residuals: Vec<f64> = points.iter().zip(heights).map(|(p, h)| h - sphere.at(p).0).collect();
        for (p, res) in points.iter().zip(&residuals) {
            fourier_row(p.y.atan2(p.x), &mut row);
            ata.ger(1.0, &row, &row, 1.0);
            atb.axpy(*res, &row, 1.0);
        }
        let series = ata.cholesky()?.solve(&atb);
        let rss: f64 = points
            .iter()
            .zip(&residuals)
            .map(|(p, res)| {
                fourier_row(p.y.atan2(p.x), &mut row);
                (res - row.dot(&series)).powi(2)
            })
            .sum();
        let height_noise = (rss / (n - 4 - terms) as f64).sqrt().max(quantum / 12f64.sqrt());
        let grid = sizes.grid();
        let h = TAU / GRID as f64;
        let (mut slope, mut arc, mut tangent, mut along_plane) =
            (Vec::with_capacity(GRID), Vec::with_capacity(GRID), Vec::with_capacity(GRID), Vec::with_capacity(GRID));
        for (i, ((r, rp), (c, s))) in grid.iter().zip(grid_unit()).enumerate() {
            let p = Vector2::new(r * c, r * s);
            let dp = Vector2::new(rp * c - r * s, rp * s + r * c);
            let theta = TAU * i as f64 / GRID as f64;
            let series_slope: f64 = (1..=RESIDUAL_HARMONICS)
                .map(|k| {
                    let (sk, ck) = (k as f64 * theta).sin_cos();
                    k as f64 * (series[2 * k] * ck - series[2 * k - 1] * sk)
                })
                .sum();
            let zp = sphere.at(&p).1.dot(&dp) + series_slope;
            let plane = r * r + rp * rp;
            let s3 = (plane + zp * zp).sqrt();
            slope.push(zp);
            arc.push(s3);
            tangent.push(dp);
            along_plane.push(plane / s3);
        }
        // The plane's circumference as the size module took it (finer, its noise's
        // lengthening off) against this grid's: the same change in 3-D, times ∂L₃/∂L₂.
        let on_grid = super::size::grid_length(grid);
        let shift = if on_grid > 0.0 {
            (sizes.circumference - on_grid) * along_plane.iter().sum::<f64>() * h / on_grid
        } else {
            0.0
        };
        let circumference = arc.iter().sum::<f64>() * h + shift;
        circumference.is_finite().then_some(Frame3d {
            sphere,
            circumference,
            height_noise,
            heights: n,
            slope,
            arc,
            tangent,
            along_plane,
        })
    }

    /// The frame curve, dioptres.
    pub fn frame_curve(&self) -> f64 {
        self.sphere.frame_curve()
    }

    /// `∂L₃/∂L₂` for a change of the contour's scale in the plane: `∮ (r² + r'²)/s₃ / L₂`.
    pub fn plane_factor(&self, circumference_2d: f64) -> f64 {
        if circumference_2d > 0.0 {
            self.along_plane.iter().sum::<f64>() * TAU / GRID as f64 / circumference_2d
        } else {
            1.0
        }
    }

    /// `∂L₃/∂(tan τ_x, tan τ_y)`: `-∮ z' (dp/dθ)/s₃ dθ` (a tilt removed moves every
    /// height by `-p·δs`).
    pub fn tilt_response(&self) -> Vector2<f64> {
        let h = TAU / GRID as f64;
        -self.slope.iter().zip(&self.tangent).zip(&self.arc).map(|((z, t), s)| t * (z / s)).sum::<Vector2<f64>>() * h
    }

    /// The variance of `L₃` from the heights' noise through the series' coefficients
    /// (module docs).
    pub fn noise_variance(&self) -> f64 {
        let h = TAU / GRID as f64;
        let per_coefficient = 2.0 * self.height_noise * self.height_noise / self.heights as f64;
        (1..=RESIDUAL_HARMONICS)
            .map(|k| {
                let (mut gc, mut gs) = (0.0, 0.0);
                for (i, (z, s)) in self.slope.iter().zip(&self.arc).enumerate() {
                    let (sk, ck) = (k as f64 * TAU * i as f64 / GRID as f64).sin_cos();
                    gc -= z * k as f64 * sk / s * h;
                    gs += z * k as f64 * ck / s * h;
                }
                gc * gc + gs * gs
            })
            .sum::<f64>()
            * per_coefficient
    }

    /// `U95(L₃)` (k = 2) from the plane's `U95(C)` and the slopes' covariance (module docs).
    pub fn circumference_u95(&self, circumference_2d: f64, u95_2d: f64, slope_covariance: &Matrix2<f64>) -> f64 {
        let plane = self.plane_factor(circumference_2d) * u95_2d / 2.0;
        let g = self.tilt_response();
        let tilt = (g.transpose() * slope_covariance * g)[0].max(0.0);
        2.0 * (plane * plane + tilt + self.noise_variance()).sqrt()
    }
}

/// `(1, cos θ, sin θ, …, cos Kθ, sin Kθ)` into `row`.
fn fourier_row(theta: f64, row: &mut DVector<f64>) {
    row[0] = 1.0;
    for k in 1..=RESIDUAL_HARMONICS {
        let (s, c) = (k as f64 * theta).sin_cos();
        row[2 * k - 1] = c;
        row[2 * k] = s;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::smooth::Smooth;

    #[test]
    fn tilt_of_two_flat_artefacts() {
        let ring = |r: f64, n: usize| {
            (0..n)
                .map(|i| r * Vector2::new((TAU * i as f64 / n as f64).cos(), (TAU * i as f64 / n as f64).sin()))
                .collect::<Vec<_>>()
        };
        let (a, b) = (ring(0.02, 400), ring(0.03, 400));
        let tilt: [f64; 2] = [1.7e-3, -0.9e-3];
        let h = |pts: &[Vector2<f64>], z0: f64| -> Vec<f64> {
            pts.iter().map(|p| z0 + p.x * tilt[0].tan() + p.y * tilt[1].tan()).collect()
        };
        let (ha, hb) = (h(&a, 0.001), h(&b, -0.004));
        let mut hb_noisy = hb.clone();
        hb_noisy[7] += 1e-9;
        let fit = fit_axis_tilt(&[(&a, &ha), (&b, &hb_noisy)]).unwrap();
        assert!((fit.angles[0] - tilt[0]).abs() < 1e-9 && (fit.angles[1] - tilt[1]).abs() < 1e-9, "{fit:?}");
        assert!((fit.height_zero - 0.001).abs() < 1e-11);
        assert!(fit.height_above(&a[3], ha[3]).abs() < 1e-11);
        assert_eq!(fit_axis_tilt(&[(&a[..2], &ha[..2])]), Err(TiltError::TooFew { heights: 2, needed: 4 }));
        let line: Vec<Vector2<f64>> = (0..10).map(|i| Vector2::new(i as f64 * 1e-3, 0.0)).collect();
        assert_eq!(fit_axis_tilt(&[(&line, &[0.0; 10])]), Err(TiltError::Singular));
    }

    /// The covariance is exactly symmetric (a parameter that is not is refused): 200 noisy
    /// fits, off-centre artefacts, a tilted axis.
    #[test]
    fn the_tilt_covariance_is_exactly_symmetric() {
        use rand::SeedableRng;
        use rand_distr::{Distribution, Normal};
        let mut rng = rand::rngs::StdRng::seed_from_u64(11);
        let noise = Normal::new(0.0, 5e-6).unwrap();
        for _ in 0..200 {
            let artefact = |r: f64, c: Vector2<f64>, z0: f64, rng: &mut rand::rngs::StdRng| {
                let pts: Vec<Vector2<f64>> = (0..400)
                    .map(|i| c + r * Vector2::new((TAU * i as f64 / 400.0).cos(), (TAU * i as f64 / 400.0).sin()))
                    .collect();
                let z: Vec<f64> = pts.iter().map(|p| z0 + 1.7e-3 * p.x + 0.3e-3 * p.y + noise.sample(rng)).collect();
                (pts, z)
            };
            let (a, ha) = artefact(0.02, Vector2::new(6e-4, -4e-4), 0.0, &mut rng);
            let (b, hb) = artefact(0.02, Vector2::new(-3e-4, 5e-4), -1.5e-3, &mut rng);
            let fit = fit_axis_tilt(&[(&a, &ha), (&b, &hb)]).unwrap();
            assert_eq!(fit.covariance[1].to_bits(), fit.covariance[2].to_bits(), "{:?}", fit.covariance);
            assert!(fit.covariance[1].powi(2) <= fit.covariance[0] * fit.covariance[3], "{:?}", fit.covariance);
        }
    }

    #[test]
    fn a_spherical_ellipse_length_and_curve() {
        // An ellipse 26 × 16 mm on a base-6 sphere (R = 88.33 mm) whose apex is 4 mm nasal
        // and 2 mm up of the box centre (the lens's optical centre, decentred).
        let big_r = FRAME_CURVE_METRES / 6.0;
        let m = 1024;
        let radius = |t: f64| 1.0 / ((t.cos() / 0.026).powi(2) + (t.sin() / 0.016).powi(2)).sqrt();
        let radii: Vec<f64> = (0..m).map(|i| radius(TAU * i as f64 / m as f64)).collect();
        let sizes = Sizes::of(&Smooth::fit(&radii, 100).unwrap());
        let points: Vec<Vector2<f64>> =
            (0..m).map(|i| TAU * i as f64 / m as f64).map(|t| radius(t) * Vector2::new(t.cos(), t.sin())).collect();
        let apex = Vector2::new(0.004, 0.002);
        let sag = |p: &Vector2<f64>| big_r - (big_r * big_r - (p - apex).norm_squared()).sqrt();
        let z: Vec<f64> = points.iter().map(sag).collect();
        let frame = Frame3d::of(&sizes, &points, &z, 0.0).unwrap();
        assert!((frame.frame_curve() - 6.0).abs() < 1e-6, "{}", frame.frame_curve());
        // The length by a fine sum along the curve itself.
        let fine = 200_000;
        let at = |t: f64| {
            let p = radius(t) * Vector2::new(t.cos(), t.sin());
            nalgebra::Vector3::new(p.x, p.y, sag(&p))
        };
        let length: f64 =
            (0..fine).map(|i| (at(TAU * (i + 1) as f64 / fine as f64) - at(TAU * i as f64 / fine as f64)).norm()).sum();
        assert!((frame.circumference - length).abs() < 0.2e-6, "{} vs {length}", frame.circumference);
        assert!(frame.circumference - sizes.circumference > 10e-6, "{}", frame.circumference - sizes.circumference);
        // Flat: the 3-D length is the plane's.
        let flat = Frame3d::of(&sizes, &points, &vec![0.0; m], 0.0).unwrap();
        assert_eq!(flat.frame_curve(), 0.0);
        assert_eq!(flat.circumference, sizes.circumference);
    }
}
