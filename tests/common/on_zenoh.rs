//! What the tests of the node on Zenoh share: the test's own session listening on loopback,
//! the node connecting to it directly (no router), and a lens-like scan.

use std::process::Command;

use ros2_client::zenoh::{Context, ContextOptions};
use tracer_calib::interfaces::RawScan;
use tracer_calib::rmw::dds::TypesInUse;

use super::NodeProcess;

/// A Zenoh session in peer mode listening on `tcp/127.0.0.1:port`, no multicast scouting,
/// on ROS domain `domain`, with the type hashes of the node's types.
pub fn listening_context(port: u16, domain: u16) -> Context {
    let mut config = zenoh::Config::default();
    config.insert_json5("mode", "\"peer\"").unwrap();
    config.insert_json5("listen/endpoints", &format!("[\"tcp/127.0.0.1:{port}\"]")).unwrap();
    config.insert_json5("scouting/multicast/enabled", "false").unwrap();
    let types = TypesInUse::default();
    Context::with_options(
        ContextOptions::new().domain_id(domain).zenoh_config(config).type_hashes(types.hashing_resolver()),
    )
    .expect("the test's Zenoh session")
}

/// `tracer_calib_node` on Zenoh, connecting to `tcp/127.0.0.1:port` without looking for a
/// router (`ZENOH_ROUTER_CHECK_ATTEMPTS=-1`).
pub fn node_connecting_to(port: u16) -> NodeProcess {
    NodeProcess(
        Command::new(env!("CARGO_BIN_EXE_tracer_calib_node"))
            .env("RMW_IMPLEMENTATION", "rmw_zenoh_cpp")
            .env("ZENOH_ROUTER_CHECK_ATTEMPTS", "-1")
            .env("ZENOH_CONFIG_OVERRIDE", format!("connect/endpoints=[\"tcp/127.0.0.1:{port}\"]"))
            .spawn()
            .expect("the node starts"),
    )
}

/// A lens-like scan: 400 samples, a circle of 20 000 counts.
pub fn lens_scan(scan_id: u32) -> RawScan {
    RawScan {
        scan_id,
        target: 3,
        steps_per_revolution: 400,
        step: (0..400).collect(),
        counts: vec![20_000; 400],
        ..RawScan::default()
    }
}
