//! `~/get_type_description` (type_description_interfaces/srv/GetTypeDescription, REP-2016):
//! the answer, as rcl gives it (`rcl_node_type_description_service_handle_request`, which
//! rclcpp's and rclpy's nodes serve), from [`super::type_hash::describe`] and the texts in
//! [`KNOWN`].
//!
//! - The request's `type_hash` must be `RIHS01_` and 64 hex digits, else
//!   `Failed to parse type hash`.
//! - The type is looked up by that hash among the types the node uses (each message type
//!   of a topic, each service type of a service or client; rcl's type cache), else `Type not
//!   currently in use by this node`; like rcl, the request's `type_name` is not compared.
//! - `type_description` is the type's description and every type it uses; with
//!   `include_type_sources`, `type_sources` holds one source for the type and each of those,
//!   in that order: a message's `.msg` text (encoding `msg`), a service's `.srv` text
//!   (`srv`), and nothing for the types rosidl makes of a service (its `_Request`,
//!   `_Response` and `_Event`: encoding `implicit`), as rosidl generates them: the file's
//!   lines joined by newlines, without a newline at the end.

use super::definition::Definition;
use super::type_hash::{Described, TypeDescription, describe, hash, hash_string};
use super::{
    Field as FieldMsg, FieldType as FieldTypeMsg, GetTypeDescriptionRequest, GetTypeDescriptionResponse,
    IndividualTypeDescription, KNOWN, TypeDescription as TypeDescriptionMsg, TypeSource,
};

/// rcl's reason for a `type_hash` that is not a RIHS01 hash.
pub const BAD_HASH: &str = "Failed to parse type hash";
/// rcl's reason for a hash of no type the node uses.
pub const NOT_IN_USE: &str = "Type not currently in use by this node";

fn individual(d: &TypeDescription) -> IndividualTypeDescription {
    IndividualTypeDescription {
        type_name: d.type_name.clone(),
        fields: d
            .fields
            .iter()
            .map(|f| FieldMsg {
                name: f.name.clone(),
                r#type: FieldTypeMsg {
                    type_id: f.field_type.type_id,
                    capacity: f.field_type.capacity,
                    string_capacity: f.field_type.string_capacity,
                    nested_type_name: f.field_type.nested_type_name.clone(),
                },
                default_value: f.default_value.clone(),
            })
            .collect(),
    }
}

/// A description as the message type_description_interfaces/msg/TypeDescription.
pub fn to_message(d: &Described) -> TypeDescriptionMsg {
    TypeDescriptionMsg {
        type_description: individual(&d.type_description),
        referenced_type_descriptions: d.referenced_type_descriptions.iter().map(individual).collect(),
    }
}

/// The source of one type: its text and encoding (module docs).
pub fn source(type_name: &str) -> TypeSource {
    let (encoding, text) = if let Some((_, definition)) = KNOWN.iter().find(|(n, _)| n.ros_name() == type_name) {
        match definition {
            Definition::Msg(text) => ("msg", *text),
            // A service half: a type rosidl makes of the .srv.
            Definition::Request(_) | Definition::Response(_) => ("implicit", ""),
        }
    } else if type_name.ends_with("_Event") {
        ("implicit", "")
    } else {
        // A service: the whole .srv text, which each half's definition holds.
        let request = format!("{type_name}_Request");
        match KNOWN.iter().find(|(n, _)| n.ros_name() == request) {
            Some((_, Definition::Request(srv))) => ("srv", *srv),
            _ => ("", ""),
        }
    };
    // rosidl gives the file's lines joined by newlines: no newline at the end.
    let raw_file_contents = text.lines().collect::<Vec<_>>().join("\n");
    TypeSource { type_name: type_name.to_string(), encoding: encoding.to_string(), raw_file_contents }
}

/// Whether `s` is a RIHS01 hash as rosidl writes it.
fn parses(s: &str) -> bool {
    s.strip_prefix("RIHS01_").is_some_and(|hex| hex.len() == 64 && hex.bytes().all(|b| b.is_ascii_hexdigit()))
}

