//! The ROS shell: the `tracer_calib_node` program around the cell. It maps the wire to the
//! cell's logic ([`crate::cell`]) and back, and owns the node's DDS entities; it holds no
//! logic of its own beyond what rcl does for a stock node.
//!
//! - [`args`]: the command line (`--ros-args`: remaps, `-p`, params files, log levels);
//! - [`names`]: node, topic and service names, validated, expanded and remapped as rcl does
//!   ([`crate::names`], below the middleware, which validates names too; here for the shell);
//! - [`qos_overrides`]: the `qos_overrides.*` parameters, as rclcpp offers them;
//! - [`node`]: the node itself, one loop per concern.
//!
//! Below it: the interface layer ([`crate::interfaces`]), the middleware
//! ([`crate::rmw`]: environment, DDS participant), the cell. Nothing but the node binary
//! uses this module.

pub mod args;
pub mod logging;
pub use crate::names;
pub mod node;
pub mod qos_overrides;
