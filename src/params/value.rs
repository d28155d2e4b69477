//! A ROS parameter value, how a YAML scalar or a `-p` value becomes one, and how one is
//! written back as YAML (typed as ROS 2's `rcl_yaml_param_parser` does).

use std::fmt;

use crate::c_number;

use yaml_rust2::parser::{Event, MarkedEventReceiver, Parser};
use yaml_rust2::scanner::{Marker, TScalarStyle};

/// A ROS 2 parameter value, as a params file or a `-p` override can give it.
///
/// (ROS also has byte arrays, which YAML cannot express; they are not needed here.)
#[derive(Debug, Clone, PartialEq)]
pub enum ParamValue {
    /// `bool`.
    Bool(bool),
    /// `integer` (64-bit).
    Integer(i64),
    /// `double`.
    Double(f64),
    /// `string`.
    String(String),
    /// `bool_array`.
    BoolArray(Vec<bool>),
    /// `integer_array`.
    IntegerArray(Vec<i64>),
    /// `double_array`.
    DoubleArray(Vec<f64>),
    /// `string_array`.
    StringArray(Vec<String>),
}

/// YAML 1.1 booleans that `rcl_yaml_param_parser` accepts (plain scalars only).
const YAML_TRUE: &[&str] = &["Y", "y", "yes", "Yes", "YES", "true", "True", "TRUE", "on", "On", "ON"];
const YAML_FALSE: &[&str] = &["N", "n", "no", "No", "NO", "false", "False", "FALSE", "off", "Off", "OFF"];
/// YAML's special floats that `rcl_yaml_param_parser` accepts.
const YAML_SPECIAL_FLOATS: &[&str] =
    &[".nan", ".NaN", ".NAN", ".inf", ".Inf", ".INF", "+.inf", "+.Inf", "+.INF", "-.inf", "-.Inf", "-.INF"];

impl ParamValue {
    /// Types one YAML scalar the way ROS 2's `rcl_yaml_param_parser` does (params files and
    /// `-p` overrides).
    ///
    /// `text` is the scalar's content (already unquoted and unescaped by the YAML reader);
    /// `quoted` is true for single- or double-quoted scalars, and should also be passed as true
    /// for a scalar tagged `!!str`. Then:
    ///
    /// 1. quoted -> [`ParamValue::String`];
    /// 2. `y Y yes Yes YES true True TRUE on On ON` -> `Bool(true)`,
    ///    `n N no No NO false False FALSE off Off OFF` -> `Bool(false)`;
    /// 3. what C's `strtoll(text, &end, 0)` reads completely and without overflow ->
    ///    `Integer`: decimal `-12`, hex `0x1F`, and **octal** `010` (= 8);
    /// 4. `.inf .Inf .INF` (with `+`/`-`), `.nan .NaN .NAN`, and what C's `strtod` reads
    ///    completely without overflow or underflow -> `Double`: `1.5`, `1e-6`, `5.`, `.5`,
    ///    `inf`, `nan`, `0x1p3`, and also `08` (not octal, so strtoll stops; strtod reads 8.0);
    /// 5. anything else -> `String` (`1e999` too: strtod overflows).
    ///
    /// An empty plain scalar gives `String("")`; rcl rejects it ("No value"), so a params-file
    /// reader should too. YAML `null`/`~` are not special for rcl: they give strings.
    pub fn from_yaml_scalar(text: &str, quoted: bool) -> ParamValue {
        if quoted {
            return ParamValue::String(text.to_string());
        }
        if YAML_TRUE.contains(&text) {
            return ParamValue::Bool(true);
        }
        if YAML_FALSE.contains(&text) {
            return ParamValue::Bool(false);
        }
        if let Some(i) = c_number::strtoll(text) {
            return ParamValue::Integer(i);
        }
        if YAML_SPECIAL_FLOATS.contains(&text) {
            let magnitude = if text.to_ascii_lowercase().ends_with("nan") { f64::NAN } else { f64::INFINITY };
            return ParamValue::Double(if text.starts_with('-') { -magnitude } else { magnitude });
        }
        if let Some(d) = c_number::strtod(text) {
            return ParamValue::Double(d);
        }
        ParamValue::String(text.to_string())
    }

