//! `tracer_calib`: makes the contact contour tracer of a lens-edging cell measure true.
//!
//! - [`engine`]: the pure calibration engine (geometry, plate models, LM, correction);
//! - the shell around it: files ([`io`]) and the offline tool ([`cli`]).
//!
//! Conventions (see the README): SI units (metres, radians), the rail turns
//! counter-clockwise, `P = (rho - dL) u + d v`.

pub mod cli;
pub mod engine;
pub mod io;
pub mod params;
pub mod records;
pub mod ros;
