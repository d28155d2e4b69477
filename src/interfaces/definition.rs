//! Interface definitions: the `.msg` / `.srv` texts, the one parser of them, and the
//! *complete* definitions rosbag2 stores.
//!
//! The syntax of the texts, and its one parser: [`super::syntax`].
//!
//! # Complete definitions (`ros2msg`)
//!
//! What rosbag2 stores in MCAP schema records and the `message_definitions` table: the type's
//! own text, then every type it depends on (recursively, each once), each preceded by a line
//! of 80 `=` and a line `MSG: pkg/msg/Type`:
//!
//! ```text
//! std_msgs/Header header
//! uint32 scan_id
//! ...
//!
//! ================================================================================
//! MSG: std_msgs/msg/Header
//! builtin_interfaces/Time stamp
//! string frame_id
//! ================================================================================
//! MSG: builtin_interfaces/msg/Time
//! ...
//! ```
//!
//! Dependencies follow rosbag2's order (`LocalMessageDefinitionSource`): depth first, the
//! dependencies of one type sorted by name, each type only at its first occurrence. (rosbag2
//! itself writes the dependency name as the field spells it, e.g. `MSG: std_msgs/Header`; the
//! rosbag2 format document, and this module, use the full `std_msgs/msg/Header`. Readers such
//! as rosbags and Foxglove accept both.)

use std::collections::BTreeSet;

pub use super::syntax::{Member, PRIMITIVES, Parsed, field_message_type, normalize_type, parse, split_srv};
use super::{InterfaceName, KNOWN, RosMsg};

/// Where a type's definition text is: a whole `.msg` file, or one half of a `.srv` file.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Definition {
    /// A message: the whole text.
    Msg(&'static str),
    /// A service's request: the `.srv` text before its `---` line.
    Request(&'static str),
    /// A service's response: the `.srv` text after its `---` line.
    Response(&'static str),
}

impl Definition {
    /// The definition text of the type itself.
    pub fn text(self) -> &'static str {
        match self {
            Definition::Msg(text) => text,
            Definition::Request(srv) => split_srv(srv).0,
            Definition::Response(srv) => split_srv(srv).1,
        }
    }
}

/// The line of 80 `=` that separates the definitions of a complete `ros2msg` definition.
pub const SEPARATOR: &str = "================================================================================";

/// The fields of a definition text, `(type, name)`, types normalized ([`normalize_type`]).
pub fn fields(text: &str, package: &str) -> Result<Vec<(String, String)>, String> {
    Ok(parse(text)?
        .members
        .into_iter()
        .filter(|m| m.constant.is_none())
        .map(|m| (normalize_type(m.ty, package), m.name.to_string()))
        .collect())
}

/// The constants of a definition text, `(type, name, value as written)`.
pub fn constants(text: &str) -> Result<Vec<(String, String, String)>, String> {
    Ok(parse(text)?
        .members
        .into_iter()
        .filter_map(|m| m.constant.map(|v| (m.ty.to_string(), m.name.to_string(), v.to_string())))
        .collect())
}

/// The definition text of a known type, by its ROS name (`pkg/msg/Type`).
pub fn text_of(ros_name: &str) -> Option<&'static str> {
    KNOWN.iter().find(|(name, _)| name.ros_name() == ros_name).map(|(_, definition)| definition.text())
}

/// The ROS names (`pkg/msg/Type`) of the types with known definitions.
pub fn known_types() -> impl Iterator<Item = String> {
    KNOWN.iter().filter(|(name, _)| name.kind == super::InterfaceKind::Msg).map(|(name, _)| name.ros_name())
}

/// The complete `ros2msg` definition of `T`: its text and those of all its dependencies.
/// `None` if one of its dependencies is unknown.
pub fn full_definition_of<T: RosMsg>() -> Option<String> {
    complete(T::NAME, T::DEFINITION.text())
}

/// The complete `ros2msg` definition of a known type, by its ROS name (`pkg/msg/Type`).
pub fn full_definition(ros_name: &str) -> Option<String> {
    let (name, definition) = KNOWN.iter().find(|(name, _)| name.ros_name() == ros_name)?;
    complete(*name, definition.text())
}