    /// Parses the value of a `-p NAME:=VALUE` override: a one-line YAML value, as rcl reads it.
    ///
    /// Accepts a plain, `'single'`- or `"double"`-quoted scalar (optionally tagged `!!str`,
    /// which makes it a string), or a flow sequence `[a, b, c]` whose items all have the same
    /// type (ROS has no mixed arrays; `[1, 2.5]` is an error, write `[1.0, 2.5]`). A trailing
    /// ` # comment` is ignored. Mappings, nested sequences, anchors and block scalars are errors,
    /// as are an empty plain value and an empty sequence (its type is unknown).
    ///
    /// The YAML is read by `yaml_rust2`'s parser (as rcl reads it with libyaml); its scalars
    /// are typed by rcl's rules ([`ParamValue::from_yaml_scalar`]), not YAML 1.2's core
    /// schema, which `yaml_rust2`'s loader follows (`010` is 8 for rcl, `yes` a bool).
    pub fn parse_yaml(text: &str) -> Result<ParamValue, YamlValueError> {
        /// The parser's events, in order.
        struct Events(Vec<Event>);
        impl MarkedEventReceiver for Events {
            fn on_event(&mut self, event: Event, _: Marker) {
                self.0.push(event);
            }
        }
        use YamlValueError::NotAValue;
        let mut events = Events(Vec::new());
        Parser::new_from_str(text)
            .load(&mut events, true)
            .map_err(|e| YamlValueError::NotYaml(e.info().to_string()))?;
        let body: Vec<Event> = events
            .0
            .into_iter()
            .filter(|e| !matches!(e, Event::StreamStart | Event::StreamEnd | Event::DocumentStart | Event::DocumentEnd))
            .collect();
        let empty = NotAValue("empty value (write '' for an empty string)");
        match body.as_slice() {
            [] => Err(empty),
            [Event::Scalar(text, TScalarStyle::Plain, ..)] if text.is_empty() => Err(empty),
            [scalar @ Event::Scalar(..)] => yaml_scalar(scalar),
            // rcl reads a block sequence (`- 1`) as no value: only `[a, b]` is one.
            [Event::SequenceStart(..), ..] if !text.trim_start().starts_with('[') => {
                Err(NotAValue("a sequence is written [a, b, c]"))
            }
            [Event::SequenceStart(anchor, _), items @ .., Event::SequenceEnd] => {
                if *anchor != 0 {
                    return Err(NotAValue("YAML anchors are not supported in parameter values"));
                }
                if items.is_empty() {
                    return Err(NotAValue("an empty sequence has no type"));
                }
                let values = items.iter().map(yaml_scalar).collect::<Result<Vec<_>, _>>()?;
                ParamValue::array_of(values)
                    .ok_or(NotAValue("an array must hold scalars of one type (write [1.0, 2.5], not [1, 2.5])"))
            }
            [Event::MappingStart(..), ..] => Err(NotAValue("a YAML mapping is not a parameter value")),
            [Event::Alias(_)] => Err(NotAValue("YAML aliases are not supported in parameter values")),
            _ => Err(NotAValue("expected one scalar, or a sequence of scalars [a, b, c]")),
        }
    }

