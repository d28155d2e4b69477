//! The command line and `-p` values against rcl's rules.

use super::*;
use crate::params::value::YamlValueError;

fn parse(args: &[&str]) -> Result<RosArgs, ArgsError> {
    RosArgs::parse(args.iter().copied())
}

fn scalar(text: &str) -> ParamValue {
    ParamValue::from_yaml_scalar(text, false)
}

// ------------------------------------------------------------ YAML scalar typing

#[test]
fn yaml_booleans_follow_rcl() {
    for t in ["true", "True", "TRUE", "yes", "Yes", "YES", "on", "On", "ON", "y", "Y"] {
        assert_eq!(scalar(t), ParamValue::Bool(true), "{t}");
    }
    for f in ["false", "False", "FALSE", "no", "No", "NO", "off", "Off", "OFF", "n", "N"] {
        assert_eq!(scalar(f), ParamValue::Bool(false), "{f}");
    }
    for s in ["tRue", "yES", "oN", "t", "f", "1 ", "truee"] {
        assert!(!matches!(scalar(s), ParamValue::Bool(_)), "{s}");
    }
    assert_eq!(ParamValue::from_yaml_scalar("true", true), ParamValue::String("true".into()));
}

#[test]
fn yaml_integers_follow_strtoll_base_0() {
    assert_eq!(scalar("0"), ParamValue::Integer(0));
    assert_eq!(scalar("400"), ParamValue::Integer(400));
    assert_eq!(scalar("-12"), ParamValue::Integer(-12));
    assert_eq!(scalar("+7"), ParamValue::Integer(7));
    assert_eq!(scalar("0x1F"), ParamValue::Integer(31));
    assert_eq!(scalar("0X1f"), ParamValue::Integer(31));
    assert_eq!(scalar("-0x10"), ParamValue::Integer(-16));
    assert_eq!(scalar("010"), ParamValue::Integer(8), "octal, as in C");
    assert_eq!(scalar("9223372036854775807"), ParamValue::Integer(i64::MAX));
    assert_eq!(scalar("-9223372036854775808"), ParamValue::Integer(i64::MIN));
    assert_eq!(scalar(" 5"), ParamValue::Integer(5), "strtoll skips leading space");
    // not fully consumed, or overflowing: not an integer
    assert_eq!(scalar("08"), ParamValue::Double(8.0), "not octal; strtod reads it");
    assert_eq!(scalar("9223372036854775808"), ParamValue::Double(2f64.powi(63)));
    assert_eq!(scalar("0x"), ParamValue::String("0x".into()));
    assert_eq!(scalar("12abc"), ParamValue::String("12abc".into()));
    assert_eq!(scalar("5 "), ParamValue::String("5 ".into()));
    assert_eq!(scalar("1_000"), ParamValue::String("1_000".into()));
    assert_eq!(scalar("-"), ParamValue::String("-".into()));
    assert_eq!(scalar("+-5"), ParamValue::String("+-5".into()));
    assert_eq!(ParamValue::from_yaml_scalar("42", true), ParamValue::String("42".into()));
}

#[test]
fn yaml_doubles_follow_strtod() {
    assert_eq!(scalar("0.045"), ParamValue::Double(0.045));
    assert_eq!(scalar("1.0e-6"), ParamValue::Double(1.0e-6));
    assert_eq!(scalar("1e-6"), ParamValue::Double(1e-6));
    assert_eq!(scalar("1E3"), ParamValue::Double(1000.0));
    assert_eq!(scalar("-2.5"), ParamValue::Double(-2.5));
    assert_eq!(scalar("5."), ParamValue::Double(5.0));
    assert_eq!(scalar(".5"), ParamValue::Double(0.5));
    assert_eq!(scalar("+.5e+1"), ParamValue::Double(5.0));
    assert_eq!(scalar("0x1p3"), ParamValue::Double(8.0));
    assert_eq!(scalar("0x1.8p1"), ParamValue::Double(3.0));
    assert_eq!(scalar("inf"), ParamValue::Double(f64::INFINITY));
    assert_eq!(scalar("-Infinity"), ParamValue::Double(f64::NEG_INFINITY));
    for t in [".inf", ".Inf", ".INF", "+.inf", "+.Inf", "+.INF"] {
        assert_eq!(scalar(t), ParamValue::Double(f64::INFINITY), "{t}");
    }
    for t in ["-.inf", "-.Inf", "-.INF"] {
        assert_eq!(scalar(t), ParamValue::Double(f64::NEG_INFINITY), "{t}");
    }
    for t in [".nan", ".NaN", ".NAN", "nan", "NaN", "nan(123)"] {
        assert!(matches!(scalar(t), ParamValue::Double(d) if d.is_nan()), "{t}");
    }
    // not doubles
    for s in ["1e", "1e+", "e5", ".", "1.2.3", "1e999", "-1e999", "1e-400", "0x1p", ".infinity", "1,5", "1.5x"] {
        assert_eq!(scalar(s), ParamValue::String(s.into()), "{s}");
    }
    assert_eq!(scalar("0e-400"), ParamValue::Double(0.0), "an exact zero does not underflow");
}