fn complete(name: InterfaceName, text: &str) -> Option<String> {
    fn append(text: &str, package: &str, seen: &mut BTreeSet<String>, out: &mut String) -> Option<()> {
        out.push_str(text);
        for dep in dependencies(text, package)? {
            if seen.insert(dep.clone()) {
                out.push('\n');
                out.push_str(SEPARATOR);
                out.push_str("\nMSG: ");
                out.push_str(&dep);
                out.push('\n');
                append(text_of(&dep)?, dep.split('/').next().unwrap_or(""), seen, out)?;
            }
        }
        Some(())
    }
    let mut out = String::new();
    append(text, name.package, &mut BTreeSet::new(), &mut out)?;
    Some(out)
}

/// The message types a definition text refers to, sorted, each once.
fn dependencies(text: &str, package: &str) -> Option<BTreeSet<String>> {
    let parsed = parse(text).ok()?;
    Some(
        parsed
            .members
            .iter()
            .filter(|m| m.constant.is_none())
            .filter_map(|m| field_message_type(m.ty, package))
            .collect(),
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::interfaces::{Contour, PolygonStamped};

    fn text(name: &str) -> &'static str {
        text_of(name).unwrap()
    }

    #[test]
    fn complete_definition_follows_rosbag2_order() {
        let sep = |name: &str| format!("\n{SEPARATOR}\nMSG: {name}\n");
        let (contour, point, header, time, polygon_stamped, polygon, point32) = (
            text("tracer_calib_msgs/msg/Contour"),
            text("geometry_msgs/msg/Point"),
            text("std_msgs/msg/Header"),
            text("builtin_interfaces/msg/Time"),
            text("geometry_msgs/msg/PolygonStamped"),
            text("geometry_msgs/msg/Polygon"),
            text("geometry_msgs/msg/Point32"),
        );
        assert_eq!(
            full_definition_of::<Contour>().unwrap(),
            // Contour's own Time (calibration_stamp) sorts first, so Header's is not repeated.
            format!(
                "{contour}{}{time}{}{point}{}{header}",
                sep("builtin_interfaces/msg/Time"),
                sep("geometry_msgs/msg/Point"),
                sep("std_msgs/msg/Header")
            )
        );
        assert_eq!(
            full_definition_of::<PolygonStamped>().unwrap(),
            format!(
                "{polygon_stamped}{}{polygon}{}{point32}{}{header}{}{time}",
                sep("geometry_msgs/msg/Polygon"),
                sep("geometry_msgs/msg/Point32"),
                sep("std_msgs/msg/Header"),
                sep("builtin_interfaces/msg/Time")
            )
        );
        assert_eq!(full_definition("geometry_msgs/msg/PolygonStamped"), full_definition_of::<PolygonStamped>());
        assert_eq!(full_definition("sensor_msgs/msg/Image"), None);
    }

    #[test]
    fn srv_halves_split_at_the_separator_line() {
        let srv: &'static str = "# request\nuint32 a\n---\nbool ok # reply\n";
        assert_eq!(Definition::Request(srv).text(), "# request\nuint32 a\n");
        assert_eq!(Definition::Response(srv).text(), "bool ok # reply\n");
        assert_eq!(Definition::Response("uint32 a\n").text(), "");
    }

    #[test]
    fn members_read_fields_defaults_constants_and_comments() {
        let text = "# A header\n# block\n\n# above a\nuint8 A=1 # c\nstring<=8 s \"x\"\nPoint32[<=3] p # first\n  # continued\n";
        let parsed = parse(text).unwrap();
        assert_eq!(parsed.header, ["A header", "block"]);
        let m = parsed.members;
        assert_eq!(
            m[0],
            Member { ty: "uint8", name: "A", constant: Some("1"), default: None, comments: vec!["above a", "c"] }
        );
        assert_eq!(
            m[1],
            Member { ty: "string<=8", name: "s", constant: None, default: Some("\"x\""), comments: vec![] }
        );
        assert_eq!(m[2].comments, ["first", "continued"]);
        assert!(parse("justoneword\n").unwrap_err().contains("line 1"));
        assert_eq!(normalize_type("Point32[<=3]", "geometry_msgs"), "geometry_msgs/msg/Point32[<=3]");
        assert_eq!(normalize_type("std_msgs/msg/Header", "x"), "std_msgs/msg/Header");
        assert_eq!(normalize_type("string<=8", "x"), "string<=8");
    }
}
