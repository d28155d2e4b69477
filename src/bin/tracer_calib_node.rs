//! `tracer_calib_node`: the ROS 2 node. Standard ROS arguments:
//!
//! ```text
//! tracer_calib_node --ros-args -r __ns:=/cell1 -r __node:=tracer -r raw_scan:=/x \
//!     -p name:=value --params-file FILE
//! ```
//!
//! Logs go to stderr, warnings and errors only unless `--log-level` or `RUST_LOG` say
//! otherwise. SIGINT and SIGTERM shut the node down cleanly.

use std::process::ExitCode;

use tracer_calib::rmw::RosEnv;
use tracer_calib::ros::args::RosArgs;
use tracer_calib::ros::node::{Config, run};

fn main() -> ExitCode {
    let args = match RosArgs::from_env() {
        Ok(a) => a,
        Err(e) => {
            eprintln!("tracer_calib_node: {e}");
            return ExitCode::from(2);
        }
    };
    init_logging(&args);
    if let Some(extra) = args.program_args.get(1) {
        eprintln!("tracer_calib_node: unexpected argument '{extra}' (ROS arguments go after --ros-args)");
        return ExitCode::from(2);
    }
    let env = match RosEnv::from_env() {
        Ok(e) => e,
        Err(e) => {
            eprintln!("tracer_calib_node: {e}");
            return ExitCode::from(2);
        }
    };
    let config = match Config::load(args, env) {
        Ok(c) => c,
        Err(e) => {
            eprintln!("tracer_calib_node: {e}");
            return ExitCode::from(1);
        }
    };
    let (tx, rx) = smol::channel::bounded::<()>(1);
    if let Err(e) = ctrlc::set_handler(move || {
        let _ = tx.try_send(());
    }) {
        eprintln!("tracer_calib_node: cannot install the signal handler: {e}");
        return ExitCode::from(1);
    }
    match run(config, async move {
        let _ = rx.recv().await;
    }) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("tracer_calib_node: {e}");
            ExitCode::from(1)
        }
    }
}

/// Warnings by default; rustdds' per-datagram size warnings only as errors, and not its
/// multicast-leave error at shutdown.
fn init_logging(args: &RosArgs) {
    let mut builder = env_logger::Builder::new();
    builder.filter_level(log::LevelFilter::Warn);
    builder.filter_module("rustdds", log::LevelFilter::Error);
    // Its only error: leaving the discovery multicast group as the participant closes,
    // which fails (harmlessly) on loopback-only set-ups, two ERROR lines a shutdown.
    builder.filter_module("rustdds::network::udp_listener", log::LevelFilter::Off);
    // ros2-client's rosout_raw is a tracing span; with tracing's `log` feature on (zenoh
    // turns it on) every span would come out as an ERROR "rosout_raw;" line. Zenoh's own
    // tracing events still come through, as log records of their modules.
    builder.filter_module("tracing::span", log::LevelFilter::Off);
    // zenoh 1.8's admin space, as the session closes at shutdown, fails to publish the
    // closing links' events ("Unable to publish transport event: session closed", ERROR;
    // rmw_zenoh's processes print it too): harmless, and the admin space is all it logs.
    builder.filter_module("zenoh::api::admin", log::LevelFilter::Off);
    if let Some(level) = args.log_level.and_then(|l| l.level_filter()) {
        builder.filter_module("tracer_calib", level);
        builder.filter_module("tracer_calib_node", level);
    }
    if let Ok(spec) = std::env::var("RUST_LOG") {
        builder.parse_filters(&spec);
    }
    builder.init();
}
