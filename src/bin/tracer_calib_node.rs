//! `tracer_calib_node`: the ROS 2 node. Standard ROS arguments:
//!
//! ```text
//! tracer_calib_node --ros-args -r __ns:=/cell1 -r __node:=tracer -r raw_scan:=/x \
//!     -p name:=value --params-file FILE
//! ```
//!
//! The node's records go to stderr and to `/rosout` at INFO and above unless `--log-level`
//! says otherwise (rcl's rules: `tracer_calib::ros::logging`); the libraries' warnings and
//! errors to stderr (`RUST_LOG` sets those). SIGINT and SIGTERM shut the node down cleanly.

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
    tracer_calib::ros::logging::install(&args);
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
