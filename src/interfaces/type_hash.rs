//! Type descriptions and RIHS01 type hashes (REP-2016), as rosidl computes them.
//!
//! Since Iron, every endpoint announces its type's hash (`typehash=RIHS01_<64 hex>;` in the
//! DDS USER_DATA; rmw_zenoh puts it in its key expressions), and `~/get_type_description`
//! answers with the description. Both come from the same [`Described`] value, built here from
//! the one copy of each `.msg` / `.srv` text ([`super::KNOWN`]):
//!
//! - a *type description* is the type's name and its fields, each with a type id
//!   (`type_description_interfaces/msg/FieldType`: `NESTED_TYPE` 1, `INT8` 2, `UINT8` 3, ...,
//!   `BOOLEAN` 15, `BYTE` 16, `STRING` 17, `BOUNDED_STRING` 21; plus 48 for a fixed array,
//!   96 for a bounded sequence, 144 for an unbounded one), a capacity (the array's size or
//!   bound), a string capacity (`string<=N`) and the nested type's name (`pkg/msg/Type`);
//!   constants are not part of it, and `char` is `uint8`, as rosidl reads `.msg` files;
//! - a service `pkg/srv/S` is described by three nested fields, `request_message`
//!   (`S_Request`), `response_message` (`S_Response`) and `event_message` (`S_Event`: `info`,
//!   a `service_msgs/msg/ServiceEventInfo`, and `request` / `response`, each a sequence of at
//!   most one);
//! - the hash is `RIHS01_` and the SHA-256 of the JSON of `{"type_description": ...,
//!   "referenced_type_descriptions": [...]}` (every type it uses, at any depth, sorted by
//!   name), as Python's `json.dumps(..., separators=(', ', ': '))` writes it, without the
//!   fields' default values.
//!
//! The tests check every hash against the `.json` files rosidl installs (the colcon build of
//! `msg/`, the standard packages' wheels).

use std::collections::BTreeMap;
use std::fmt::Write as _;

use sha2::{Digest, Sha256};

use super::definition::parse;
use super::syntax::{field_message_type, split_array};
use super::{KNOWN, RosMsg};

/// `type_description_interfaces/msg/FieldType`: the type of one field.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct FieldType {
    /// The type id (see the module docs).
    pub type_id: u8,
    /// A fixed array's size, or a bounded sequence's bound; 0 otherwise.
    pub capacity: u64,
    /// A bounded string's bound; 0 otherwise.
    pub string_capacity: u64,
    /// The nested type's name, `pkg/msg/Type`; empty for a primitive.
    pub nested_type_name: String,
}

/// `type_description_interfaces/msg/Field`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Field {
    pub name: String,
    pub field_type: FieldType,
    /// The default value as rosidl writes it (Python's `str` of the value: `True`, `0`,
    /// `1.0`); empty if none (not hashed).
    pub default_value: String,
}

/// `type_description_interfaces/msg/IndividualTypeDescription`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct TypeDescription {
    /// `pkg/msg/Type`, `pkg/srv/Service`, `pkg/srv/Service_Request`...
    pub type_name: String,
    pub fields: Vec<Field>,
}

/// `type_description_interfaces/msg/TypeDescription`: a type and every type it uses.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Described {
    pub type_description: TypeDescription,
    /// Every type the described one uses, at any depth, sorted by name.
    pub referenced_type_descriptions: Vec<TypeDescription>,
}

/// The type id of a primitive of the interface language (`char` is `uint8`, as in rosidl).
fn primitive_id(base: &str) -> Option<(u8, u64)> {
    if let Some(bound) = base.strip_prefix("string<=") {
        return Some((21, bound.parse().ok()?));
    }
    if let Some(bound) = base.strip_prefix("wstring<=") {
        return Some((22, bound.parse().ok()?));
    }
    Some((
        match base {
            "int8" => 2,
            "uint8" | "char" => 3,
            "int16" => 4,
            "uint16" => 5,
            "int32" => 6,
            "uint32" => 7,
            "int64" => 8,
            "uint64" => 9,
            "float32" => 10,
            "float64" => 11,
            "bool" => 15,
            "byte" => 16,
            "string" => 17,
            "wstring" => 18,
            _ => return None,
        },
        0,
    ))
}