    /// The array of `values`, all of one type (integers among doubles are not: ROS has no
    /// mixed arrays); `None` if they are not. No value: an empty string array.
    pub fn array_of(values: Vec<ParamValue>) -> Option<ParamValue> {
        let all = |f: fn(&ParamValue) -> bool| values.iter().all(f);
        Some(if values.is_empty() {
            ParamValue::StringArray(Vec::new())
        } else if all(|v| matches!(v, ParamValue::Bool(_))) {
            ParamValue::BoolArray(values.iter().map(|v| matches!(v, ParamValue::Bool(true))).collect())
        } else if all(|v| matches!(v, ParamValue::Integer(_))) {
            ParamValue::IntegerArray(
                values.iter().filter_map(|v| if let ParamValue::Integer(i) = v { Some(*i) } else { None }).collect(),
            )
        } else if all(|v| matches!(v, ParamValue::Double(_))) {
            ParamValue::DoubleArray(values.iter().filter_map(ParamValue::as_f64).collect())
        } else if all(|v| matches!(v, ParamValue::String(_))) {
            ParamValue::StringArray(
                values.into_iter().filter_map(|v| if let ParamValue::String(s) = v { Some(s) } else { None }).collect(),
            )
        } else {
            return None;
        })
    }

    /// Writes the value as one-line YAML that [`ParamValue::parse_yaml`], rcl and other YAML
    /// readers (YAML 1.1's PyYAML too) give back unchanged: doubles always carry a `.`, and a
    /// signed exponent if any (`1.0`, `1.0e-6`, `1.5e+20`, `.inf`, `.nan`), strings are quoted whenever they would otherwise read as something else,
    /// arrays are flow sequences. For writing params files.
    pub fn to_yaml(&self) -> String {
        match self {
            ParamValue::Bool(b) => b.to_string(),
            ParamValue::Integer(i) => i.to_string(),
            ParamValue::Double(d) => yaml_double(*d),
            ParamValue::String(s) => yaml_string(s),
            ParamValue::BoolArray(v) => yaml_list(v.iter().map(bool::to_string)),
            ParamValue::IntegerArray(v) => yaml_list(v.iter().map(i64::to_string)),
            ParamValue::DoubleArray(v) => yaml_list(v.iter().map(|d| yaml_double(*d))),
            ParamValue::StringArray(v) => yaml_list(v.iter().map(|s| yaml_string(s))),
        }
    }

    /// An array with no element (of any element type).
    pub fn is_empty_array(&self) -> bool {
        match self {
            ParamValue::BoolArray(v) => v.is_empty(),
            ParamValue::IntegerArray(v) => v.is_empty(),
            ParamValue::DoubleArray(v) => v.is_empty(),
            ParamValue::StringArray(v) => v.is_empty(),
            _ => false,
        }
    }

    /// The ROS parameter type name, as rclcpp prints it (`bool`, `integer`, `double`, `string`,
    /// `bool_array`, ...).
    pub fn type_name(&self) -> &'static str {
        match self {
            ParamValue::Bool(_) => "bool",
            ParamValue::Integer(_) => "integer",
            ParamValue::Double(_) => "double",
            ParamValue::String(_) => "string",
            ParamValue::BoolArray(_) => "bool_array",
            ParamValue::IntegerArray(_) => "integer_array",
            ParamValue::DoubleArray(_) => "double_array",
            ParamValue::StringArray(_) => "string_array",
        }
    }
}

impl fmt::Display for ParamValue {
    /// Same as [`ParamValue::to_yaml`].
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.to_yaml())
    }
}

impl From<ParamValue> for ros2_client::ParameterValue {
    fn from(value: ParamValue) -> Self {
        use ros2_client::ParameterValue as P;
        match value {
            ParamValue::Bool(b) => P::Boolean(b),
            ParamValue::Integer(i) => P::Integer(i),
            ParamValue::Double(d) => P::Double(d),
            ParamValue::String(s) => P::String(s),
            ParamValue::BoolArray(v) => P::BooleanArray(v),
            ParamValue::IntegerArray(v) => P::IntegerArray(v),
            ParamValue::DoubleArray(v) => P::DoubleArray(v),
            ParamValue::StringArray(v) => P::StringArray(v),
        }
    }
}

