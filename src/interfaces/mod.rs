//! The interface layer: Rust mirrors of every ROS 2 message and service the node and the
//! tools speak, each with its `.msg` text, and the CDR codec that puts them on the wire and in
//! bag files.
//!
//! It sits below everything that moves messages: the node shell ([`crate::ros`]), the files
//! ([`crate::io`]: rosbag2), the offline tool ([`crate::cli`]) and the cell's logic
//! ([`crate::cell`]) all use it; it uses none of them.
//!
//! - [`standard`]: the standard types used (`builtin_interfaces`, `std_msgs`,
//!   `geometry_msgs`, `diagnostic_msgs`, `service_msgs`; those of ros2-client's own endpoints,
//!   `rcl_interfaces` and `rmw_dds_common`, for their hashes; `type_description_interfaces`),
//!   their `.msg` / `.srv` texts copied verbatim from ROS 2 (`standard/msg/<package>/<Type>.msg`,
//!   `standard/srv/<package>/<Service>.srv`); a text there is a type known to the crate;
//! - [`tracer_calib_msgs`]: the node's own package, its texts read from `msg/` at compile
//!   time (the files colcon builds the package from);
//! - [`syntax`]: the `.msg` / `.srv` parser, the one reader of the texts (the build script
//!   uses it too);
//! - [`definition`]: where each type's text is, and the complete definitions rosbag2 stores;
//! - [`type_hash`]: type descriptions and RIHS01 hashes (REP-2016), from the same texts;
//! - [`type_description`]: the answer of `~/get_type_description` (REP-2016), as rcl's;
//! - [`cdr`]: plain CDR with its encapsulation header, as DDS sends and rosbag2 stores it.
//!
//! # One declaration per type
//!
//! Each type is declared once, by its `.msg` / `.srv` file: the build script (`build.rs`)
//! generates the struct (field order = `.msg` order = wire order, the comments as docs), the
//! constants as associated consts, and [`RosMsg`] with the ROS name and the definition text
//! ([`RosMsg::DEFINITION`]). Hand-written beside them: what a text cannot say (`Default` of
//! `Header` and `CalibrateResponse`, the `Time` type ros2-client brings). The tests check
//! every struct against its text anyway (field names, order and kinds, through serde: what CDR
//! sees), and the texts against `msg/`.
//!
//! # Wire layout
//!
//! ROS 2 over DDS sends each message as *plain CDR* (XCDR version 1), which is exactly what
//! rustdds' serializer produces from a serde `Serialize` impl when the struct fields appear in
//! the same order as in the `.msg` file ([`cdr`] says how each type is laid out). A service
//! with the *Enhanced* mapping (what `rmw_fastrtps_cpp` uses) sends the request and response
//! structs exactly like messages: the request id travels in the RTPS inline QoS, not in the
//! payload.

use serde::{Serialize, de::DeserializeOwned};

pub mod cdr;
pub mod definition;
mod name;
pub mod standard;
pub mod syntax;
pub mod tracer_calib_msgs;
pub mod type_description;
pub mod type_hash;

#[cfg(test)]
mod shape;
#[cfg(test)]
mod tests;

pub use cdr::{CDR_LE_HEADER, CdrError, from_cdr, from_cdr_msg, to_cdr};
pub use definition::Definition;
pub use name::{InterfaceKind, InterfaceName};
// Every standard type at this level: the generated code names field types
// `crate::interfaces::Type`.
pub use standard::*;
pub use tracer_calib_msgs::{
    Calibrate, CalibrateEvent, CalibrateRequest, CalibrateResponse, Calibration, Contour, RawScan,
};

/// A Rust mirror of a ROS 2 interface type, with the definition it mirrors.
///
/// Not a subtrait of ros2-client's [`ros2_client::Message`] only because ros2-client's
/// [`Time`] does not implement `Message`; every other mirror here implements both.
pub trait RosMsg: Serialize + DeserializeOwned {
    /// The ROS type name.
    const NAME: InterfaceName;
    /// The type's `.msg` text (for a service half, the part of the `.srv` text it is).
    const DEFINITION: Definition;

    /// The message decoded from a CDR `payload` (no encapsulation header) as an earlier
    /// version of its definition wrote it, before fields were appended (`build.rs`'s
    /// `APPENDED`): the fields it lacks take their absent value. `None` if the payload is
    /// no earlier layout of it, or the type has none.
    fn from_earlier_cdr(_payload: &[u8], _rep: rustdds::RepresentationIdentifier) -> Option<Self> {
        None
    }
}

/// A ROS 2 service type: its name and its request and response mirrors.
///
/// ros2-client 0.12 has no service trait of its own; `Node::create_server::<Req, Resp>` takes
/// the two types and a [`ros2_client::ServiceTypeName`] separately. Use
/// `node.create_server::<S::Request, S::Response>(ServiceMapping::Enhanced, &name,
/// &S::type_name(), qos.clone(), qos)`.
pub trait RosService {
    /// The request mirror.
    type Request: RosMsg + ros2_client::Message + Clone + 'static;
    /// The response mirror.
    type Response: RosMsg + ros2_client::Message + 'static;
    /// The service type name (`pkg/srv/Name`).
    const NAME: InterfaceName;

    /// The service type name in ros2-client's form.
    fn type_name() -> ros2_client::ServiceTypeName {
        Self::NAME.service_type_name()
    }
}

/// Every type this layer mirrors (messages and service halves), with its definition: what
/// complete definitions (rosbag2) resolve dependencies against, and what type descriptions
/// and hashes ([`type_hash`]) are made of. Listed by the build script: every text in `msg/`
/// and `standard/` is here.
pub const KNOWN: &[(InterfaceName, Definition)] = include!(concat!(env!("OUT_DIR"), "/known.rs"));
