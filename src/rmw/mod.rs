//! The middleware: how a process of ours (the node, `tracer_calib replay`, the demo) joins a
//! ROS 2 graph, as a stock node's rmw does.
//!
//! - [`env`]: the ROS environment (`ROS_DOMAIN_ID`, `ROS_AUTOMATIC_DISCOVERY_RANGE`,
//!   `ROS_STATIC_PEERS`, `ROS_LOCALHOST_ONLY`), read as rcl reads it;
//! - [`security`]: the SROS2 enclave (`ROS_SECURITY_*`, `--enclave`), found as rcl finds it;
//! - [`dds`]: the DDS participant those make, with rmw_fastrtps' discovery rules.
//!
//! It knows the interface layer's names, never the cell's logic: the node shell
//! ([`crate::ros`]) and the tools ([`crate::cli`]) sit above it. A second middleware
//! (Zenoh) goes beside [`dds`].

pub mod dds;
pub mod env;
pub mod security;

pub use env::{DiscoveryRange, EnvError, RosEnv};
pub use security::{Security, SecurityError};