#[test]
fn yaml_strings_and_edge_cases() {
    assert_eq!(scalar("full"), ParamValue::String("full".into()));
    assert_eq!(scalar("tracer_axis"), ParamValue::String("tracer_axis".into()));
    assert_eq!(scalar("null"), ParamValue::String("null".into()), "rcl has no null");
    assert_eq!(scalar("~"), ParamValue::String("~".into()));
    assert_eq!(scalar(""), ParamValue::String(String::new()));
}

// ------------------------------------------------------------ -p values

fn yaml(text: &str) -> ParamValue {
    ParamValue::parse_yaml(text).unwrap_or_else(|e| panic!("{text}: {e}"))
}

#[test]
fn parse_yaml_scalars_quotes_and_tags() {
    assert_eq!(yaml("0.0349"), ParamValue::Double(0.0349));
    assert_eq!(yaml("  7  "), ParamValue::Integer(7));
    assert_eq!(yaml("'7'"), ParamValue::String("7".into()));
    assert_eq!(yaml("\"true\""), ParamValue::String("true".into()));
    assert_eq!(yaml("'it''s'"), ParamValue::String("it's".into()));
    assert_eq!(yaml(r#""a\tb\n\"c\" \u00e9 \x41""#), ParamValue::String("a\tb\n\"c\" é A".into()));
    assert_eq!(yaml("''"), ParamValue::String(String::new()));
    assert_eq!(yaml("!!str 42"), ParamValue::String("42".into()));
    assert_eq!(yaml("!!float 42"), ParamValue::Integer(42), "rcl only honours !!str");
    assert_eq!(yaml("hello world"), ParamValue::String("hello world".into()));
    assert_eq!(yaml("a,b"), ParamValue::String("a,b".into()));
    assert_eq!(yaml("1.5 # metres"), ParamValue::Double(1.5));
    assert_eq!(yaml("a#b"), ParamValue::String("a#b".into()));
    assert_eq!(yaml("'x' # comment"), ParamValue::String("x".into()));
    assert_eq!(yaml("http://host/x"), ParamValue::String("http://host/x".into()));
    assert_eq!(yaml("[1 2]"), ParamValue::StringArray(vec!["1 2".into()]), "valid YAML: one plain scalar");
}

#[test]
fn parse_yaml_sequences() {
    assert_eq!(yaml("[1, 2, 3]"), ParamValue::IntegerArray(vec![1, 2, 3]));
    assert_eq!(yaml("[1.0,2.5]"), ParamValue::DoubleArray(vec![1.0, 2.5]));
    assert_eq!(yaml("[true, off]"), ParamValue::BoolArray(vec![true, false]));
    assert_eq!(yaml("[a, 'b c', \"d\"]"), ParamValue::StringArray(vec!["a".into(), "b c".into(), "d".into()]));
    assert_eq!(yaml("['1', '2']"), ParamValue::StringArray(vec!["1".into(), "2".into()]));
    assert_eq!(yaml("[ 1 , 2 , ]"), ParamValue::IntegerArray(vec![1, 2]));
    assert_eq!(yaml("[.inf, -.inf]"), ParamValue::DoubleArray(vec![f64::INFINITY, f64::NEG_INFINITY]));
}

#[test]
fn parse_yaml_rejects_what_rcl_rejects() {
    for bad in [
        "",
        "   ",
        "[]",
        "[1, 2.5]",
        "[1, a]",
        "[[1]]",
        "[1, 2",
        "{a: 1}",
        "a: b",
        "a:",
        "'open",
        "\"open",
        "\"bad \\q escape\"",
        "&anchor 1",
        "*alias",
        "|",
        "- 1",
        "'a' b",
        "[1,,2]",
        "# just a comment",
    ] {
        assert!(ParamValue::parse_yaml(bad).is_err(), "{bad:?} should be rejected");
    }
    // Not YAML, or YAML that is no value: told apart, in the words `-p` reports.
    let e = ParamValue::parse_yaml("'open").unwrap_err();
    assert!(matches!(e, YamlValueError::NotYaml(_)) && e.to_string().starts_with("not valid YAML: "), "{e}");
    let e = ParamValue::parse_yaml("[1, 2.5]").unwrap_err();
    assert_eq!(e, YamlValueError::NotAValue("an array must hold scalars of one type (write [1.0, 2.5], not [1, 2.5])"));
    assert_eq!(e.to_string(), "an array must hold scalars of one type (write [1.0, 2.5], not [1, 2.5])");
    assert!(matches!(ParamValue::parse_yaml("{a: 1}"), Err(YamlValueError::NotAValue(_))));
}

#[test]
fn to_yaml_round_trips() {
    let values = vec![
        ParamValue::Bool(true),
        ParamValue::Bool(false),
        ParamValue::Integer(0),
        ParamValue::Integer(-400),
        ParamValue::Integer(i64::MIN),
        ParamValue::Double(0.0),
        ParamValue::Double(-0.0),
        ParamValue::Double(1.0),
        ParamValue::Double(0.045),
        ParamValue::Double(1e-6),
        ParamValue::Double(5e-7),
        ParamValue::Double(1e16),
        ParamValue::Double(-1.25e21),
        ParamValue::Double(f64::MAX),
        ParamValue::Double(f64::MIN_POSITIVE),
        ParamValue::Double(f64::INFINITY),
        ParamValue::Double(f64::NEG_INFINITY),
        ParamValue::Double(std::f64::consts::PI),
        ParamValue::String("full".into()),
        ParamValue::String("tracer_axis".into()),
        ParamValue::String("/cell1/params.yaml".into()),
        ParamValue::String(String::new()),
        ParamValue::String("true".into()),
        ParamValue::String("y".into()),
        ParamValue::String("400".into()),
        ParamValue::String("0x10".into()),
        ParamValue::String("1.5".into()),
        ParamValue::String(".inf".into()),
        ParamValue::String("nan".into()),
        ParamValue::String("null".into()),
        ParamValue::String("~".into()),
        ParamValue::String("-abc".into()),
        ParamValue::String("it's: a # test, [x]".into()),
        ParamValue::String(" padded ".into()),
        ParamValue::String("line\nbreak\t\"q\" \\".into()),
        ParamValue::String("ünïcode".into()),
        ParamValue::BoolArray(vec![true, false]),
        ParamValue::IntegerArray(vec![1, -2, 3]),
        ParamValue::DoubleArray(vec![1.0, 2.5, -0.001]),
        ParamValue::StringArray(vec!["a".into(), "1".into(), "b, c".into(), "'q'".into()]),
    ];
    for value in values {
        let text = value.to_yaml();
        assert_eq!(ParamValue::parse_yaml(&text).as_ref(), Ok(&value), "{value:?} -> {text}");
        assert_eq!(value.to_string(), text);
    }
    let nan = ParamValue::parse_yaml(&ParamValue::Double(f64::NAN).to_yaml()).unwrap();
    assert!(matches!(nan, ParamValue::Double(d) if d.is_nan()));
    assert_eq!(ParamValue::Double(1.0).to_yaml(), "1.0");
    // Floats in YAML 1.1 too (PyYAML: `ros2 param load`): a '.', and a signed exponent.
    assert_eq!(ParamValue::Double(1e-6).to_yaml(), "1.0e-6");
    assert_eq!(ParamValue::Double(5e-7).to_yaml(), "5.0e-7");
    assert_eq!(ParamValue::Double(-1.25e21).to_yaml(), "-1.25e+21");
    assert_eq!(ParamValue::Double(f64::MAX).to_yaml(), "1.7976931348623157e+308");
    assert_eq!(ParamValue::Double(0.045).to_yaml(), "0.045");
    assert_eq!(ParamValue::DoubleArray(vec![1e-6, 2e22]).to_yaml(), "[1.0e-6, 2.0e+22]");
    assert_eq!(ParamValue::String("full".into()).to_yaml(), "full");
    assert_eq!(ParamValue::String("true".into()).to_yaml(), "'true'");
    assert_eq!(ParamValue::DoubleArray(vec![1.0, 2.5]).to_yaml(), "[1.0, 2.5]");
}

#[test]
fn param_values_convert_to_ros2_client() {
    use ros2_client::ParameterValue as P;
    assert_eq!(P::from(ParamValue::Bool(true)), P::Boolean(true));
    assert_eq!(P::from(ParamValue::Integer(4)), P::Integer(4));
    assert_eq!(P::from(ParamValue::Double(0.5)), P::Double(0.5));
    assert_eq!(P::from(ParamValue::String("s".into())), P::String("s".into()));
    assert_eq!(P::from(ParamValue::BoolArray(vec![true])), P::BooleanArray(vec![true]));
    assert_eq!(P::from(ParamValue::IntegerArray(vec![1])), P::IntegerArray(vec![1]));
    assert_eq!(P::from(ParamValue::DoubleArray(vec![1.5])), P::DoubleArray(vec![1.5]));
    assert_eq!(P::from(ParamValue::StringArray(vec!["a".into()])), P::StringArray(vec!["a".into()]));
    assert_eq!(ParamValue::IntegerArray(vec![]).type_name(), "integer_array");
}

// ------------------------------------------------------------ command line

#[test]
fn the_contract_command_line() {
    let args = parse(&[
        "tracer_calib_node",
        "--ros-args",
        "-r",
        "__ns:=/cell1",
        "-r",
        "__node:=tracer",
        "-r",
        "raw_scan:=/x",
        "-p",
        "plate.side:=0.05",
        "--params-file",
        "cal.yaml",
    ])
    .unwrap();
    assert_eq!(args.program_args, vec!["tracer_calib_node"]);
    let node = args.node_identity("tracer_calibrator", "/").unwrap();
    assert_eq!(node, NodeIdentity { name: "tracer".into(), namespace: "/cell1".into() });
    assert_eq!(node.fully_qualified_name(), "/cell1/tracer");
    assert_eq!(args.resolve_topic("raw_scan", &node).unwrap(), "/x");
    assert_eq!(args.resolve_topic("contour", &node).unwrap(), "/cell1/contour");
    assert_eq!(args.resolve_topic("/diagnostics", &node).unwrap(), "/diagnostics");
    assert_eq!(args.resolve_service("calibrate", &node).unwrap(), "/cell1/calibrate");
    let overrides: Vec<_> = args.param_overrides_for(&node).collect();
    assert_eq!(overrides.len(), 1);
    assert_eq!((overrides[0].name.as_str(), &overrides[0].value), ("plate.side", &ParamValue::Double(0.05)));
    assert_eq!(args.params_files().collect::<Vec<_>>(), vec![Path::new("cal.yaml")]);
}

#[test]
fn defaults_without_ros_args() {
    let args = parse(&["node", "--verbose", "-r", "x"]).unwrap();
    assert_eq!(args.program_args, vec!["node", "--verbose", "-r", "x"]);
    assert_eq!(args, RosArgs { program_args: args.program_args.clone(), ..RosArgs::default() });
    let node = args.node_identity("tracer_calibrator", "").unwrap();
    assert_eq!(node.fully_qualified_name(), "/tracer_calibrator");
    assert_eq!(args.resolve_service("calibrate", &node).unwrap(), "/calibrate");
    assert!(parse(&[]).unwrap().program_args.is_empty());
}

#[test]
fn blocks_and_program_args_interleave() {
    let args = parse(&[
        "prog",
        "a",
        "--ros-args",
        "-p",
        "x:=1",
        "--",
        "b",
        "--",
        "c",
        "--ros-args",
        "--ros-args",
        "--params-file",
        "f1.yaml",
        "--",
        "--ros-args",
        "--params-file",
        "f2.yaml",
    ])
    .unwrap();
    assert_eq!(args.program_args, vec!["prog", "a", "b", "--", "c"]);
    assert_eq!(args.params_files().collect::<Vec<_>>(), vec![Path::new("f1.yaml"), Path::new("f2.yaml")]);
    assert_eq!(args.param_overrides().count(), 1);
}

#[test]
fn long_flags_and_ignored_flags() {
    let args = parse(&[
        "p",
        "--ros-args",
        "--remap",
        "__node:=n",
        "--param",
        "model:=paper",
        "--log-level",
        "DEBUG",
        "--log-level",
        "rustdds:=error",
        "--log-level",
        "info",
        "--enable-rosout-logs",
        "--disable-rosout-logs",
        "--disable-stdout-logs",
        "--enable-external-lib-logs",
        "--log-config-file",
        "log.conf",
        "-e",
        "/enclave",
        "--log-file-name",
        "x.log",
    ])
    .unwrap();
    assert_eq!(args.node_identity("d", "/").unwrap().name, "n");
    assert_eq!(args.param_overrides().next().unwrap().value, ParamValue::String("paper".into()));
    assert_eq!(args.log_level, Some(LogLevel::Info), "the last one");
    assert_eq!(args.logger_levels, vec![("rustdds".to_string(), LogLevel::Error)]);
    assert_eq!(args.log_config_file.as_deref(), Some(Path::new("log.conf")));
    assert_eq!(args.enclave.as_deref(), Some("/enclave"));
    // The last of each pair wins; the external-lib toggle and the log file name are ignored.
    assert_eq!((args.rosout_logs, args.stdout_logs), (Some(false), Some(false)));
    assert_eq!(args.ignored, vec!["--enable-external-lib-logs".to_string(), "--log-file-name x.log".to_string()]);
    assert_eq!(LogLevel::Warn.level_filter(), Some(log::LevelFilter::Warn));
    assert_eq!(LogLevel::Fatal.level_filter(), Some(log::LevelFilter::Error));
    assert_eq!(LogLevel::Unset.level_filter(), None);
    assert_eq!("Warning".parse::<LogLevel>(), Ok(LogLevel::Warn));
    let unknown = "loud".parse::<LogLevel>().unwrap_err();
    assert_eq!(unknown, UnknownLogLevel("loud".into()));
    assert_eq!(unknown.to_string(), "unknown log level 'loud' (debug, info, warn, error, fatal, unset)");
}

#[test]
fn params_files_and_overrides_keep_their_order() {
    let args =
        parse(&["p", "--ros-args", "--params-file", "a.yaml", "-p", "x:=1", "--params-file", "b.yaml", "-p", "x:=2"])
            .unwrap();
    let kinds: Vec<String> = args
        .param_sources
        .iter()
        .map(|s| match s {
            ParamSource::File(p) => p.display().to_string(),
            ParamSource::Override(o) => format!("{}={}", o.name, o.value),
        })
        .collect();
    assert_eq!(kinds, vec!["a.yaml", "x=1", "b.yaml", "x=2"]);
}

#[test]
fn errors_name_the_bad_argument() {
    let err = parse(&["p", "--ros-args", "-r", "foo"]).unwrap_err();
    assert_eq!(err.to_string(), "-r expects [NODE:]FROM:=TO, got 'foo': no ':=' in it");
    let err = parse(&["p", "--ros-args", "--remap"]).unwrap_err();
    assert_eq!(err.to_string(), "--remap expects [NODE:]FROM:=TO, but nothing follows it");
    let err = parse(&["p", "--ros-args", "-p", "plate.side=1"]).unwrap_err();
    assert!(err.to_string().starts_with("-p expects [NODE:]NAME:=VALUE, got 'plate.side=1'"), "{err}");
    let err = parse(&["p", "--ros-args", "-p", "a:=[1, 2.5]"]).unwrap_err();
    assert!(err.to_string().contains("'a:=[1, 2.5]'") && err.to_string().contains("one type"), "{err}");
    let err = parse(&["p", "--ros-args", "--params-file"]).unwrap_err();
    assert!(matches!(err, ArgsError::MissingValue { ref flag, .. } if flag == "--params-file"));
    let err = parse(&["p", "--ros-args", "--log-level", "loud"]).unwrap_err();
    assert!(err.to_string().contains("unknown log level 'loud'"), "{err}");
    let err = parse(&["p", "--ros-args", "--verbose"]).unwrap_err();
    assert_eq!(err, ArgsError::UnknownRosArg("--verbose".into()));
    assert!(err.to_string().contains("'--verbose'"));
    // A flag's value is taken as is, even if it looks like a flag.
    let err = parse(&["p", "--ros-args", "-r", "--"]).unwrap_err();
    assert!(matches!(err, ArgsError::BadValue { ref got, .. } if got == "--"), "{err}");
    // Flags outside a block are the program's business.
    assert!(parse(&["p", "-r", "foo", "--verbose"]).is_ok());
}

#[test]
fn remap_rule_parsing() {
    let r = RemapRule::parse("raw_scan:=/x").unwrap();
    assert_eq!(r, RemapRule { node: None, kind: RemapKind::Name, from: "raw_scan".into(), to: "/x".into() });
    let r = RemapRule::parse("tracer:raw_scan:=~/in").unwrap();
    assert_eq!((r.node.as_deref(), r.kind, r.to.as_str()), (Some("tracer"), RemapKind::Name, "~/in"));
    assert_eq!(RemapRule::parse("rostopic://a:=b").unwrap().kind, RemapKind::Topic);
    assert_eq!(RemapRule::parse("n:rosservice://a/b:=c").unwrap().kind, RemapKind::Service);
    assert_eq!(RemapRule::parse("__name:=x").unwrap().kind, RemapKind::NodeName);
    assert_eq!(RemapRule::parse("__ns:=/a/b/").unwrap().to, "/a/b");
    assert_eq!(RemapRule::parse("__ns:=/").unwrap().to, "/");
    for bad in [
        "foo",
        ":=x",
        "x:=",
        "__ns:=cell1",
        "__ns:=/1cell",
        "__node:=a/b",
        "__node:=9lives",
        "a b:=c",
        "a:=b c",
        "*:=x",
        "a/**:=x",
        "a:=\\1",
        "a//b:=c",
        "a:=b/",
        "bad-node:a:=b",
        "a:b:c:=d",
        "1a:=b",
    ] {
        assert!(RemapRule::parse(bad).is_err(), "{bad} should be rejected");
    }
}

#[test]
fn param_override_parsing() {
    let o = ParamOverride::parse("calibration.alpha0:=0.0349").unwrap();
    assert_eq!(o, ParamOverride { node: None, name: "calibration.alpha0".into(), value: ParamValue::Double(0.0349) });
    let o = ParamOverride::parse("tracer:resample_points:=0x10").unwrap();
    assert_eq!((o.node.as_deref(), o.value), (Some("tracer"), ParamValue::Integer(16)));
    let o = ParamOverride::parse("url:=a:=b").unwrap();
    assert_eq!(o.value, ParamValue::String("a:=b".into()));
    let o = ParamOverride::parse("output_frame_id:='1'").unwrap();
    assert_eq!(o.value, ParamValue::String("1".into()));
    for bad in ["x", "x=1", ":=1", "x:=", "a..b:=1", ".a:=1", "a-b:=1", "n-1:x:=1", "*:=1"] {
        assert!(ParamOverride::parse(bad).is_err(), "{bad} should be rejected");
    }
}

/// The `-p` rules of `tests/data/rcl_param_rules.json`, each read as that file says rcl
/// reads it (tests/interop checks the same file against rcl itself, through rclpy).
#[test]
fn param_rules_as_rcl_reads_them() {
    let cases: Vec<serde_json::Value> =
        serde_json::from_str(include_str!("../../../tests/data/rcl_param_rules.json")).unwrap();
    assert!(cases.len() > 20);
    for case in cases {
        let arg = case["arg"].as_str().unwrap();
        let parsed = RosArgs::parse(["node", "--ros-args", "-p", arg]);
        if case["error"].as_bool() == Some(true) {
            assert!(parsed.is_err(), "{arg}: rcl refuses it, we took it: {parsed:?}");
            continue;
        }
        let args = parsed.unwrap_or_else(|e| panic!("{arg}: rcl takes it, we refused: {e}"));
        if case["type"] == "not_set" {
            assert_eq!((args.param_sources.len(), args.ignored.len()), (0, 1), "{arg}: sets nothing");
            continue;
        }
        let o = args.param_overrides().next().unwrap().clone();
        assert_eq!(o.name, case["name"].as_str().unwrap(), "{arg}");
        let want = &case["value"];
        let ok = match (case["type"].as_str().unwrap(), &o.value) {
            ("bool", ParamValue::Bool(b)) => want.as_bool() == Some(*b),
            ("integer", ParamValue::Integer(i)) => want.as_i64() == Some(*i),
            ("double", ParamValue::Double(d)) => {
                want.as_f64() == Some(*d)
                    || (want == "inf" && *d == f64::INFINITY)
                    || (want == "-inf" && *d == f64::NEG_INFINITY)
            }
            ("string", ParamValue::String(s)) => want.as_str() == Some(s.as_str()),
            ("integer_array", ParamValue::IntegerArray(v)) => {
                want.as_array().unwrap().iter().map(|x| x.as_i64().unwrap()).eq(v.iter().copied())
            }
            ("double_array", ParamValue::DoubleArray(v)) => {
                want.as_array().unwrap().iter().map(|x| x.as_f64().unwrap()).eq(v.iter().copied())
            }
            ("string_array", ParamValue::StringArray(v)) => {
                want.as_array().unwrap().iter().map(|x| x.as_str().unwrap()).eq(v.iter().map(String::as_str))
            }
            ("bool_array", ParamValue::BoolArray(v)) => {
                want.as_array().unwrap().iter().map(|x| x.as_bool().unwrap()).eq(v.iter().copied())
            }
            _ => false,
        };
        assert!(ok, "{arg}: rcl reads {} {want}, we read {:?}", case["type"], o.value);
    }
}

#[test]
fn node_targeted_rules_apply_only_to_their_node() {
    let rules = [
        "p",
        "--ros-args",
        "-r",
        "other:__node:=wrong",
        "-r",
        "tracer_calibrator:__ns:=/cell2",
        "-r",
        "other:raw_scan:=/not_mine",
        "-r",
        "tracer_calibrator:raw_scan:=/mine",
        "-p",
        "other:model:=paper",
        "-p",
        "tracer_calibrator:model:=full",
    ];
    // a '/' is not allowed in a node prefix
    assert!(parse(&[&rules[..], &["-p", "cell2/tracer_calibrator:model:=bad"]].concat()).is_err());
    let args = parse(&rules).unwrap();
    let node = args.node_identity("tracer_calibrator", "/").unwrap();
    assert_eq!(node.fully_qualified_name(), "/cell2/tracer_calibrator");
    assert_eq!(args.resolve_topic("raw_scan", &node).unwrap(), "/mine");
    let values: Vec<_> = args.param_overrides_for(&node).map(|o| o.value.clone()).collect();
    assert_eq!(values, vec![ParamValue::String("full".into())]);
}

#[test]
fn the_first_matching_remap_wins() {
    let args =
        parse(&["p", "--ros-args", "-r", "__node:=a", "-r", "__node:=b", "-r", "x:=/one", "-r", "x:=/two"]).unwrap();
    let node = args.node_identity("d", "/").unwrap();
    assert_eq!(node.name, "a");
    assert_eq!(args.resolve_topic("x", &node).unwrap(), "/one");
}

#[test]
fn topic_remaps_target_the_final_node_name() {
    // As in rcl: topic rules compare their NODE: prefix with the remapped node name.
    let args = parse(&["p", "--ros-args", "-r", "__node:=tracer", "-r", "tracer:x:=/y", "-r", "orig:x:=/z"]).unwrap();
    let node = args.node_identity("orig", "/").unwrap();
    assert_eq!(args.resolve_topic("x", &node).unwrap(), "/y");
}