pub(crate) fn yaml_double(d: f64) -> String {
    if d.is_nan() {
        ".nan".into()
    } else if d.is_infinite() {
        if d > 0.0 { ".inf".into() } else { "-.inf".into() }
    } else {
        // Debug is the shortest round-trip form and always has '.' or 'e': "1.0", "1e-6",
        // "1.5e20". YAML 1.1 (PyYAML: `ros2 param load`, launch's YAML) reads a number as a
        // float only with a '.' in the mantissa and a signed exponent, and "1e-6" as a
        // string: written "1.0e-6", "1.5e+20", as `ros2 param dump` writes them.
        let shortest = format!("{d:?}");
        match shortest.split_once('e') {
            None => shortest,
            Some((mantissa, exponent)) => {
                let point = if mantissa.contains('.') { "" } else { ".0" };
                let sign = if exponent.starts_with('-') { "" } else { "+" };
                format!("{mantissa}{point}e{sign}{exponent}")
            }
        }
    }
}

pub(crate) fn yaml_string(s: &str) -> String {
    let plain_chars = |c: char| c.is_ascii_alphanumeric() || matches!(c, '_' | '.' | '/' | '-' | '+');
    let reads_back = ParamValue::from_yaml_scalar(s, false) == ParamValue::String(s.to_string());
    let yaml_null = matches!(s, "~" | "null" | "Null" | "NULL");
    if !s.is_empty() && s.chars().all(plain_chars) && reads_back && !yaml_null && !s.starts_with('-') {
        return s.to_string();
    }
    if s.chars().any(|c| c.is_control()) {
        let mut out = String::from("\"");
        for c in s.chars() {
            match c {
                '"' => out.push_str("\\\""),
                '\\' => out.push_str("\\\\"),
                '\n' => out.push_str("\\n"),
                '\t' => out.push_str("\\t"),
                '\r' => out.push_str("\\r"),
                c if c.is_control() => out.push_str(&format!("\\u{:04x}", u32::from(c))),
                c => out.push(c),
            }
        }
        out.push('"');
        return out;
    }
    format!("'{}'", s.replace('\'', "''"))
}

/// Why a `-p` value was not read ([`ParamValue::parse_yaml`]): not YAML, or YAML that is
/// no parameter value.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum YamlValueError {
    /// Not YAML: the parser's words.
    #[error("not valid YAML: {0}")]
    NotYaml(String),
    /// YAML that is no parameter value (empty, a mapping, a block scalar, an array of
    /// mixed types, ...): why.
    #[error("{0}")]
    NotAValue(&'static str),
}

fn yaml_list(items: impl Iterator<Item = String>) -> String {
    format!("[{}]", items.collect::<Vec<_>>().join(", "))
}

/// One scalar event as a parameter value: typed as rcl types it ([`ParamValue::from_yaml_scalar`]),
/// quoted or tagged `!!str` a string; block scalars (`|`, `>`) and anchors refused.
fn yaml_scalar(event: &Event) -> Result<ParamValue, YamlValueError> {
    use YamlValueError::NotAValue;
    let Event::Scalar(text, style, anchor, tag) = event else {
        return Err(NotAValue("a sequence must hold scalars (no nested sequence or mapping)"));
    };
    if *anchor != 0 {
        return Err(NotAValue("YAML anchors are not supported in parameter values"));
    }
    let quoted = match style {
        TScalarStyle::Plain => false,
        TScalarStyle::SingleQuoted | TScalarStyle::DoubleQuoted => true,
        _ => return Err(NotAValue("a block scalar (| or >) is not a one-line value")),
    };
    let str_tag =
        tag.as_ref().is_some_and(|t| t.suffix == "str" && (t.handle == "!!" || t.handle == "tag:yaml.org,2002:"));
    Ok(ParamValue::from_yaml_scalar(text, quoted || str_tag))
}

impl ParamValue {
    /// As a double; an integer is accepted too (`side: 1` means 1.0).
    pub fn as_f64(&self) -> Option<f64> {
        match *self {
            ParamValue::Double(d) => Some(d),
            ParamValue::Integer(i) => Some(i as f64),
            _ => None,
        }
    }
}
