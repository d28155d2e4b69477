//! The params-file reader and the typed parameters: `params::file::parse`, then
//! `Parameters::apply_file` for two node names, as the node does at start-up.
//!
//! Invariants besides "no panic":
//! - an applied file renders (`params::file::render`, as the node persists) to text that
//!   parses and applies back to the same typed parameters, with the same values listed;
//! - a failed apply names the file and leaves the parameters as they were;
//! - the file's own entries (with ROS parameter names) render and read back unchanged,
//!   and each value's one-line YAML reads back through `ParamValue::parse_yaml` (`-p`).
#![no_main]

use libfuzzer_sys::fuzz_target;
use tracer_calib::params::file::{self, Entry};
use tracer_calib::params::{ParamValue, Parameters};

const PATH: &str = "fuzz";
/// The comment the node writes at the top of the file it persists.
const COMMENT: &str = "Parameters of tracer_calib_node, written by the node after each change.\nLoad with: --ros-args --params-file THIS_FILE";

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else { return };
    let Ok(parsed) = file::parse(text, PATH) else { return };

    for fqn in ["/tracer_calibrator", "/cell1/tracer"] {
        typed_round_trip(&parsed, fqn);
        untyped_round_trip(&parsed, fqn);
    }
    for section in &parsed.sections {
        for e in &section.params {
            value_round_trip(&e.value);
        }
    }
});

fn typed_round_trip(parsed: &file::ParamsFile, fqn: &str) {
    let mut p = Parameters::default();
    match p.apply_file(parsed, fqn, PATH) {
        Err(e) => {
            assert_eq!(p, Parameters::default(), "a failed apply changed the parameters");
            assert!(e.to_string().starts_with(PATH), "{e}");
        }
        Ok(unknown) => {
            for name in &unknown {
                assert!(!Parameters::is_known(name), "{name} is known but was returned as unknown");
            }
            let list = p.to_list();
            let rendered = file::render(fqn, &list, COMMENT);
            let back = file::parse(&rendered, PATH)
                .unwrap_or_else(|e| panic!("rendered parameters do not parse: {e}\n{rendered}"));
            let entries: Vec<(String, ParamValue)> =
                back.entries_for(fqn).map(|e| (e.name.clone(), e.value.clone())).collect();
            assert_eq!(entries, list, "rendered parameters read back differently:\n{rendered}");
            let mut q = Parameters::default();
            let unknown = q
                .apply_file(&back, fqn, PATH)
                .unwrap_or_else(|e| panic!("rendered parameters do not apply: {e}\n{rendered}"));
            assert!(unknown.is_empty(), "{unknown:?}");
            assert_eq!(q, p, "rendered parameters applied differently:\n{rendered}");
        }
    }
}

/// Is `name` a ROS parameter name: `[A-Za-z0-9_]` tokens separated by `.`?
fn ros_param_name(name: &str) -> bool {
    !name.is_empty()
        && name.split('.').all(|t| !t.is_empty() && t.chars().all(|c| c.is_ascii_alphanumeric() || c == '_'))
}

fn untyped_round_trip(parsed: &file::ParamsFile, fqn: &str) {
    let list: Vec<(String, ParamValue)> = parsed
        .entries_for(fqn)
        .filter(|e| ros_param_name(&e.name))
        .map(|e: &Entry| (e.name.clone(), e.value.clone()))
        .collect();
    let rendered = file::render(fqn, &list, COMMENT);
    let back =
        file::parse(&rendered, PATH).unwrap_or_else(|e| panic!("rendered entries do not parse: {e}\n{rendered}"));
    let entries: Vec<(String, ParamValue)> = back.entries_for(fqn).map(|e| (e.name.clone(), e.value.clone())).collect();
    assert_eq!(entries.len(), list.len(), "rendered entries read back differently:\n{rendered}");
    for ((n1, v1), (n2, v2)) in list.iter().zip(&entries) {
        assert_eq!(n1, n2, "\n{rendered}");
        assert!(same(v1, v2), "{n1}: {v1:?} read back as {v2:?}:\n{rendered}");
    }
}

fn value_round_trip(v: &ParamValue) {
    let yaml = v.to_yaml();
    match ParamValue::parse_yaml(&yaml) {
        Ok(back) => assert!(same(v, &back), "{v:?} -> {yaml:?} -> {back:?}"),
        // An empty array has no type on a command line; that is the one documented refusal.
        Err(e) => assert!(yaml == "[]", "{v:?} -> {yaml:?} does not read back: {e}"),
    }
}

/// Equality with NaN equal to NaN.
fn same(a: &ParamValue, b: &ParamValue) -> bool {
    let f = |x: &f64, y: &f64| x == y || (x.is_nan() && y.is_nan());
    match (a, b) {
        (ParamValue::Double(x), ParamValue::Double(y)) => f(x, y),
        (ParamValue::DoubleArray(x), ParamValue::DoubleArray(y)) => {
            x.len() == y.len() && x.iter().zip(y).all(|(x, y)| f(x, y))
        }
        _ => a == b,
    }
}
