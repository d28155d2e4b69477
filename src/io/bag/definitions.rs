//! Message definitions in `ros2msg` form, as rosbag2 stores them in MCAP schema records and in
//! the `message_definitions` table.
//!
//! A *complete* definition is the type's own `.msg` text, then every type it depends on
//! (recursively, each once), each preceded by a line of 80 `=` and a line `MSG: pkg/msg/Type`:
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
//! rosbag2 format document, and this module, use the full `std_msgs/msg/Header`. Readers such as
//! rosbags and Foxglove accept both.)
//!
//! The texts of our own messages come from `msg/msg/*.msg`; those of the standard messages are
//! the files of ROS 2 Kilted, copied verbatim.

use std::collections::BTreeSet;

/// The line of 80 `=` that separates the definitions of a complete `ros2msg` definition.
pub const SEPARATOR: &str = "================================================================================";

/// `tracer_calib_msgs/msg/RawScan`, the text of `msg/msg/RawScan.msg`.
pub const RAW_SCAN_MSG: &str = include_str!("../../../msg/msg/RawScan.msg");

/// `tracer_calib_msgs/msg/Contour`, the text of `msg/msg/Contour.msg`.
pub const CONTOUR_MSG: &str = include_str!("../../../msg/msg/Contour.msg");

/// `tracer_calib_msgs/msg/Calibration`, the text of `msg/msg/Calibration.msg`.
pub const CALIBRATION_MSG: &str = include_str!("../../../msg/msg/Calibration.msg");

/// `std_msgs/msg/Header` (ROS 2 Kilted).
pub const HEADER_MSG: &str = "\
# Standard metadata for higher-level stamped data types.
# This is generally used to communicate timestamped data
# in a particular coordinate frame.

# Two-integer timestamp that is expressed as seconds and nanoseconds.
builtin_interfaces/Time stamp

# Transform frame with which this data is associated.
string frame_id
";

/// `builtin_interfaces/msg/Time` (ROS 2 Kilted).
pub const TIME_MSG: &str = "\
# This message communicates ROS Time defined here:
# https://design.ros2.org/articles/clock_and_time.html

# The seconds component, valid over all int32 values.
int32 sec

# The nanoseconds component, valid in the range [0, 1e9).
uint32 nanosec
";

/// `geometry_msgs/msg/Point` (ROS 2 Kilted).
pub const POINT_MSG: &str = "\
# This contains the position of a point in free space
float64 x
float64 y
float64 z
";

/// `geometry_msgs/msg/Point32` (ROS 2 Kilted).
pub const POINT32_MSG: &str = "\
# This contains the position of a point in free space(with 32 bits of precision).
# It is recommended to use Point wherever possible instead of Point32.
#
# This recommendation is to promote interoperability.
#
# This message is designed to take up less space when sending
# lots of points at once, as in the case of a PointCloud.

float32 x
float32 y
float32 z
";

/// `geometry_msgs/msg/Polygon` (ROS 2 Kilted).
pub const POLYGON_MSG: &str = "\
# A specification of a polygon where the first and last points are assumed to be connected

Point32[] points
";

/// `geometry_msgs/msg/PolygonStamped` (ROS 2 Kilted).
pub const POLYGON_STAMPED_MSG: &str = "\
# This represents a Polygon with reference coordinate frame and timestamp

std_msgs/Header header
Polygon polygon
";

/// Every `.msg` text this module knows, by full type name (`pkg/msg/Type`).
const KNOWN: &[(&str, &str)] = &[
    ("tracer_calib_msgs/msg/RawScan", RAW_SCAN_MSG),
    ("tracer_calib_msgs/msg/Contour", CONTOUR_MSG),
    ("tracer_calib_msgs/msg/Calibration", CALIBRATION_MSG),
    ("std_msgs/msg/Header", HEADER_MSG),
    ("builtin_interfaces/msg/Time", TIME_MSG),
    ("geometry_msgs/msg/Point", POINT_MSG),
    ("geometry_msgs/msg/Point32", POINT32_MSG),
    ("geometry_msgs/msg/Polygon", POLYGON_MSG),
    ("geometry_msgs/msg/PolygonStamped", POLYGON_STAMPED_MSG),
];

const PRIMITIVES: &[&str] = &[
    "bool", "byte", "char", "float32", "float64", "int8", "uint8", "int16", "uint16", "int32", "uint32", "int64",
    "uint64", "string", "wstring",
];

/// The `.msg` text of one type (not its dependencies), if this module knows it.
pub fn msg_text(type_name: &str) -> Option<&'static str> {
    KNOWN.iter().find(|(name, _)| *name == type_name).map(|(_, text)| *text)
}

/// The type names this module has definitions for.
pub fn known_types() -> impl Iterator<Item = &'static str> {
    KNOWN.iter().map(|(name, _)| *name)
}

/// The complete `ros2msg` definition of `type_name` (`pkg/msg/Type`): its text and those of
/// all its dependencies. `None` if the type or one of its dependencies is unknown.
pub fn full_definition(type_name: &str) -> Option<String> {
    fn append(type_name: &str, seen: &mut BTreeSet<String>, out: &mut String) -> Option<()> {
        let text = msg_text(type_name)?;
        out.push_str(text);
        for dep in dependencies(text, package_of(type_name)) {
            if seen.insert(dep.clone()) {
                out.push('\n');
                out.push_str(SEPARATOR);
                out.push_str("\nMSG: ");
                out.push_str(&dep);
                out.push('\n');
                append(&dep, seen, out)?;
            }
        }
        Some(())
    }
    let mut out = String::new();
    append(type_name, &mut BTreeSet::new(), &mut out)?;
    Some(out)
}

