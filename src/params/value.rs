//! A ROS parameter value, and how a YAML scalar becomes one.

use std::fmt;

/// A ROS 2 parameter value (the types this node's parameters use, plus arrays so a
/// params file meant for other nodes still parses).
#[derive(Debug, Clone, PartialEq)]
pub enum ParamValue {
    Bool(bool),
    Integer(i64),
    Double(f64),
    String(String),
    BoolArray(Vec<bool>),
    IntegerArray(Vec<i64>),
    DoubleArray(Vec<f64>),
    StringArray(Vec<String>),
}

impl ParamValue {
    /// Type a YAML scalar as ROS's `rcl_yaml_param_parser` does: a quoted scalar is a
    /// string; otherwise `true/false` (also `yes/no`, `on/off`, in lower, Title or
    /// UPPER case) is a bool, a whole number (decimal, or `0x` hex) an integer, a
    /// number `strtod` reads (with `.inf`/`.nan` forms) a double, and anything else a
    /// string.
    pub fn from_yaml_scalar(text: &str, quoted: bool) -> ParamValue {
        if quoted {
            return ParamValue::String(text.to_string());
        }
        if let Some(b) = parse_bool(text) {
            return ParamValue::Bool(b);
        }
        if let Some(i) = parse_integer(text) {
            return ParamValue::Integer(i);
        }
        if let Some(d) = parse_double(text) {
            return ParamValue::Double(d);
        }
        ParamValue::String(text.to_string())
    }

    /// The ROS type name, for messages: `bool`, `integer`, `double`, `string`, ...
    pub fn type_name(&self) -> &'static str {
        match self {
            ParamValue::Bool(_) => "bool",
            ParamValue::Integer(_) => "integer",
            ParamValue::Double(_) => "double",
            ParamValue::String(_) => "string",
            ParamValue::BoolArray(_) => "bool array",
            ParamValue::IntegerArray(_) => "integer array",
            ParamValue::DoubleArray(_) => "double array",
            ParamValue::StringArray(_) => "string array",
        }
    }

    /// As a double; an integer is accepted too (`side: 1` means 1.0).
    pub fn as_f64(&self) -> Option<f64> {
        match *self {
            ParamValue::Double(d) => Some(d),
            ParamValue::Integer(i) => Some(i as f64),
            _ => None,
        }
    }

    /// The value as YAML that [`ParamValue::from_yaml_scalar`] (and ROS) read back as
    /// the same type: doubles always carry a `.` or an exponent, strings are quoted.
    pub fn to_yaml(&self) -> String {
        fn list<T>(v: &[T], f: impl Fn(&T) -> String) -> String {
            format!("[{}]", v.iter().map(f).collect::<Vec<_>>().join(", "))
        }
        match self {
            ParamValue::Bool(b) => b.to_string(),
            ParamValue::Integer(i) => i.to_string(),
            ParamValue::Double(d) => yaml_double(*d),
            ParamValue::String(s) => yaml_string(s),
            ParamValue::BoolArray(v) => list(v, |b| b.to_string()),
            ParamValue::IntegerArray(v) => list(v, |i| i.to_string()),
            ParamValue::DoubleArray(v) => list(v, |d| yaml_double(*d)),
            ParamValue::StringArray(v) => list(v, |s| yaml_string(s)),
        }
    }
}

impl fmt::Display for ParamValue {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ParamValue::String(s) => f.write_str(s),
            other => f.write_str(&other.to_yaml()),
        }
    }
}

fn parse_bool(t: &str) -> Option<bool> {
    match t {
        "true" | "True" | "TRUE" | "yes" | "Yes" | "YES" | "on" | "On" | "ON" => Some(true),
        "false" | "False" | "FALSE" | "no" | "No" | "NO" | "off" | "Off" | "OFF" => Some(false),
        _ => None,
    }
}

fn parse_integer(t: &str) -> Option<i64> {
    let (neg, body) = match t.as_bytes().first()? {
        b'-' => (true, &t[1..]),
        b'+' => (false, &t[1..]),
        _ => (false, t),
    };
    let magnitude = if let Some(hex) = body.strip_prefix("0x").or_else(|| body.strip_prefix("0X")) {
        i128::from_str_radix(hex, 16).ok()?
    } else {
        if body.is_empty() || !body.bytes().all(|b| b.is_ascii_digit()) {
            return None;
        }
        body.parse::<i128>().ok()?
    };
    i64::try_from(if neg { -magnitude } else { magnitude }).ok()
}

