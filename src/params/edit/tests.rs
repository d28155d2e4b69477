use super::*;
use crate::params::file::parse;

/// A cell's shared params file as an integrator keeps it.
const SHARED: &str = "\
# Edging line 3, cell 1. Owner: J. Doe.
/**:
  ros__parameters:
    use_sim_time: false   # the cell runs on wall time

# The edger: do not raise feed_rate (certificate 4711).
/cell1/edger:
  ros__parameters:
    feed_rate: 0.5        # do not raise
    wheel: \"fine\"

/cell1/tracer:
  ros__parameters:
    # Plate certificate 4711, 2026-03-01.
    plate:
      side: 0.045         # certified
    calibration.alpha0: 0.0   # rad
    model: full
    # end of the tracer's keys

# The PLC bridge
/cell1/plc:
  ros__parameters:
    port: 502
";

fn d(x: f64) -> ParamValue {
    ParamValue::Double(x)
}

fn values(text: &str, fqn: &str) -> Vec<(String, ParamValue)> {
    let f = parse(text, "t").unwrap();
    let mut out: Vec<(String, ParamValue)> = Vec::new();
    for e in f.entries_for(fqn) {
        out.retain(|(n, _)| n != &e.name);
        out.push((e.name.clone(), e.value.clone()));
    }
    out
}

#[test]
fn a_shared_file_keeps_everything_but_this_nodes_values() {
    let changes = vec![
        ("calibration.alpha0".to_string(), d(0.0349)),
        ("plate.side".to_string(), d(0.05)),
        ("calibration.valid".to_string(), ParamValue::Bool(true)),
        ("calibration.covariance".to_string(), ParamValue::DoubleArray(vec![1e-12, 0.0])),
    ];
    let out = edit(SHARED, "/cell1/tracer", &changes).unwrap();
    let want = "\
# tracer_calib: params format 2
# Edging line 3, cell 1. Owner: J. Doe.
/**:
  ros__parameters:
    use_sim_time: false   # the cell runs on wall time

# The edger: do not raise feed_rate (certificate 4711).
/cell1/edger:
  ros__parameters:
    feed_rate: 0.5        # do not raise
    wheel: \"fine\"

/cell1/tracer:
  ros__parameters:
    # Plate certificate 4711, 2026-03-01.
    plate:
      side: 0.05         # certified
    calibration.alpha0: 0.0349   # rad
    model: full
    # end of the tracer's keys
    calibration.valid: true
    calibration.covariance: [1.0e-12, 0.0]

# The PLC bridge
/cell1/plc:
  ros__parameters:
    port: 502
";
    assert_eq!(out, want);
    // The same change again changes nothing; a further one edits in place.
    assert_eq!(edit(&out, "/cell1/tracer", &changes).unwrap(), out);
    let again = edit(&out, "/cell1/tracer", &[("calibration.alpha0".into(), d(-0.01))]).unwrap();
    assert_eq!(again, out.replace("calibration.alpha0: 0.0349   # rad", "calibration.alpha0: -0.01   # rad"));
    // Other nodes read exactly what they read before.
    for node in ["/cell1/edger", "/cell1/plc", "/cell2/tracer"] {
        assert_eq!(values(&out, node), values(SHARED, node), "{node}");
    }
}

#[test]
fn a_node_without_a_section_gets_one_at_the_end() {
    let out = edit(SHARED, "/cell2/tracer", &[("calibration.valid".into(), ParamValue::Bool(true))]).unwrap();
    assert_eq!(
        out,
        format!(
            "# tracer_calib: params format 2\n{SHARED}\n/cell2/tracer:\n  ros__parameters:\n    calibration.valid: true\n"
        )
    );
    // At the root the key is the bare node name; an empty file gets the format line and it.
    let out = edit("", "/tracer_calibrator", &[("model".into(), ParamValue::String("full_tip".into()))]).unwrap();
    assert_eq!(out, "# tracer_calib: params format 2\ntracer_calibrator:\n  ros__parameters:\n    model: full_tip\n");
    // The file's own indentation is kept for the new section.
    let wide = "a:\n    ros__parameters:\n        x: 1\n";
    let out = edit(wide, "/b", &[("y".into(), ParamValue::Integer(2))]).unwrap();
    assert!(out.ends_with("\nb:\n    ros__parameters:\n        y: 2\n"), "{out}");
}

#[test]
fn lists_keep_their_style_and_an_empty_one_removes_the_key() {
    // `ros2 param dump` writes block lists.
    let dumped = "/t:\n  ros__parameters:\n    calibration.covariance:\n    - 1.0\n    - 2.0\n    model: full\n";
    let out =
        edit(dumped, "/t", &[("calibration.covariance".into(), ParamValue::DoubleArray(vec![3.0, 4.0, 5.0]))]).unwrap();
    assert_eq!(
        out,
        "# tracer_calib: params format 2\n/t:\n  ros__parameters:\n    calibration.covariance:\n    - 3.0\n    - 4.0\n    - 5.0\n    model: full\n"
    );
    let out = edit(&out, "/t", &[("calibration.covariance".into(), ParamValue::DoubleArray(vec![]))]).unwrap();
    assert_eq!(out, "# tracer_calib: params format 2\n/t:\n  ros__parameters:\n    model: full\n");
    let flow = "/t:\n  ros__parameters:\n    tags: ['a', \"b\"]   # two\n";
    let out = edit(flow, "/t", &[("tags".into(), ParamValue::StringArray(vec!["c".into()]))]).unwrap();
    assert!(out.ends_with("    tags: [c]   # two\n"), "{out}");
    // A quoted string keeps what follows it.
    let quoted = "/t:\n  ros__parameters:\n    frame: 'it''s' # q\n";
    let out = edit(quoted, "/t", &[("frame".into(), ParamValue::String("axis".into()))]).unwrap();
    assert!(out.ends_with("    frame: axis # q\n"), "{out}");
}

#[test]
fn an_empty_parameter_map_opens_up() {
    let text = "/t:\n  ros__parameters: {}   # nothing yet\n/u:\n  ros__parameters:\n    a: 1\n";
    let out = edit(text, "/t", &[("model".into(), ParamValue::String("paper".into()))]).unwrap();
    assert_eq!(
        out,
        "# tracer_calib: params format 2\n/t:\n  ros__parameters: # nothing yet\n    model: paper\n/u:\n  ros__parameters:\n    a: 1\n"
    );
}

#[test]
fn what_would_be_reformatted_is_refused_with_the_reason() {
    let why = |text: &str, name: &str| edit(text, "/t", &[(name.into(), d(1.5))]).unwrap_err().to_string();
    assert!(
        why("/t:\n  ros__parameters:\n    x: &v 1.0\n/u:\n  ros__parameters:\n    y: 2.0\n", "x").contains("anchor")
    );
    assert!(why("base: &b\n  ros__parameters:\n    x: 1.0\n/t: *b\n", "x").contains("aliases"));
    assert!(why("/t:\n  ros__parameters: {x: 1.0, y: 2.0}\n", "x").contains("flow map"));
    assert!(why("/t:\n  ros__parameters: {x: 1.0}\n", "z").contains("flow map"));
    assert!(why("/t:\n  ros__parameters:\n    x: !!float 1\n", "x").contains("tag"));
    assert!(why("/t:\n  ros__parameters:\n    s: a\n      b\n", "s").contains("several lines"));
    assert!(why("/t:\n  ros__parameters:\n    s: |\n      a\n", "s").contains("several lines"));
    assert!(
        why("/t:\n  ros__parameters:\n    x: 1.0\n---\n/u:\n  ros__parameters:\n    y: 1\n", "x").contains("documents")
    );
    assert!(why("{/t: {ros__parameters: {x: 1.0}}}\n", "x").contains("flow map"));
    let later = "/t:\n  ros__parameters:\n    x: 1.0\n/**:\n  ros__parameters:\n    x: 2.0\n";
    assert_eq!(why(later, "x"), "section '/**' sets 'x' for this node after its own section");
    let commented = "/t:\n  ros__parameters:\n    x:\n    - 1.0  # first\n    - 2.0\n";
    let e = edit(commented, "/t", &[("x".into(), ParamValue::DoubleArray(vec![1.0]))]).unwrap_err();
    assert!(e.to_string().contains("comments"), "{e}");
    assert!(why("/t: [1]\n", "x").contains("does not read"));
}

#[test]
fn the_format_line_is_kept_or_upgraded() {
    assert_eq!(declared_format("# x\n# tracer_calib: params format 1\n"), Some((1, 1)));
    assert_eq!(declared_format("/t: {}\n"), None);
    let old = "# tracer_calib: params format 1\n/t:\n  ros__parameters:\n    x: 1.0\n";
    let out = edit(old, "/t", &[("x".into(), d(2.0))]).unwrap();
    assert_eq!(out, "# tracer_calib: params format 2\n/t:\n  ros__parameters:\n    x: 2.0\n");
    assert_eq!(edit(&out, "/t", &[]).unwrap(), out);
}

#[test]
fn crlf_lines_stay_crlf() {
    let text = "/t:\r\n  ros__parameters:\r\n    x: 1.0  # c\r\n";
    let out = edit(text, "/t", &[("x".into(), d(2.0))]).unwrap();
    assert!(out.contains("    x: 2.0  # c\r\n"), "{out:?}");
}
