//! The thin ROS shell: message mirrors, command line, the node's state and wiring.

pub mod args;
pub mod discovery;
pub mod msgs;
pub mod node;
pub mod qos_overrides;
pub mod state;