fn parse_double(t: &str) -> Option<f64> {
    let lower = t.to_ascii_lowercase();
    match lower.trim_start_matches(['+', '-']) {
        ".inf" | "inf" | "infinity" => {
            return Some(if lower.starts_with('-') { f64::NEG_INFINITY } else { f64::INFINITY });
        }
        ".nan" | "nan" => return Some(f64::NAN),
        _ => {}
    }
    // Rust's parser accepts what strtod does for plain decimal numbers, but also
    // "inf"/"nan" words handled above; reject anything with letters besides e/E.
    if t.bytes().any(|b| b.is_ascii_alphabetic() && b != b'e' && b != b'E') {
        return None;
    }
    t.parse::<f64>().ok()
}

/// A double that reads back as a double: `1.0`, `1.0e-6`, `.inf`, `.nan`.
pub fn yaml_double(d: f64) -> String {
    if d.is_nan() {
        return ".nan".into();
    }
    if d.is_infinite() {
        return if d > 0.0 { ".inf".into() } else { "-.inf".into() };
    }
    let s = format!("{d:?}"); // shortest round-trip form: "0.0349", "1e-6", "1.5e20"
    match s.find(['e', 'E']) {
        Some(e) if !s[..e].contains('.') => format!("{}.0{}", &s[..e], &s[e..]),
        _ => s,
    }
}

/// A double-quoted YAML string with the necessary escapes.
pub fn yaml_string(s: &str) -> String {
    let mut out = String::with_capacity(s.len() + 2);
    out.push('"');
    for c in s.chars() {
        match c {
            '"' => out.push_str("\\\""),
            '\\' => out.push_str("\\\\"),
            '\n' => out.push_str("\\n"),
            '\t' => out.push_str("\\t"),
            '\r' => out.push_str("\\r"),
            c if c.is_control() => out.push_str(&format!("\\u{:04x}", c as u32)),
            c => out.push(c),
        }
    }
    out.push('"');
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn scalars_are_typed_like_ros() {
        use ParamValue::*;
        assert_eq!(ParamValue::from_yaml_scalar("true", false), Bool(true));
        assert_eq!(ParamValue::from_yaml_scalar("Off", false), Bool(false));
        assert_eq!(ParamValue::from_yaml_scalar("true", true), String("true".into()));
        assert_eq!(ParamValue::from_yaml_scalar("400", false), Integer(400));
        assert_eq!(ParamValue::from_yaml_scalar("-0x10", false), Integer(-16));
        assert_eq!(ParamValue::from_yaml_scalar("1.0e-6", false), Double(1e-6));
        assert_eq!(ParamValue::from_yaml_scalar("1e-6", false), Double(1e-6));
        assert_eq!(ParamValue::from_yaml_scalar("-.inf", false), Double(f64::NEG_INFINITY));
        assert_eq!(ParamValue::from_yaml_scalar("full", false), String("full".into()));
        assert_eq!(ParamValue::from_yaml_scalar("99999999999999999999", false), Double(1e20));
    }

    #[test]
    fn written_values_read_back_as_the_same_type() {
        for v in [
            ParamValue::Double(0.0),
            ParamValue::Double(1e-6),
            ParamValue::Double(-2.5e21),
            ParamValue::Double(0.0349),
            ParamValue::Integer(-3),
            ParamValue::Bool(false),
            ParamValue::String("with \"quotes\" and \\ and: colon".into()),
            ParamValue::String("400".into()),
        ] {
            let yaml = v.to_yaml();
            let (text, quoted) = match yaml.strip_prefix('"') {
                Some(inner) => (inner.strip_suffix('"').unwrap().replace("\\\"", "\"").replace("\\\\", "\\"), true),
                None => (yaml.clone(), false),
            };
            assert_eq!(ParamValue::from_yaml_scalar(&text, quoted), v, "{yaml}");
        }
        assert_eq!(yaml_double(1e-6), "1.0e-6");
        assert_eq!(yaml_double(3.0), "3.0");
    }
}
