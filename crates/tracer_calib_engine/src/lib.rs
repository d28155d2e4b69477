//! The calibration engine of `tracer_calib`: pure computation, no I/O, no ROS types (the
//! crate depends on no middleware and no I/O library; the root package's
//! `tests/engine_crate.rs` checks it). `tracer_calib` re-exports it as `tracer_calib::engine`.
//!
//! The pipeline, one module a stage:
//!
//! 1. [`geometry`] — rail angle, rail frame, the touched point `P = (rho-dL) u + d v`;
//! 2. [`shape`] — convex contours (the plate: a rounded square) and where a rail ray
//!    leaves them;
//! 3. [`scan`] — a validated revolution of samples;
//! 4. [`model`] — the plate models as least-squares problems: [`model::full`] (every
//!    sample), [`model::full_scale`] (and the encoder scale), [`model::tip`] (and the
//!    stylus tip's radius, from a ring-gauge scan) and [`model::paper`] (the seed
//!    paper's reduced model);
//! 5. [`lm`] — the Levenberg-Marquardt solver, with covariance;
//! 6. [`start`] — a start that converges from any mounting error in range;
//! 7. [`calibrate`](mod@calibrate) — start, fit, outlier rejection, uncertainty: a [`Calibration`];
//!    [`lack_of_fit`] — whether the fit left structure in the residuals (a test of their
//!    low harmonics against the scan's own noise);
//! 8. [`correct`](mod@correct) — every sample to the tip's centre, and equal-angle resampling;
//! 9. [`smooth`] — a closed contour as a Fourier series `r(θ)`;
//!    [`stylus`] — from the tip's centre to the surface it touched (or the groove's bottom);
//! 10. [`size`] — circumference, box and FED of a corrected contour from a smooth fit, with
//!     their 95 % uncertainty from the calibration's covariance and the scan's noise;
//!     [`height`] — the axis's tilt from the flat artefacts' heights, and a frame's curve
//!     and 3-D length from its groove's.
//!
//! [`simulate`] makes scans of known shapes with known errors for tests and tools.

pub mod angle;
pub mod calibrate;
pub mod correct;
pub mod geometry;
pub mod height;
pub mod lack_of_fit;
pub mod lm;
pub mod model;
pub mod scan;
pub mod shape;
pub mod simulate;
pub mod size;
pub mod smooth;
pub mod start;
pub mod stylus;

pub use calibrate::{Calibration, CalibrationError, Options, Ring, calibrate, calibrate_with_ring};
pub use correct::{Corrector, PolarContour, correct, resample_radii};
pub use geometry::Mounting;
pub use model::tip::{RingError, RingSpec};
pub use model::{ModelKind, PlateError, PlateSpec};
pub use scan::{Sample, Scan, ScanError};
pub use stylus::{Groove, Traced, touched_surface};