/// The answer to `request` by a node whose endpoints use `types_in_use` (type names:
/// `pkg/msg/Type`, `pkg/srv/Service`).
pub fn answer<'a>(
    request: &GetTypeDescriptionRequest,
    types_in_use: impl IntoIterator<Item = &'a str>,
) -> GetTypeDescriptionResponse {
    let refuse = |reason: &str| GetTypeDescriptionResponse {
        successful: false,
        failure_reason: reason.to_string(),
        ..Default::default()
    };
    if !parses(&request.type_hash) {
        return refuse(BAD_HASH);
    }
    let wanted = format!("RIHS01_{}", request.type_hash["RIHS01_".len()..].to_ascii_lowercase());
    let Some(described) =
        types_in_use.into_iter().filter_map(|name| describe(name).ok()).find(|d| hash_string(&hash(d)) == wanted)
    else {
        return refuse(NOT_IN_USE);
    };
    let type_sources = if request.include_type_sources {
        std::iter::once(&described.type_description)
            .chain(&described.referenced_type_descriptions)
            .map(|d| source(&d.type_name))
            .collect()
    } else {
        Vec::new()
    };
    GetTypeDescriptionResponse {
        successful: true,
        failure_reason: String::new(),
        type_description: to_message(&described),
        type_sources,
        extra_information: Vec::new(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::interfaces::type_hash::type_hash;

    fn request(type_name: &str, type_hash: &str, include_type_sources: bool) -> GetTypeDescriptionRequest {
        GetTypeDescriptionRequest {
            type_name: type_name.to_string(),
            type_hash: type_hash.to_string(),
            include_type_sources,
        }
    }

    const IN_USE: [&str; 3] =
        ["tracer_calib_msgs/msg/RawScan", "tracer_calib_msgs/srv/Calibrate", "rcl_interfaces/msg/Log"];

    #[test]
    fn a_message_with_its_sources() {
        let raw_scan = "tracer_calib_msgs/msg/RawScan";
        let r = answer(&request(raw_scan, &type_hash(raw_scan).unwrap(), true), IN_USE);
        assert!(r.successful, "{}", r.failure_reason);
        assert_eq!(r.type_description.type_description.type_name, raw_scan);
        let referenced: Vec<&str> =
            r.type_description.referenced_type_descriptions.iter().map(|d| d.type_name.as_str()).collect();
        assert_eq!(referenced, ["builtin_interfaces/msg/Time", "std_msgs/msg/Header"]);
        let sources: Vec<(&str, &str)> =
            r.type_sources.iter().map(|s| (s.type_name.as_str(), s.encoding.as_str())).collect();
        assert_eq!(
            sources,
            [(raw_scan, "msg"), ("builtin_interfaces/msg/Time", "msg"), ("std_msgs/msg/Header", "msg")]
        );
        assert_eq!(
            r.type_sources[0].raw_file_contents,
            include_str!("../../msg/msg/RawScan.msg").trim_end_matches('\n')
        );
        // Without sources: the same description, no sources.
        let r2 = answer(&request(raw_scan, &type_hash(raw_scan).unwrap(), false), IN_USE);
        assert!(r2.successful && r2.type_sources.is_empty());
        assert_eq!(r2.type_description, r.type_description);
    }

    #[test]
    fn a_service_with_its_sources_as_rosidl_makes_them() {
        let calibrate = "tracer_calib_msgs/srv/Calibrate";
        let r = answer(&request("", &type_hash(calibrate).unwrap(), true), IN_USE);
        assert!(r.successful, "{}", r.failure_reason);
        let sources: Vec<(&str, &str, bool)> = r
            .type_sources
            .iter()
            .map(|s| (s.type_name.as_str(), s.encoding.as_str(), s.raw_file_contents.is_empty()))
            .collect();
        assert_eq!(
            sources,
            [
                (calibrate, "srv", false),
                ("builtin_interfaces/msg/Time", "msg", false),
                ("service_msgs/msg/ServiceEventInfo", "msg", false),
                ("tracer_calib_msgs/srv/Calibrate_Event", "implicit", true),
                ("tracer_calib_msgs/srv/Calibrate_Request", "implicit", true),
                ("tracer_calib_msgs/srv/Calibrate_Response", "implicit", true),
            ]
        );
        assert_eq!(
            r.type_sources[0].raw_file_contents,
            include_str!("../../msg/srv/Calibrate.srv").trim_end_matches('\n')
        );
    }

    #[test]
    fn refusals_are_rcls() {
        let r = answer(&request("tracer_calib_msgs/msg/RawScan", "", false), IN_USE);
        assert_eq!((r.successful, r.failure_reason.as_str()), (false, BAD_HASH));
        let r = answer(&request("x", "RIHS01_12", false), IN_USE);
        assert_eq!(r.failure_reason, BAD_HASH);
        // A type the node does not use, though known.
        let header = type_hash("std_msgs/msg/Header").unwrap();
        let r = answer(&request("std_msgs/msg/Header", &header, false), IN_USE);
        assert_eq!((r.successful, r.failure_reason.as_str()), (false, NOT_IN_USE));
        // A service half is not a type in use: its service is.
        let half = type_hash("tracer_calib_msgs/srv/Calibrate_Request").unwrap();
        assert_eq!(answer(&request("", &half, false), IN_USE).failure_reason, NOT_IN_USE);
        // Nobody's hash.
        let r = answer(&request("sensor_msgs/msg/Image", &format!("RIHS01_{}", "0".repeat(64)), false), IN_USE);
        assert_eq!((r.successful, r.failure_reason.as_str()), (false, NOT_IN_USE));
    }
}
