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
    // Its certificates, each u = U/k.
    assert_eq!(
        [c.params.plate_side_uncertainty, c.params.corner_radius_uncertainty, c.params.tip_radius_uncertainty],
        [1.0e-6, 5.0e-6, 0.0]
    );
    assert_eq!(c.params.seating_uncertainty, 3.5e-4);
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

/// A temporary directory of its own for one test.
fn scratch(name: &str) -> std::path::PathBuf {
    let d = std::env::temp_dir().join(format!("tracer_calib_config_{name}_{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

#[test]
fn a_params_file_apart_from_the_files_read_is_created_from_them_then_read_after_them() {
    // What the launch files do without params_file: the installed defaults read, the
    // node's own file under $ROS_HOME created from them, then read after them.
    let root = env!("CARGO_MANIFEST_DIR");
    let defaults = format!("{root}/config/tracer_calib.yaml");
    let d = scratch("seed");
    let state = d.join("ros_home/tracer_calib/tracer_calibrator.yaml");
    let state_s = state.display().to_string();
    let argv = ["n", "--ros-args", "--params-file", &defaults, "-p", &format!("params_file:={state_s}")];
    let c = load(&argv).unwrap();
    assert_eq!(c.params.params_file, state_s);
    assert_eq!(std::fs::read_to_string(&state).unwrap(), std::fs::read_to_string(&defaults).unwrap());
    assert_eq!(c.persist_problem, "");
    // Once the node has edited it, its values win over the defaults'.
    std::fs::write(&state, "tracer_calibrator:\n  ros__parameters:\n    model: full_tip\n").unwrap();
    assert_eq!(load(&argv).unwrap().params.model.as_str(), "full_tip");
    // A sibling file (a persist that could not edit the file) is read after it, and said.
    let sibling = d.join("ros_home/tracer_calib/tracer_calibrator.persisted.tracer_calibrator.yaml");
    std::fs::write(&sibling, "tracer_calibrator:\n  ros__parameters:\n    model: paper\n").unwrap();
    let c = load(&argv).unwrap();
    assert_eq!(c.params.model.as_str(), "paper");
    assert!(c.persist_problem.contains(&sibling.display().to_string()), "{}", c.persist_problem);
    // A file of a newer format is refused, naming it.
    std::fs::write(&state, "# tracer_calib: params format 9\ntracer_calibrator:\n  ros__parameters: {}\n").unwrap();
    let e = load(&argv).unwrap_err();
    assert!(e.starts_with(&format!("{state_s}:1: params format 9, written by a newer tracer_calib")), "{e}");
    // A params file given with --params-file that does not exist still stops the node.
    let missing = d.join("missing.yaml").display().to_string();
    let e = load(&["n", "--ros-args", "--params-file", &missing]).unwrap_err();
    assert!(e.starts_with(&format!("{missing}: cannot read")), "{e}");
    std::fs::remove_dir_all(&d).unwrap();
}

/// What a cell's operators open (docs/node.md): the diagnostic_aggregator analyzers match
/// the node's two status names (as `cell::diagnostics` and `cell::driver` make them), and
/// the RViz view shows the topic the node publishes polygons on, in its default frame.
#[test]
fn the_operators_files_name_what_the_node_publishes() {
    use yaml_rust2::YamlLoader;
    let root = env!("CARGO_MANIFEST_DIR");
    let text = std::fs::read_to_string(format!("{root}/config/tracer_calib_analyzers.yaml")).unwrap();
    let doc = &YamlLoader::load_from_str(&text).unwrap()[0];
    let group = &doc["analyzers"]["ros__parameters"]["tracers"];
    assert_eq!(group["type"].as_str(), Some("diagnostic_aggregator/AnalyzerGroup"));
    let pattern = |name: &str| regex::Regex::new(group["analyzers"][name]["regex"][0].as_str().unwrap()).unwrap();
    let (calibration, driver) = (pattern("calibration"), pattern("driver"));
    for fqn in ["/tracer_calibrator", "/cell1/tracer", "/line3/cell2/tracer"] {
        let status = format!("tracer_calib: {fqn}");
        let driver_status = format!("tracer_calib: {fqn}: tracer driver");
        assert!(calibration.is_match(&status) && !calibration.is_match(&driver_status), "{fqn}");
        assert!(driver.is_match(&driver_status) && !driver.is_match(&status), "{fqn}");
    }
    let rviz = std::fs::read_to_string(format!("{root}/config/tracer_calib.rviz")).unwrap();
    let view = &YamlLoader::load_from_str(&rviz).unwrap()[0]["Visualization Manager"];
    assert_eq!(view["Global Options"]["Fixed Frame"].as_str(), Some("tracer_axis"));
    let polygon =
        view["Displays"].as_vec().unwrap().iter().find(|d| d["Class"].as_str() == Some("rviz_default_plugins/Polygon"));
    assert_eq!(polygon.unwrap()["Topic"]["Value"].as_str(), Some("/contour_polygon"));
}