fn package_of(type_name: &str) -> &str {
    type_name.split('/').next().unwrap_or("")
}

/// One field or constant line of a `.msg` text: `(type, name, constant value)`, comments and
/// blank lines skipped, default values ignored.
pub(crate) fn parse_lines(text: &str) -> impl Iterator<Item = (&str, &str, Option<&str>)> {
    text.lines().filter_map(|line| {
        let line = line.split('#').next().unwrap_or("").trim();
        if line.is_empty() {
            return None;
        }
        let (ty, rest) = line.split_once(char::is_whitespace)?;
        let rest = rest.trim();
        match rest.split_once('=') {
            Some((name, value)) => Some((ty, name.trim(), Some(value.trim()))),
            None => Some((ty, rest.split_whitespace().next().unwrap_or(""), None)),
        }
    })
}

/// The message type a field type refers to, as `pkg/msg/Type`, or `None` for a primitive.
/// `package` resolves bare names (`Point32[]` in geometry_msgs).
pub(crate) fn field_message_type(field_type: &str, package: &str) -> Option<String> {
    let base = field_type.split('[').next().unwrap_or(field_type);
    let base = base.split("<=").next().unwrap_or(base);
    if PRIMITIVES.contains(&base) {
        return None;
    }
    let parts: Vec<&str> = base.split('/').collect();
    Some(match parts.as_slice() {
        [name] => format!("{package}/msg/{name}"),
        [pkg, name] => format!("{pkg}/msg/{name}"),
        _ => base.to_string(),
    })
}

/// The message types a `.msg` text refers to, sorted, each once.
fn dependencies(text: &str, package: &str) -> BTreeSet<String> {
    parse_lines(text)
        .filter(|(_, _, value)| value.is_none())
        .filter_map(|(ty, _, _)| field_message_type(ty, package))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ros::msgs::{
        Calibration, Contour, Header, Point, Point32, Polygon, PolygonStamped, RawScan, RosMsg, Time,
    };

    type Fields = Vec<(String, String)>;
    type Constants = Vec<(String, String, String)>;

    /// The fields and constants of a definition text, types normalised to `pkg/msg/Type`.
    fn fields_of(text: &str, package: &str) -> (Fields, Constants) {
        let mut fields = Vec::new();
        let mut constants = Vec::new();
        for (ty, name, value) in parse_lines(text) {
            match value {
                Some(v) => constants.push((ty.to_string(), name.to_string(), v.to_string())),
                None => {
                    let suffix = ty.find('[').map(|i| &ty[i..]).unwrap_or("");
                    let ty = field_message_type(ty, package).map(|t| format!("{t}{suffix}")).unwrap_or(ty.to_string());
                    fields.push((ty, name.to_string()));
                }
            }
        }
        (fields, constants)
    }

    fn check<T: RosMsg>() {
        let name = T::NAME.ros_name();
        let text = msg_text(&name).unwrap_or_else(|| panic!("no definition for {name}"));
        let (fields, constants) = fields_of(text, T::NAME.package);
        let expected: Vec<(String, String)> = T::FIELDS
            .iter()
            .map(|(ty, n)| {
                let suffix = ty.find('[').map(|i| &ty[i..]).unwrap_or("");
                let ty =
                    field_message_type(ty, T::NAME.package).map(|t| format!("{t}{suffix}")).unwrap_or(ty.to_string());
                (ty, n.to_string())
            })
            .collect();
        assert_eq!(fields, expected, "{name}: fields");
        let expected: Vec<(String, String, String)> =
            T::CONSTANTS.iter().map(|(t, n, v)| (t.to_string(), n.to_string(), v.to_string())).collect();
        assert_eq!(constants, expected, "{name}: constants");
        assert!(full_definition(&name).is_some(), "{name}: dependencies");
    }

    #[test]
    fn definitions_match_the_mirrors() {
        check::<RawScan>();
        check::<Contour>();
        check::<Calibration>();
        check::<Header>();
        check::<Time>();
        check::<Point>();
        check::<Point32>();
        check::<Polygon>();
        check::<PolygonStamped>();
    }

    #[test]
    fn complete_definition_follows_rosbag2_order() {
        let sep = |name: &str| format!("\n{SEPARATOR}\nMSG: {name}\n");
        assert_eq!(
            full_definition("tracer_calib_msgs/msg/Contour").unwrap(),
            format!(
                "{CONTOUR_MSG}{}{POINT_MSG}{}{HEADER_MSG}{}{TIME_MSG}",
                sep("geometry_msgs/msg/Point"),
                sep("std_msgs/msg/Header"),
                sep("builtin_interfaces/msg/Time")
            )
        );
        assert_eq!(
            full_definition("geometry_msgs/msg/PolygonStamped").unwrap(),
            format!(
                "{POLYGON_STAMPED_MSG}{}{POLYGON_MSG}{}{POINT32_MSG}{}{HEADER_MSG}{}{TIME_MSG}",
                sep("geometry_msgs/msg/Polygon"),
                sep("geometry_msgs/msg/Point32"),
                sep("std_msgs/msg/Header"),
                sep("builtin_interfaces/msg/Time")
            )
        );
        assert_eq!(full_definition("sensor_msgs/msg/Image"), None);
    }
}