/// The field type of a field type as written in a text of `package`.
fn field_type(ty: &str, package: &str) -> Result<FieldType, String> {
    let (base, suffix) = split_array(ty);
    let (mut type_id, string_capacity, nested_type_name) = match primitive_id(base) {
        Some((id, bound)) => (id, bound, String::new()),
        None => (1, 0, field_message_type(base, package).ok_or_else(|| format!("bad type '{ty}'"))?),
    };
    let inner = suffix.trim_start_matches('[').trim_end_matches(']');
    let capacity = if suffix.is_empty() {
        0
    } else if inner.is_empty() {
        type_id += 144;
        0
    } else if let Some(bound) = inner.strip_prefix("<=") {
        type_id += 96;
        bound.parse().map_err(|_| format!("bad bound in '{ty}'"))?
    } else {
        type_id += 48;
        inner.parse().map_err(|_| format!("bad array size in '{ty}'"))?
    };
    Ok(FieldType { type_id, capacity, string_capacity, nested_type_name })
}

fn nested(type_name: &str) -> FieldType {
    FieldType { type_id: 1, capacity: 0, string_capacity: 0, nested_type_name: type_name.to_string() }
}

fn field(name: &str, field_type: FieldType) -> Field {
    Field { name: name.to_string(), field_type, default_value: String::new() }
}

/// The description of one type by name, not of the types it uses: a message or service half
/// from its text ([`KNOWN`]), a service or a service's event message as rosidl makes them.
fn individual(type_name: &str) -> Result<TypeDescription, String> {
    let mut parts = type_name.split('/');
    let (package, kind, name) = match (parts.next(), parts.next(), parts.next()) {
        (Some(p), Some(k), Some(n)) => (p, k, n),
        _ => return Err(format!("'{type_name}' is not a type name pkg/msg/Type or pkg/srv/Service")),
    };
    if kind == "srv" {
        let service = |suffix: &str| format!("{package}/srv/{name}_{suffix}");
        if let Some(service_name) = name.strip_suffix("_Event") {
            let half = |suffix: &str| FieldType {
                type_id: 97,
                capacity: 1,
                string_capacity: 0,
                nested_type_name: format!("{package}/srv/{service_name}_{suffix}"),
            };
            return Ok(TypeDescription {
                type_name: type_name.to_string(),
                fields: vec![
                    field("info", nested("service_msgs/msg/ServiceEventInfo")),
                    field("request", half("Request")),
                    field("response", half("Response")),
                ],
            });
        }
        if !name.ends_with("_Request") && !name.ends_with("_Response") {
            return Ok(TypeDescription {
                type_name: type_name.to_string(),
                fields: vec![
                    field("request_message", nested(&service("Request"))),
                    field("response_message", nested(&service("Response"))),
                    field("event_message", nested(&service("Event"))),
                ],
            });
        }
    }
    let text = KNOWN
        .iter()
        .find(|(n, _)| n.ros_name() == type_name)
        .map(|(_, d)| d.text())
        .ok_or_else(|| format!("no definition of {type_name}"))?;
    let parsed = parse(text).map_err(|e| format!("{type_name}: {e}"))?;
    let fields = parsed
        .members
        .iter()
        .filter(|m| m.constant.is_none())
        .map(|m| {
            let field_type = field_type(m.ty, package).map_err(|e| format!("{type_name}: {e}"))?;
            let default_value = m.default.map(|d| rosidl_default(field_type.type_id, d)).unwrap_or_default();
            Ok(Field { name: m.name.to_string(), field_type, default_value })
        })
        .collect::<Result<Vec<_>, String>>()?;
    Ok(TypeDescription { type_name: type_name.to_string(), fields })
}

