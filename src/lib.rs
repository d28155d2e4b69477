//! `tracer_calib`: makes the contact contour tracer of a lens-edging cell measure true.
//!
//! The layers, each using only those listed before it:
//!
//! - [`engine`]: the pure calibration engine (geometry, plate models, LM, correction): no
//!   I/O, no ROS types;
//! - [`interfaces`]: the ROS message types, their `.msg` texts and the CDR codec;
//! - [`params`], [`records`]: the node's parameters (and their YAML file), the
//!   calibration history;
//! - [`cell`]: the cell's logic (scan checks, correction, calibration in force, records,
//!   diagnostics), without any middleware;
//! - [`io`]: files (CSV, rosbag2, OMA, SVG);
//! - [`names`]: ROS 2 names (node names, namespaces, topics, services, `-r` remap rules),
//!   validated, expanded and remapped as rcl does;
//! - [`rmw`]: joining a ROS graph (the ROS environment, the DDS participant);
//! - [`ros`]: the node shell (`tracer_calib_node`); [`cli`]: the offline tool
//!   (`tracer_calib`). Neither uses the other.
//!
//! Conventions (docs/engine.md): SI units (metres, radians), the rail turns
//! counter-clockwise, `P = (k rho - dL) u + d v`.

pub(crate) mod c_number;
pub mod cell;
pub mod cli;
pub use tracer_calib_engine as engine;
pub mod interfaces;
pub mod io;
pub mod names;
pub mod params;
pub mod records;
pub mod rmw;
pub mod ros;
