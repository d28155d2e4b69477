//! The ROS command-line parser: `ros::args::RosArgs::parse` on an argv made by splitting
//! the input at NUL bytes, then what the node does with it at start-up (its name and
//! namespace, `-p` overrides applied to the typed parameters, its topic and service names
//! resolved and turned into ros2-client names).
//!
//! Invariants besides "no panic": an accepted node identity has an absolute fully qualified
//! name; resolved names are valid fully qualified names; a failed `-p` leaves the
//! parameters as they were.
#![no_main]

use libfuzzer_sys::fuzz_target;
use tracer_calib::params::Parameters;
use tracer_calib::ros::args::RosArgs;
use tracer_calib::ros::names::{ros2_name, validate_full_name};

fuzz_target!(|data: &[u8]| {
    let text = String::from_utf8_lossy(data);
    let argv: Vec<&str> = text.split('\0').collect();
    let Ok(args) = RosArgs::parse(argv.iter().copied()) else { return };
    assert!(args.program_args.len() <= argv.len());
    let _ = args.params_files().count();
    let Ok(identity) = args.node_identity("tracer_calibrator", "/") else { return };
    let fqn = identity.fully_qualified_name();
    assert!(fqn.starts_with('/'), "{fqn}");
    // ros2-client is stricter than rcl (no `__` inside a token): an error, never a panic.
    let _ = identity.ros2_node_name();
    let mut params = Parameters::default();
    for o in args.param_overrides_for(&identity) {
        let before = params.clone();
        if params.set(&o.name, &o.value).is_err() {
            assert_eq!(params, before, "a failed set changed the parameters");
        }
    }
    for topic in ["raw_scan", "contour", "contour_polygon", "/diagnostics"] {
        if let Ok(resolved) = args.resolve_topic(topic, &identity) {
            assert!(validate_full_name(&resolved).is_ok(), "{resolved}");
            let _ = ros2_name(&resolved);
        }
    }
    if let Ok(resolved) = args.resolve_service("calibrate", &identity) {
        assert!(validate_full_name(&resolved).is_ok(), "{resolved}");
        let _ = ros2_name(&resolved);
    }
});