/// A scalar default value as rosidl writes it in a description: the value parsed, then
/// Python's `str` of it (`true` -> `True`, `1` of a float -> `1.0`). Other defaults (strings,
/// arrays) as written.
fn rosidl_default(type_id: u8, written: &str) -> String {
    let w = written.trim();
    match type_id {
        15 => match w {
            "true" | "True" | "1" => "True".to_string(),
            "false" | "False" | "0" => "False".to_string(),
            _ => w.to_string(),
        },
        2..=9 | 16 => w.parse::<i128>().map(|v| v.to_string()).unwrap_or_else(|_| w.to_string()),
        10 | 11 => w.parse::<f64>().map(python_float).unwrap_or_else(|_| w.to_string()),
        _ => w.to_string(),
    }
}

/// Python's `repr` of a float (`1.0`, `0.25`, `1e-05`, `1e+16`).
fn python_float(x: f64) -> String {
    if !x.is_finite() {
        return if x.is_nan() {
            "nan".into()
        } else if x > 0.0 {
            "inf".into()
        } else {
            "-inf".into()
        };
    }
    let a = x.abs();
    if a == 0.0 || (1e-4..1e16).contains(&a) {
        let s = format!("{x}");
        if s.contains('.') { s } else { format!("{s}.0") }
    } else {
        // Rust writes `1e-5`, Python `1e-05`: at least two exponent digits, with a sign.
        let s = format!("{x:e}");
        let (mantissa, exp) = s.split_once('e').expect("an exponent");
        let (sign, digits) = exp.strip_prefix('-').map_or(("+", exp), |d| ("-", d));
        format!("{mantissa}e{sign}{digits:0>2}")
    }
}

/// The description of `type_name` (`pkg/msg/Type`, `pkg/srv/Service`, a service half) and of
/// every type it uses. An unknown type, or one that uses one, is an error naming it.
pub fn describe(type_name: &str) -> Result<Described, String> {
    let type_description = individual(type_name)?;
    let mut referenced = BTreeMap::new();
    let mut todo: Vec<String> = nested_names(&type_description);
    while let Some(name) = todo.pop() {
        if referenced.contains_key(&name) {
            continue;
        }
        let d = individual(&name)?;
        todo.extend(nested_names(&d));
        referenced.insert(name, d);
    }
    Ok(Described { type_description, referenced_type_descriptions: referenced.into_values().collect() })
}

/// The description of `T` (for a service half, of that message alone: use [`describe`] with
/// the service's name for the service).
pub fn describe_type<T: RosMsg>() -> Result<Described, String> {
    describe(&T::NAME.ros_name())
}

fn nested_names(d: &TypeDescription) -> Vec<String> {
    d.fields
        .iter()
        .filter(|f| !f.field_type.nested_type_name.is_empty())
        .map(|f| f.field_type.nested_type_name.clone())
        .collect()
}

/// A JSON string as Python's `json.dumps` writes it with `ensure_ascii=True`.
fn json_string(out: &mut String, s: &str) {
    out.push('"');
    for c in s.chars() {
        match c {
            '"' => out.push_str("\\\""),
            '\\' => out.push_str("\\\\"),
            '\n' => out.push_str("\\n"),
            '\r' => out.push_str("\\r"),
            '\t' => out.push_str("\\t"),
            c if (c as u32) < 0x20 || (c as u32) > 0x7e => {
                let mut buf = [0u16; 2];
                for unit in c.encode_utf16(&mut buf) {
                    write!(out, "\\u{unit:04x}").expect("writing to a String");
                }
            }
            c => out.push(c),
        }
    }
    out.push('"');
}

fn json_description(out: &mut String, d: &TypeDescription) {
    out.push_str("{\"type_name\": ");
    json_string(out, &d.type_name);
    out.push_str(", \"fields\": [");
    for (i, f) in d.fields.iter().enumerate() {
        if i > 0 {
            out.push_str(", ");
        }
        out.push_str("{\"name\": ");
        json_string(out, &f.name);
        let t = &f.field_type;
        write!(
            out,
            ", \"type\": {{\"type_id\": {}, \"capacity\": {}, \"string_capacity\": {}, \"nested_type_name\": ",
            t.type_id, t.capacity, t.string_capacity
        )
        .expect("writing to a String");
        json_string(out, &t.nested_type_name);
        out.push_str("}}");
    }
    out.push_str("]}");
}

