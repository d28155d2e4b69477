//! The shipped params files in config/ load as the node loads them.

use tracer_calib::params::ParamValue;
use tracer_calib::rmw::RosEnv;
use tracer_calib::ros::args::RosArgs;
use tracer_calib::ros::node::Config;

fn load(argv: &[&str]) -> Result<Config, String> {
    let args = RosArgs::parse(argv.iter().map(|s| s.to_string())).map_err(|e| e.to_string())?;
    Config::load(args, RosEnv::from_lookup(|_| None).unwrap())
}

#[test]
fn default_config_gives_the_contract_defaults() {
    let root = env!("CARGO_MANIFEST_DIR");
    let path = format!("{root}/config/tracer_calib.yaml");
    let c = load(&["tracer_calib_node", "--ros-args", "--params-file", &path]).unwrap();
    assert_eq!(c.identity.fully_qualified_name(), "/tracer_calibrator");
    let want = tracer_calib::params::Parameters {
        params_file: path.clone(),
        history_file: format!("{root}/config/tracer_calib.history.jsonl"),
        ..Default::default()
    };
    assert_eq!(c.params, want);
}

#[test]
fn namespaced_example_applies_to_its_node_only() {
    let root = env!("CARGO_MANIFEST_DIR");
    let path = format!("{root}/config/cell1_tracer.yaml");
    let c = load(&["n", "--ros-args", "-r", "__ns:=/cell1", "-r", "__node:=tracer", "--params-file", &path]).unwrap();
    assert_eq!(c.identity.fully_qualified_name(), "/cell1/tracer");
    assert_eq!(c.params.meters_per_count, 0.5e-6);
    assert_eq!(c.params.output_frame_id, "cell1_tracer_axis");
    // Another cell's node does not pick it up.
    let c = load(&["n", "--ros-args", "-r", "__ns:=/cell2", "-r", "__node:=tracer", "--params-file", &path]).unwrap();
    assert_eq!(c.params.meters_per_count, 1e-6);
    // -p overrides the file; a bad -p names itself.
    let c = load(&[
        "n",
        "--ros-args",
        "-r",
        "__ns:=/cell1",
        "-r",
        "__node:=tracer",
        "--params-file",
        &path,
        "-p",
        "model:=paper",
    ])
    .unwrap();
    assert_eq!(c.params.get("model"), Some(ParamValue::String("paper".into())));
    let e = load(&["n", "--ros-args", "-p", "plate.side:=-2.0"]).unwrap_err();
    assert!(e.starts_with("-p plate.side:=-2.0: must be positive (greater than 0), got -2"), "{e}");
}

#[test]
fn history_file_defaults_beside_the_params_file_unless_set() {
    let c = load(&["n", "--ros-args"]).unwrap();
    assert_eq!(c.params.history_file, "", "no params file, no history");
    let c = load(&["n", "--ros-args", "-p", "params_file:=/var/lib/cell/tracer.yaml"]).unwrap();
    assert_eq!(c.params.history_file, "/var/lib/cell/tracer.history.jsonl");
    let c = load(&["n", "--ros-args", "-p", "params_file:=/x/p.yaml", "-p", "history_file:=/y/h.jsonl"]).unwrap();
    assert_eq!(c.params.history_file, "/y/h.jsonl");
    let c = load(&["n", "--ros-args", "-p", "params_file:=/x/p.yaml", "-p", "history_file:=''"]).unwrap();
    assert_eq!(c.params.history_file, "", "set to empty: no history");
    let e = load(&["n", "--ros-args", "-p", "plate.side:=-2.0"]).unwrap_err();
    assert!(e.starts_with("-p plate.side:=-2.0: must be positive (greater than 0), got -2"), "{e}");
}
