//! The middleware: how a process of ours (the node, `tracer_calib replay`, the demo) joins a
//! ROS 2 graph, as a stock node's rmw does.
//!
//! - [`env`](mod@env): the ROS environment (`ROS_DOMAIN_ID`, `ROS_AUTOMATIC_DISCOVERY_RANGE`,
//!   `ROS_STATIC_PEERS`, `ROS_LOCALHOST_ONLY`), read as rcl reads it;
//! - [`security`]: the SROS2 enclave (`ROS_SECURITY_*`, `--enclave`), found as rcl finds it;
//! - [`implementation`]: `RMW_IMPLEMENTATION`, which of the two middlewares below;
//! - [`dds`]: the DDS participant those make, with rmw_fastrtps' discovery rules;
//! - [`zenoh`]: the Zenoh session, configured and checked as rmw_zenoh_cpp does.
//!
//! It knows the interface layer's names, never the cell's logic: the node shell
//! ([`crate::ros`]) and the tools ([`crate::cli`]) sit above it.

pub mod dds;
pub mod env;
pub mod implementation;
pub mod security;
#[cfg(feature = "zenoh")]
pub mod zenoh;

pub use env::{DiscoveryRange, EnvError, RosEnv};
pub use implementation::Middleware;
pub use security::{Security, SecurityError};