/// What is hashed: the description as rosidl serializes it for the hash (no default values).
pub fn hashed_json(d: &Described) -> String {
    let mut out = String::from("{\"type_description\": ");
    json_description(&mut out, &d.type_description);
    out.push_str(", \"referenced_type_descriptions\": [");
    for (i, r) in d.referenced_type_descriptions.iter().enumerate() {
        if i > 0 {
            out.push_str(", ");
        }
        json_description(&mut out, r);
    }
    out.push_str("]}");
    out
}

/// The RIHS01 hash of a description: version 1 and the SHA-256 of [`hashed_json`].
pub fn hash(d: &Described) -> [u8; 32] {
    Sha256::digest(hashed_json(d).as_bytes()).into()
}

/// The hash as rmw writes it: `RIHS01_` and 64 lower-case hex digits.
pub fn hash_string(hash: &[u8; 32]) -> String {
    let mut out = String::from("RIHS01_");
    for b in hash {
        write!(out, "{b:02x}").expect("writing to a String");
    }
    out
}

/// The `RIHS01_...` hash of a type by name (`pkg/msg/Type`, `pkg/srv/Service`).
pub fn type_hash(type_name: &str) -> Result<String, String> {
    Ok(hash_string(&hash(&describe(type_name)?)))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::interfaces::{InterfaceKind, InterfaceName};

    #[test]
    fn field_types_follow_rosidl() {
        let t = |ty: &str| {
            let f = field_type(ty, "geometry_msgs").unwrap();
            (f.type_id, f.capacity, f.string_capacity, f.nested_type_name)
        };
        assert_eq!(t("uint32[]"), (151, 0, 0, String::new()));
        assert_eq!(t("char[16]"), (51, 16, 0, String::new()));
        assert_eq!(t("byte"), (16, 0, 0, String::new()));
        assert_eq!(t("string<=8[<=3]"), (21 + 96, 3, 8, String::new()));
        assert_eq!(t("Point32[]"), (145, 0, 0, "geometry_msgs/msg/Point32".to_string()));
        assert_eq!(t("std_msgs/Header"), (1, 0, 0, "std_msgs/msg/Header".to_string()));
        assert!(describe("nope").is_err());
        assert!(describe("sensor_msgs/msg/Image").unwrap_err().contains("no definition of sensor_msgs/msg/Image"));
    }

    #[test]
    fn defaults_are_written_as_rosidl_writes_them() {
        assert_eq!(rosidl_default(15, "true"), "True");
        assert_eq!(rosidl_default(15, "false"), "False");
        assert_eq!(rosidl_default(3, "0"), "0");
        assert_eq!(rosidl_default(2, "-2"), "-2");
        assert_eq!(rosidl_default(11, "1"), "1.0");
        assert_eq!(rosidl_default(11, "0.0"), "0.0");
        assert_eq!(rosidl_default(10, "0.25"), "0.25");
        assert_eq!(python_float(1e-5), "1e-05");
        assert_eq!(python_float(2e16), "2e+16");
        // In a description: type_description_interfaces/msg/FieldType's type_id, 0.
        let d = describe("type_description_interfaces/msg/FieldType").unwrap();
        assert_eq!(d.type_description.fields[0].default_value, "0");
    }

    #[test]
    fn the_hashed_json_is_pythons() {
        let d = describe("builtin_interfaces/msg/Time").unwrap();
        assert_eq!(
            hashed_json(&d),
            "{\"type_description\": {\"type_name\": \"builtin_interfaces/msg/Time\", \"fields\": [\
             {\"name\": \"sec\", \"type\": {\"type_id\": 6, \"capacity\": 0, \"string_capacity\": 0, \"nested_type_name\": \"\"}}, \
             {\"name\": \"nanosec\", \"type\": {\"type_id\": 7, \"capacity\": 0, \"string_capacity\": 0, \"nested_type_name\": \"\"}}]}, \
             \"referenced_type_descriptions\": []}"
        );
        let mut s = String::new();
        json_string(&mut s, "a\"b\\c\u{e9}\u{1F600}");
        assert_eq!(s, "\"a\\\"b\\\\c\\u00e9\\ud83d\\ude00\"");
    }

    /// The `.json` rosidl installs for `type_name` (the wheels' standard packages, the colcon
    /// build of `msg/` that `tests/interop/setup.sh` makes, bond_core's `bond` that
    /// `tests/interop/bond.sh` builds), if there.
    fn rosidl_json(type_name: &str) -> Option<(std::path::PathBuf, String)> {
        let mut parts = type_name.splitn(3, '/');
        let (package, kind, name) = (parts.next()?, parts.next()?, parts.next()?);
        let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("target/ros");
        for distro in ["kilted", "jazzy"] {
            for prefix in ["venv", "msgs_install", "bond_install"] {
                let path = root.join(distro).join(prefix).join(format!("share/{package}/{kind}/{name}.json"));
                if let Ok(text) = std::fs::read_to_string(&path) {
                    return Some((path, text));
                }
            }
        }
        None
    }

    /// Every hash equals the one rosidl generated for the same type (the `type_hashes` of its
    /// `.json`; `tests/interop/setup.sh` and `bond.sh` install them, as `scripts/test.sh`
    /// runs them first).
    #[test]
    #[ignore = "needs rosidl's .json files (tests/interop/setup.sh); scripts/test.sh runs it"]
    fn hashes_equal_rosidls() {
        let mut names: Vec<InterfaceName> = KNOWN.iter().map(|(n, _)| *n).collect();
        names.push(InterfaceName::srv("tracer_calib_msgs", "Calibrate"));
        names.push(InterfaceName::srv("type_description_interfaces", "GetTypeDescription"));
        names.push(InterfaceName::srv("rcl_interfaces", "GetParameters"));
        // An empty request: rosidl's placeholder field.
        names.push(InterfaceName::srv("lifecycle_msgs", "GetState"));
        names.push(InterfaceName::srv("lifecycle_msgs", "GetAvailableTransitions"));
        let mut described = 0;
        for name in names {
            let type_name = name.ros_name();
            let (json_name, ours) = match name.kind {
                // A service half's hash is listed in its service's file.
                InterfaceKind::Srv if type_name.ends_with("_Request") || type_name.ends_with("_Response") => {
                    (type_name.rsplit_once('_').map(|(s, _)| s.to_string()).unwrap(), type_hash(&type_name).unwrap())
                }
                _ => (type_name.clone(), type_hash(&type_name).unwrap()),
            };
            let (path, text) = rosidl_json(&json_name).unwrap_or_else(|| {
                panic!("no rosidl .json of {json_name} under target/ros: run tests/interop/setup.sh first")
            });
            let json: serde_json::Value = serde_json::from_str(&text).unwrap();
            let theirs = json["type_hashes"]
                .as_array()
                .unwrap()
                .iter()
                .find(|h| h["type_name"] == type_name.as_str())
                .unwrap_or_else(|| panic!("{}: no hash of {type_name}", path.display()))["hash_string"]
                .as_str()
                .unwrap()
                .to_string();
            assert_eq!(ours, theirs, "{type_name} (rosidl: {})", path.display());
            // The whole description, default values included, is rosidl's too.
            if json_name == type_name {
                let d = describe(&type_name).unwrap();
                let as_json = |t: &TypeDescription| {
                    serde_json::json!({
                        "type_name": t.type_name,
                        "fields": t.fields.iter().map(|f| serde_json::json!({
                            "name": f.name,
                            "type": {
                                "type_id": f.field_type.type_id,
                                "capacity": f.field_type.capacity,
                                "string_capacity": f.field_type.string_capacity,
                                "nested_type_name": f.field_type.nested_type_name,
                            },
                            "default_value": f.default_value,
                        })).collect::<Vec<_>>(),
                    })
                };
                let ours = serde_json::json!({
                    "type_description": as_json(&d.type_description),
                    "referenced_type_descriptions":
                        d.referenced_type_descriptions.iter().map(as_json).collect::<Vec<_>>(),
                });
                assert_eq!(ours, json["type_description_msg"], "{type_name}: description");
                described += 1;
            }
        }
        assert!(described >= 30, "{described} descriptions compared");
    }
}
