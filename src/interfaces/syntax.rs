//! The syntax of the ROS 2 interface language: one parser of `.msg` / `.srv` texts.
//!
//! A line is `TYPE NAME` (a field), `TYPE NAME DEFAULT` (a field with a default value, not on
//! the wire) or `TYPE NAME=VALUE` (a constant, not on the wire); `#` starts a comment; a
//! `.srv` text is the request, a line `---`, the response. A field type is a primitive
//! (`bool byte char float32 float64 int8 uint8 ... string wstring`, `string<=N`) or a message
//! (`Header` in the own package, `pkg/Type`, `pkg/msg/Type`), possibly followed by `[]`,
//! `[N]` or `[<=N]`.
//!
//! A definition without fields (`GetState_Request`, an empty `.msg`) gets the one field rosidl
//! gives it, `uint8 structure_needs_at_least_one_member` ([`PLACEHOLDER_FIELD`]): it is on the
//! wire (one octet) and in the type's description and hash.
//!
//! This file uses nothing but `std`: the build script (`build.rs`) includes it too, to
//! generate the message structs from the same texts with the same parser.

/// The primitive types of the interface language.
pub const PRIMITIVES: &[&str] = &[
    "bool", "byte", "char", "float32", "float64", "int8", "uint8", "int16", "uint16", "int32", "uint32", "int64",
    "uint64", "string", "wstring",
];

/// The field rosidl adds to a structure that has none (C and IDL have no empty structs).
pub const PLACEHOLDER_FIELD: &str = "structure_needs_at_least_one_member";

/// One line of a definition that declares something: a field or a constant.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Member<'a> {
    /// The type as written (`std_msgs/Header`, `uint32[]`, `Point32[]`).
    pub ty: &'a str,
    /// The field's or constant's name.
    pub name: &'a str,
    /// A constant's value (`Some`), or `None` for a field.
    pub constant: Option<&'a str>,
    /// A field's default value as written, if any (not on the wire).
    pub default: Option<&'a str>,
    /// Its comments: the comment lines right above it, the one behind it, and indented
    /// comment lines that continue that one; `#` and surrounding blanks stripped.
    pub comments: Vec<&'a str>,
}

/// A definition text read: the comment block it opens with, and its members in order.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Parsed<'a> {
    /// The comment lines at the very top, before anything else.
    pub header: Vec<&'a str>,
    /// Fields and constants, in order.
    pub members: Vec<Member<'a>>,
}

fn comment_of(line: &str) -> Option<&str> {
    line.split_once('#').map(|(_, c)| c.trim())
}

/// Reads a definition text (one part of a `.srv`: see [`split_srv`]); a `---` line is
/// skipped. A line that is not `TYPE NAME...` is an error naming it. A definition with no
/// field gets rosidl's [`PLACEHOLDER_FIELD`], a `uint8`, after its constants.
pub fn parse(text: &str) -> Result<Parsed<'_>, String> {
    let mut parsed = Parsed::default();
    let mut above: Vec<&str> = Vec::new();
    let mut at_top = true;
    for (number, raw) in text.lines().enumerate() {
        let code = raw.split('#').next().unwrap_or("").trim();
        if code.is_empty() || code == "---" {
            match comment_of(raw) {
                Some(c) if at_top => parsed.header.push(c),
                Some(c) if above.is_empty() && raw.starts_with(char::is_whitespace) => {
                    if let Some(last) = parsed.members.last_mut() {
                        last.comments.push(c);
                    }
                }
                Some(c) => above.push(c),
                None => {
                    at_top = false;
                    above.clear();
                }
            }
            continue;
        }
        at_top = false;
        let (ty, rest) = code
            .split_once(char::is_whitespace)
            .ok_or_else(|| format!("line {}: expected 'TYPE NAME', got '{code}'", number + 1))?;
        let rest = rest.trim();
        let mut comments = std::mem::take(&mut above);
        comments.extend(comment_of(raw));
        parsed.members.push(match rest.split_once('=') {
            Some((name, value)) => {
                Member { ty, name: name.trim(), constant: Some(value.trim()), default: None, comments }
            }
            None => {
                let (name, default) = match rest.split_once(char::is_whitespace) {
                    Some((name, default)) => (name, Some(default.trim())),
                    None => (rest, None),
                };
                Member { ty, name, constant: None, default, comments }
            }
        });
    }
    if parsed.members.iter().all(|m| m.constant.is_some()) {
        parsed.members.push(Member {
            ty: "uint8",
            name: PLACEHOLDER_FIELD,
            constant: None,
            default: None,
            comments: Vec::new(),
        });
    }
    Ok(parsed)
}

/// A `.srv` text's request and response parts (the response empty if there is no `---`).
pub fn split_srv(srv: &str) -> (&str, &str) {
    let mut at = 0;
    for line in srv.split_inclusive('\n') {
        if line.trim() == "---" {
            return (&srv[..at], &srv[at + line.len()..]);
        }
        at += line.len();
    }
    (srv, "")
}

/// A field type's base type and array suffix: `uint32[]` -> (`uint32`, `[]`).
pub fn split_array(field_type: &str) -> (&str, &str) {
    match field_type.find('[') {
        Some(i) => field_type.split_at(i),
        None => (field_type, ""),
    }
}

/// The message type a field type refers to, as `pkg/msg/Type`, or `None` for a primitive.
/// `package` resolves bare names (`Point32[]` in geometry_msgs).
pub fn field_message_type(field_type: &str, package: &str) -> Option<String> {
    let base = split_array(field_type).0;
    let base = base.split("<=").next().unwrap_or(base);
    if PRIMITIVES.contains(&base) {
        return None;
    }
    let parts: Vec<&str> = base.split('/').collect();
    Some(match parts.as_slice() {
        [name] => format!("{package}/msg/{name}"),
        [pkg, name] | [pkg, _, name] => format!("{pkg}/msg/{name}"),
        _ => base.to_string(),
    })
}

/// A field type with a message type written in full (`Point32[]` in geometry_msgs ->
/// `geometry_msgs/msg/Point32[]`); primitives as they are.
pub fn normalize_type(field_type: &str, package: &str) -> String {
    let suffix = split_array(field_type).1;
    match field_message_type(field_type, package) {
        Some(message) => format!("{message}{suffix}"),
        None => field_type.to_string(),
    }
}

/// The Rust type of a ROS primitive field type (`float64` -> `f64`, `string<=10` ->
/// `String`), if `ty` is one: what the generated structs hold, what their serde shape is.
pub fn rust_primitive(ty: &str) -> Option<&'static str> {
    Some(match ty {
        "bool" => "bool",
        "byte" | "char" | "uint8" => "u8",
        "int8" => "i8",
        "int16" => "i16",
        "uint16" => "u16",
        "int32" => "i32",
        "uint32" => "u32",
        "int64" => "i64",
        "uint64" => "u64",
        "float32" => "f32",
        "float64" => "f64",
        t if t == "string" || t.starts_with("string<=") => "String",
        _ => return None,
    })
}
