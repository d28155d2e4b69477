//! Rust mirrors of every ROS 2 message and service the node speaks.
//!
//! # Wire layout
//!
//! ROS 2 over DDS sends each message as *plain CDR* (XCDR version 1), which is exactly what
//! rustdds' serializer produces from a serde `Serialize` impl when the struct fields appear in
//! the same order as in the `.msg` file:
//!
//! - a 4-byte *encapsulation header* precedes the payload: `00 01 00 00` for little-endian CDR
//!   (`00 00 00 00` for big-endian). Byte 1 selects the byte order; bytes 2-3 are options
//!   (DDS writers put the count of trailing padding bytes there). DDS adds and strips the
//!   header itself; rosbag2 stores it with each message. [`to_cdr`] and [`from_cdr`] handle it
//!   for files and tests;
//! - every primitive is aligned to its own size (1, 2, 4 or 8 bytes), counted from the first
//!   byte *after* the encapsulation header; padding bytes are zero;
//! - `bool`, `byte`, `uint8`, `char` are one octet; `float64` is 8 bytes, aligned to 8;
//! - `string` is a `u32` length that *includes* the terminating NUL, then the bytes, then NUL;
//! - an unbounded or bounded sequence `T[]` / `T[<=N]` is a `u32` element count, then the
//!   elements (each aligned as usual); a fixed array `T[N]` has no count;
//! - nested messages are inlined, with no alignment of their own beyond their first member;
//! - constants (`uint8 TARGET_LENS=3`) are not on the wire; here they are associated consts.
//!
//! A service with the *Enhanced* mapping (what `rmw_fastrtps_cpp` uses, and what the contract
//! asks for) sends the request and response structs exactly like messages: the request id
//! travels in the RTPS inline QoS, not in the payload.
//!
//! # Type names
//!
//! All ROS type names live in [`type_names`]; each mirror type also carries its name as
//! [`RosMsg::NAME`], and the field list of its `.msg` definition as [`RosMsg::FIELDS`], which the
//! tests check both against the serde layout of the struct and against the interface files in
//! `msg/`, so neither side can drift unnoticed.

use ros2_client::{Message, MessageTypeName, ServiceTypeName};
use rustdds::RepresentationIdentifier;
use serde::{Deserialize, Serialize, de::DeserializeOwned};

/// `builtin_interfaces/msg/Time`: ros2-client's own type, reused (wire: `int32 sec`,
/// `uint32 nanosec`). Construct with [`Time::new`]`(sec, nanosec)` or `Time::from_nanos`.
///
/// In memory it is a signed nanosecond count, so a wire value with `nanosec >= 10^9` is
/// folded into the seconds on receipt (ros2-client logs a warning).
pub use ros2_client::builtin_interfaces::Time;

/// One field of a ROS interface definition: `(type as written in the .msg file, field name)`.
///
/// Types are written with their package, `std_msgs/Header`, never bare `Header`, and arrays as
/// `T[]`, `T[N]` or `T[<=N]`.
pub type FieldDef = (&'static str, &'static str);

/// One constant of a ROS interface definition: `(type, name, value as written)`.
pub type ConstantDef = (&'static str, &'static str, &'static str);

/// Whether an interface is a message or part of a service.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum InterfaceKind {
    /// A message, `pkg/msg/Name`.
    Msg,
    /// A service or one half of it (`Name_Request`, `Name_Response`), `pkg/srv/Name`.
    Srv,
}

impl InterfaceKind {
    /// The middle part of the ROS name: `msg` or `srv`.
    pub const fn as_str(self) -> &'static str {
        match self {
            InterfaceKind::Msg => "msg",
            InterfaceKind::Srv => "srv",
        }
    }
}

/// The name of a ROS 2 interface type: package, kind and type name.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct InterfaceName {
    /// The ROS package, e.g. `tracer_calib_msgs`.
    pub package: &'static str,
    /// Message or service.
    pub kind: InterfaceKind,
    /// The type name, e.g. `RawScan`, `Calibrate`, or `Calibrate_Request` for a service half.
    pub name: &'static str,
}

impl InterfaceName {
    /// A message type name.
    pub const fn msg(package: &'static str, name: &'static str) -> Self {
        InterfaceName { package, kind: InterfaceKind::Msg, name }
    }

    /// A service type name (or the name of one half, e.g. `Calibrate_Request`).
    pub const fn srv(package: &'static str, name: &'static str) -> Self {
        InterfaceName { package, kind: InterfaceKind::Srv, name }
    }

    /// The ROS name as rosbag2 and `ros2 interface` write it: `pkg/msg/Name`.
    pub fn ros_name(&self) -> String {
        format!("{}/{}/{}", self.package, self.kind.as_str(), self.name)
    }

    /// The DDS type name: `pkg::msg::dds_::Name_`.
    pub fn dds_type_name(&self) -> String {
        format!("{}::{}::dds_::{}_", self.package, self.kind.as_str(), self.name)
    }

    /// The name in ros2-client's form, for `Node::create_topic`.
    ///
    /// # Panics
    ///
    /// If this is a service name: ros2-client cannot express `pkg/srv/...` topic types.
    pub fn message_type_name(&self) -> MessageTypeName {
        assert_eq!(self.kind, InterfaceKind::Msg, "{} is not a message type", self.ros_name());
        MessageTypeName::new(self.package, self.name)
    }

    /// The name in ros2-client's form, for `Node::create_server` / `create_client`: the
    /// *service* name (`Calibrate`); ros2-client appends `_Request_` / `_Response_` itself.
    ///
    /// # Panics
    ///
    /// If this is a message name.
    pub fn service_type_name(&self) -> ServiceTypeName {
        assert_eq!(self.kind, InterfaceKind::Srv, "{} is not a service type", self.ros_name());
        ServiceTypeName::new(self.package, self.name)
    }
}

/// Every ROS type name the node uses, in one place.
pub mod type_names {
    use super::InterfaceName;

    /// The node's own interface package.
    pub const PACKAGE: &str = "tracer_calib_msgs";

    /// `builtin_interfaces/msg/Time`.
    pub const TIME: InterfaceName = InterfaceName::msg("builtin_interfaces", "Time");
    /// `std_msgs/msg/Header`.
    pub const HEADER: InterfaceName = InterfaceName::msg("std_msgs", "Header");
    /// `tracer_calib_msgs/msg/RawScan`.
    pub const RAW_SCAN: InterfaceName = InterfaceName::msg(PACKAGE, "RawScan");
    /// `tracer_calib_msgs/msg/Contour`.
    pub const CONTOUR: InterfaceName = InterfaceName::msg(PACKAGE, "Contour");
    /// `tracer_calib_msgs/msg/Calibration`.
    pub const CALIBRATION: InterfaceName = InterfaceName::msg(PACKAGE, "Calibration");
    /// `geometry_msgs/msg/Point`.
    pub const POINT: InterfaceName = InterfaceName::msg("geometry_msgs", "Point");
    /// `geometry_msgs/msg/Point32`.
    pub const POINT32: InterfaceName = InterfaceName::msg("geometry_msgs", "Point32");
    /// `geometry_msgs/msg/Polygon`.
    pub const POLYGON: InterfaceName = InterfaceName::msg("geometry_msgs", "Polygon");
    /// `geometry_msgs/msg/PolygonStamped`.
    pub const POLYGON_STAMPED: InterfaceName = InterfaceName::msg("geometry_msgs", "PolygonStamped");
    /// `diagnostic_msgs/msg/KeyValue`.
    pub const KEY_VALUE: InterfaceName = InterfaceName::msg("diagnostic_msgs", "KeyValue");
    /// `diagnostic_msgs/msg/DiagnosticStatus`.
    pub const DIAGNOSTIC_STATUS: InterfaceName = InterfaceName::msg("diagnostic_msgs", "DiagnosticStatus");
    /// `diagnostic_msgs/msg/DiagnosticArray`.
    pub const DIAGNOSTIC_ARRAY: InterfaceName = InterfaceName::msg("diagnostic_msgs", "DiagnosticArray");
    /// `tracer_calib_msgs/srv/Calibrate`: give [`InterfaceName::service_type_name`] of this to
    /// ros2-client; the DDS topics then carry `tracer_calib_msgs::srv::dds_::Calibrate_Request_`
    /// and `..._Response_`.
    pub const CALIBRATE: InterfaceName = InterfaceName::srv(PACKAGE, "Calibrate");
    /// The request half of `Calibrate`, `tracer_calib_msgs/srv/Calibrate_Request`.
    pub const CALIBRATE_REQUEST: InterfaceName = InterfaceName::srv(PACKAGE, "Calibrate_Request");
    /// The response half of `Calibrate`, `tracer_calib_msgs/srv/Calibrate_Response`.
    pub const CALIBRATE_RESPONSE: InterfaceName = InterfaceName::srv(PACKAGE, "Calibrate_Response");
}

/// A Rust mirror of a ROS 2 interface type, with the definition it mirrors.
///
/// Not a subtrait of ros2-client's [`Message`] only because ros2-client's [`Time`] does not
/// implement `Message`; every other mirror here implements both.
pub trait RosMsg: Serialize + DeserializeOwned {
    /// The ROS type name.
    const NAME: InterfaceName;
    /// The fields, in `.msg` order, which is the CDR order and the struct's field order.
    const FIELDS: &'static [FieldDef];
    /// The constants of the definition (not on the wire).
    const CONSTANTS: &'static [ConstantDef] = &[];
}

/// A ROS 2 service type: its name and its request and response mirrors.
///
/// ros2-client 0.12 has no service trait of its own; `Node::create_server::<Req, Resp>` takes
/// the two types and a [`ServiceTypeName`] separately. Use
/// `node.create_server::<S::Request, S::Response>(ServiceMapping::Enhanced, &name,
/// &S::type_name(), qos.clone(), qos)`.
pub trait RosService {
    /// The request mirror.
    type Request: RosMsg + Message + Clone + 'static;
    /// The response mirror.
    type Response: RosMsg + Message + 'static;
    /// The service type name (`pkg/srv/Name`).
    const NAME: InterfaceName;

    /// The service type name in ros2-client's form.
    fn type_name() -> ServiceTypeName {
        Self::NAME.service_type_name()
    }
}

impl RosMsg for Time {
    const NAME: InterfaceName = type_names::TIME;
    const FIELDS: &'static [FieldDef] = &[("int32", "sec"), ("uint32", "nanosec")];
}

/// `std_msgs/msg/Header`: a timestamp and a coordinate frame id.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Header {
    /// Time of the data.
    pub stamp: Time,
    /// Coordinate frame the data is expressed in.
    pub frame_id: String,
}

impl Default for Header {
    fn default() -> Self {
        Header { stamp: Time::ZERO, frame_id: String::new() }
    }
}

impl Message for Header {}
impl RosMsg for Header {
    const NAME: InterfaceName = type_names::HEADER;
    const FIELDS: &'static [FieldDef] = &[("builtin_interfaces/Time", "stamp"), ("string", "frame_id")];
}

/// `tracer_calib_msgs/msg/RawScan`: one revolution of the tracer, as its encoders report it.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct RawScan {
    /// `stamp`: start of the revolution; `frame_id`: the tracer's frame.
    pub header: Header,
    /// Set by the tracer, increases by one per revolution.
    pub scan_id: u32,
    /// What was traced: one of the `TARGET_*` constants.
    pub target: u8,
    /// Angle steps in one turn (400 -> 0.9 degrees per step).
    pub steps_per_revolution: u32,
    /// Angle step of each sample, `0 <= step < steps_per_revolution`.
    pub step: Vec<u32>,
    /// Probe encoder reading of each sample; same length as `step`.
    pub counts: Vec<i32>,
}

impl RawScan {
    /// `target`: unknown.
    pub const TARGET_UNKNOWN: u8 = 0;
    /// `target`: the calibration plate.
    pub const TARGET_CALIBRATION_PLATE: u8 = 1;
    /// `target`: a spectacle frame.
    pub const TARGET_FRAME: u8 = 2;
    /// `target`: a lens.
    pub const TARGET_LENS: u8 = 3;
}

impl Message for RawScan {}
impl RosMsg for RawScan {
    const NAME: InterfaceName = type_names::RAW_SCAN;
    const FIELDS: &'static [FieldDef] = &[
        ("std_msgs/Header", "header"),
        ("uint32", "scan_id"),
        ("uint8", "target"),
        ("uint32", "steps_per_revolution"),
        ("uint32[]", "step"),
        ("int32[]", "counts"),
    ];
    const CONSTANTS: &'static [ConstantDef] = &[
        ("uint8", "TARGET_UNKNOWN", "0"),
        ("uint8", "TARGET_CALIBRATION_PLATE", "1"),
        ("uint8", "TARGET_FRAME", "2"),
        ("uint8", "TARGET_LENS", "3"),
    ];
}

/// `tracer_calib_msgs/msg/Contour`: a corrected contour in the frame of the rotation axis.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct Contour {
    /// `stamp` copied from the raw scan; `frame_id`: parameter `output_frame_id`.
    pub header: Header,
    /// Copied from the raw scan.
    pub scan_id: u32,
    /// Copied from the raw scan.
    pub target: u8,
    /// False: no calibration applied yet, points are uncorrected.
    pub calibrated: bool,
    /// One per raw sample, in sample order, metres, `z = 0`.
    pub points: Vec<Point>,
    /// Contour resampled at equal angles about the rotation axis: `radii[k]` at angle
    /// `2*pi*k/radii.len()`, metres; empty if the scan does not go all the way round.
    pub radii: Vec<f64>,
}

impl Message for Contour {}
impl RosMsg for Contour {
    const NAME: InterfaceName = type_names::CONTOUR;
    const FIELDS: &'static [FieldDef] = &[
        ("std_msgs/Header", "header"),
        ("uint32", "scan_id"),
        ("uint8", "target"),
        ("bool", "calibrated"),
        ("geometry_msgs/Point[]", "points"),
        ("float64[]", "radii"),
    ];
}

/// `geometry_msgs/msg/Point`: a position, `float64` coordinates.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct Point {
    /// x, metres.
    pub x: f64,
    /// y, metres.
    pub y: f64,
    /// z, metres.
    pub z: f64,
}

impl Message for Point {}
impl RosMsg for Point {
    const NAME: InterfaceName = type_names::POINT;
    const FIELDS: &'static [FieldDef] = &[("float64", "x"), ("float64", "y"), ("float64", "z")];
}

/// `geometry_msgs/msg/Point32`: a position, `float32` coordinates.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct Point32 {
    /// x, metres.
    pub x: f32,
    /// y, metres.
    pub y: f32,
    /// z, metres.
    pub z: f32,
}

impl Message for Point32 {}
impl RosMsg for Point32 {
    const NAME: InterfaceName = type_names::POINT32;
    const FIELDS: &'static [FieldDef] = &[("float32", "x"), ("float32", "y"), ("float32", "z")];
}

/// `geometry_msgs/msg/Polygon`: a closed polygon (the last point connects to the first).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct Polygon {
    /// The vertices.
    pub points: Vec<Point32>,
}

impl Message for Polygon {}
impl RosMsg for Polygon {
    const NAME: InterfaceName = type_names::POLYGON;
    const FIELDS: &'static [FieldDef] = &[("geometry_msgs/Point32[]", "points")];
}

/// `geometry_msgs/msg/PolygonStamped`: a polygon with a header.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct PolygonStamped {
    /// Time and frame of the polygon.
    pub header: Header,
    /// The polygon.
    pub polygon: Polygon,
}

impl Message for PolygonStamped {}
impl RosMsg for PolygonStamped {
    const NAME: InterfaceName = type_names::POLYGON_STAMPED;
    const FIELDS: &'static [FieldDef] = &[("std_msgs/Header", "header"), ("geometry_msgs/Polygon", "polygon")];
}

/// `diagnostic_msgs/msg/KeyValue`: one named value of a diagnostic status.
#[derive(Debug, Clone, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct KeyValue {
    /// What the value is.
    pub key: String,
    /// The value, as text.
    pub value: String,
}

impl Message for KeyValue {}
impl RosMsg for KeyValue {
    const NAME: InterfaceName = type_names::KEY_VALUE;
    const FIELDS: &'static [FieldDef] = &[("string", "key"), ("string", "value")];
}

/// `diagnostic_msgs/msg/DiagnosticStatus`: the state of one component.
#[derive(Debug, Clone, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct DiagnosticStatus {
    /// One of `OK`, `WARN`, `ERROR`, `STALE` (a ROS `byte`).
    pub level: u8,
    /// Component name, e.g. `tracer_calibrator: calibration`.
    pub name: String,
    /// A short description of the status.
    pub message: String,
    /// Hardware the status is about, if any.
    pub hardware_id: String,
    /// Further values.
    pub values: Vec<KeyValue>,
}

impl DiagnosticStatus {
    /// `level`: all is well.
    pub const OK: u8 = 0;
    /// `level`: a warning.
    pub const WARN: u8 = 1;
    /// `level`: an error.
    pub const ERROR: u8 = 2;
    /// `level`: no recent data.
    pub const STALE: u8 = 3;
}

impl Message for DiagnosticStatus {}
impl RosMsg for DiagnosticStatus {
    const NAME: InterfaceName = type_names::DIAGNOSTIC_STATUS;
    const FIELDS: &'static [FieldDef] = &[
        ("byte", "level"),
        ("string", "name"),
        ("string", "message"),
        ("string", "hardware_id"),
        ("diagnostic_msgs/KeyValue[]", "values"),
    ];
    const CONSTANTS: &'static [ConstantDef] =
        &[("byte", "OK", "0"), ("byte", "WARN", "1"), ("byte", "ERROR", "2"), ("byte", "STALE", "3")];
}

/// `diagnostic_msgs/msg/DiagnosticArray`: what is published on `/diagnostics`.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct DiagnosticArray {
    /// Time of the report.
    pub header: Header,
    /// One entry per component.
    pub status: Vec<DiagnosticStatus>,
}

impl Message for DiagnosticArray {}
impl RosMsg for DiagnosticArray {
    const NAME: InterfaceName = type_names::DIAGNOSTIC_ARRAY;
    const FIELDS: &'static [FieldDef] =
        &[("std_msgs/Header", "header"), ("diagnostic_msgs/DiagnosticStatus[]", "status")];
}

/// The request of `tracer_calib_msgs/srv/Calibrate`.
#[derive(Debug, Clone, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct CalibrateRequest {
    /// Which calibration-plate scan to use; 0 = the most recent one received.
    pub scan_id: u32,
    /// True: report the fit, but do not apply or persist it.
    pub dry_run: bool,
}

impl Message for CalibrateRequest {}
impl RosMsg for CalibrateRequest {
    const NAME: InterfaceName = type_names::CALIBRATE_REQUEST;
    const FIELDS: &'static [FieldDef] = &[("uint32", "scan_id"), ("bool", "dry_run")];
}

/// The response of `tracer_calib_msgs/srv/Calibrate`.
///
/// Its serde field names and order are also those of the offline tool's `--json` output.
/// The default is a failure with no result (and `scale` 1.0, the scale of no fit).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CalibrateResponse {
    /// Whether the fit succeeded (and, unless `dry_run`, was applied).
    pub success: bool,
    /// A one-line summary, or why it failed.
    pub message: String,
    /// Rail angle at step 0, radians, in (-pi/4, pi/4].
    pub alpha0: f64,
    /// Rail offset d from the rotation axis, metres.
    pub offset: f64,
    /// Encoder zero offset along the rail, metres.
    pub delta_l: f64,
    /// Standard uncertainty of `[alpha0, offset, delta_l]`, same units.
    pub stddev: Vec<f64>,
    /// Metres.
    pub rms_residual: f64,
    /// LM iterations used.
    pub iterations: u32,
    /// Samples that entered the fit.
    pub samples_used: u32,
    /// Encoder scale k (true length = counts × meters_per_count × k); 1.0 unless the
    /// model fits it.
    pub scale: f64,
    /// Standard uncertainty of `scale`; 0.0 unless the model fits it.
    pub scale_stddev: f64,
}

impl Default for CalibrateResponse {
    fn default() -> Self {
        CalibrateResponse {
            success: false,
            message: String::new(),
            alpha0: 0.0,
            offset: 0.0,
            delta_l: 0.0,
            stddev: Vec::new(),
            rms_residual: 0.0,
            iterations: 0,
            samples_used: 0,
            scale: 1.0,
            scale_stddev: 0.0,
        }
    }
}

impl Message for CalibrateResponse {}
impl RosMsg for CalibrateResponse {
    const NAME: InterfaceName = type_names::CALIBRATE_RESPONSE;
    const FIELDS: &'static [FieldDef] = &[
        ("bool", "success"),
        ("string", "message"),
        ("float64", "alpha0"),
        ("float64", "offset"),
        ("float64", "delta_l"),
        ("float64[]", "stddev"),
        ("float64", "rms_residual"),
        ("uint32", "iterations"),
        ("uint32", "samples_used"),
        ("float64", "scale"),
        ("float64", "scale_stddev"),
    ];
}

/// `tracer_calib_msgs/msg/Calibration`: the calibration in force, published latched on
/// `calibration` so that every contour can be traced to the calibration that made it.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct Calibration {
    /// Stamp: when this calibration was applied; frame_id: `output_frame_id`.
    pub header: Header,
    /// False: no calibration yet (parameters at their defaults).
    pub valid: bool,
    /// `full`, `paper` or `full_scale`.
    pub model: String,
    /// The plate scan it was fitted to; 0 if set by parameters.
    pub scan_id: u32,
    /// Radians.
    pub alpha0: f64,
    /// Metres (d).
    pub offset: f64,
    /// Metres (dL).
    pub delta_l: f64,
    /// Encoder scale k; 1.0 unless fitted.
    pub scale: f64,
    /// Standard uncertainty of `[alpha0, offset, delta_l(, scale)]`; empty if unknown.
    pub stddev: Vec<f64>,
    /// Metres; 0 if unknown.
    pub rms_residual: f64,
    pub samples_used: u32,
}

impl Message for Calibration {}
impl RosMsg for Calibration {
    const NAME: InterfaceName = type_names::CALIBRATION;
    const FIELDS: &'static [FieldDef] = &[
        ("std_msgs/Header", "header"),
        ("bool", "valid"),
        ("string", "model"),
        ("uint32", "scan_id"),
        ("float64", "alpha0"),
        ("float64", "offset"),
        ("float64", "delta_l"),
        ("float64", "scale"),
        ("float64[]", "stddev"),
        ("float64", "rms_residual"),
        ("uint32", "samples_used"),
    ];
}

/// The `tracer_calib_msgs/srv/Calibrate` service type.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Calibrate;

impl RosService for Calibrate {
    type Request = CalibrateRequest;
    type Response = CalibrateResponse;
    const NAME: InterfaceName = type_names::CALIBRATE;
}

/// Encapsulation header of little-endian plain CDR: `00 01`, options `00 00`.
pub const CDR_LE_HEADER: [u8; 4] = [0x00, 0x01, 0x00, 0x00];

/// Why CDR bytes could not be decoded or encoded.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum CdrError {
    /// Fewer than the 4 bytes of the encapsulation header.
    #[error("CDR data too short for the 4-byte encapsulation header ({0} bytes)")]
    TooShort(usize),
    /// An encapsulation other than plain CDR (e.g. XCDR2 or parameter lists).
    #[error("unsupported CDR encapsulation {} (only plain CDR: 00 00 or 00 01)", hex_pair(.0))]
    Encapsulation([u8; 2]),
    /// The CDR (de)serializer failed: truncated data, a bad bool, bad UTF-8...
    #[error("CDR: {0}")]
    Codec(String),
    /// More bytes followed the message than the at most 3 bytes of padding: probably the
    /// wrong type.
    #[error("{0} unexpected bytes after the message (wrong message type?)")]
    TrailingBytes(usize),
}

fn hex_pair(bytes: &[u8; 2]) -> String {
    format!("{:02x} {:02x}", bytes[0], bytes[1])
}

/// Serializes `value` as little-endian plain CDR, with the encapsulation header, as ROS 2 puts it
/// on the wire and in rosbag2 files.
pub fn to_cdr<T: Serialize>(value: &T) -> Result<Vec<u8>, CdrError> {
    let mut out = CDR_LE_HEADER.to_vec();
    rustdds::serialization::to_writer_with_rep_id(&mut out, value, RepresentationIdentifier::CDR_LE)
        .map_err(|e| CdrError::Codec(e.to_string()))?;
    Ok(out)
}

/// Deserializes plain CDR with its encapsulation header (either byte order).
///
/// Up to 3 trailing bytes are accepted (DDS and rosbag2 pad payloads to a multiple of 4);
/// more is an error, since it usually means the bytes are of another type.
pub fn from_cdr<T: DeserializeOwned>(bytes: &[u8]) -> Result<T, CdrError> {
    if bytes.len() < 4 {
        return Err(CdrError::TooShort(bytes.len()));
    }
    let rep_id = match [bytes[0], bytes[1]] {
        [0x00, 0x00] => RepresentationIdentifier::CDR_BE,
        [0x00, 0x01] => RepresentationIdentifier::CDR_LE,
        other => return Err(CdrError::Encapsulation(other)),
    };
    let payload = &bytes[4..];
    let (value, used) = rustdds::serialization::deserialize_from_cdr_with_rep_id::<T>(payload, rep_id)
        .map_err(|e| CdrError::Codec(e.to_string()))?;
    let rest = payload.len().saturating_sub(used);
    if rest > 3 {
        return Err(CdrError::TrailingBytes(rest));
    }
    Ok(value)
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde::ser::{self, Impossible};
    use std::fmt;

    // ---------------------------------------------------------------- samples

    /// A value of the type with distinct field values and non-empty sequences.
    trait Sample: Sized {
        fn sample() -> Self;
    }

    impl Sample for Time {
        fn sample() -> Self {
            Time::new(1_700_000_123, 456_789)
        }
    }
    impl Sample for Header {
        fn sample() -> Self {
            Header { stamp: Time::sample(), frame_id: "tracer".into() }
        }
    }
    impl Sample for RawScan {
        fn sample() -> Self {
            RawScan {
                header: Header::sample(),
                scan_id: 42,
                target: RawScan::TARGET_LENS,
                steps_per_revolution: 400,
                step: vec![0, 1, 2, 399],
                counts: vec![-5, 0, 17_000_000, i32::MIN],
            }
        }
    }
    impl Sample for Point {
        fn sample() -> Self {
            Point { x: 0.25, y: -1.5e-3, z: 3.0 }
        }
    }
    impl Sample for Point32 {
        fn sample() -> Self {
            Point32 { x: 0.5, y: -2.25, z: 7.0 }
        }
    }
    impl Sample for Contour {
        fn sample() -> Self {
            Contour {
                header: Header::sample(),
                scan_id: 9,
                target: RawScan::TARGET_FRAME,
                calibrated: true,
                points: vec![Point::sample(), Point { x: 1.0, y: 2.0, z: 0.0 }],
                radii: vec![0.021, 0.0215, f64::MIN_POSITIVE],
            }
        }
    }
    impl Sample for Polygon {
        fn sample() -> Self {
            Polygon { points: vec![Point32::sample(), Point32 { x: 1.0, y: 0.0, z: 0.0 }] }
        }
    }
    impl Sample for PolygonStamped {
        fn sample() -> Self {
            PolygonStamped { header: Header::sample(), polygon: Polygon::sample() }
        }
    }
    impl Sample for KeyValue {
        fn sample() -> Self {
            KeyValue { key: "rms_residual".into(), value: "1.2e-6".into() }
        }
    }
    impl Sample for DiagnosticStatus {
        fn sample() -> Self {
            DiagnosticStatus {
                level: DiagnosticStatus::WARN,
                name: "tracer_calibrator: calibration".into(),
                message: "not calibrated".into(),
                hardware_id: "tracer-7".into(),
                values: vec![KeyValue::sample(), KeyValue { key: "ünïcode".into(), value: String::new() }],
            }
        }
    }
    impl Sample for DiagnosticArray {
        fn sample() -> Self {
            DiagnosticArray { header: Header::sample(), status: vec![DiagnosticStatus::sample()] }
        }
    }
    impl Sample for CalibrateRequest {
        fn sample() -> Self {
            CalibrateRequest { scan_id: 77, dry_run: true }
        }
    }
    impl Sample for CalibrateResponse {
        fn sample() -> Self {
            CalibrateResponse {
                success: true,
                message: "converged".into(),
                alpha0: 0.0349,
                offset: -1.25e-4,
                delta_l: 3.5e-5,
                stddev: vec![1e-5, 2e-6, 3e-6],
                rms_residual: 4.5e-6,
                iterations: 12,
                samples_used: 398,
                scale: 1.0025,
                scale_stddev: 2.1e-4,
            }
        }
    }
    impl Sample for Calibration {
        fn sample() -> Self {
            Calibration {
                header: Header::sample(),
                valid: true,
                model: "full_scale".into(),
                scan_id: 31,
                alpha0: 0.0349,
                offset: -1.25e-4,
                delta_l: 3.5e-5,
                scale: 0.9975,
                stddev: vec![1e-5, 2e-6, 3e-6, 2e-4],
                rms_residual: 4.5e-6,
                samples_used: 398,
            }
        }
    }

    // ---------------------------------------------------------------- round trips

    fn round_trip<T: RosMsg + Sample + PartialEq + fmt::Debug>() {
        let value = T::sample();
        let bytes = to_cdr(&value).unwrap();
        assert_eq!(&bytes[..4], &CDR_LE_HEADER, "{}", T::NAME.ros_name());
        let back: T = from_cdr(&bytes).unwrap();
        assert_eq!(back, value, "{}", T::NAME.ros_name());
        // Every strict prefix of the payload is an error, never a panic or a wrong value.
        for cut in 4..bytes.len() {
            let truncated = &bytes[..cut];
            assert!(
                from_cdr::<T>(truncated).is_err(),
                "{} decoded from {cut} of {} bytes",
                T::NAME.ros_name(),
                bytes.len()
            );
        }
        // Also through rustdds' DDS adapter, the path the publisher and subscription take.
        use rustdds::no_key::{Decode, DefaultDecoder, SerializerAdapter};
        use rustdds::serialization::{CDRDeserializerAdapter, CDRSerializerAdapter};
        let payload = <CDRSerializerAdapter<T> as SerializerAdapter<T>>::to_bytes(&value).unwrap();
        assert_eq!(&payload[..], &bytes[4..]);
        let decoder = <CDRDeserializerAdapter<T> as DefaultDecoder<T>>::DECODER;
        let back: T = decoder.decode_bytes(&payload[..], RepresentationIdentifier::CDR_LE).unwrap();
        assert_eq!(back, value);
    }

    #[test]
    fn cdr_round_trip_of_every_type() {
        round_trip::<Time>();
        round_trip::<Header>();
        round_trip::<RawScan>();
        round_trip::<Contour>();
        round_trip::<Point>();
        round_trip::<Point32>();
        round_trip::<Polygon>();
        round_trip::<PolygonStamped>();
        round_trip::<KeyValue>();
        round_trip::<DiagnosticStatus>();
        round_trip::<DiagnosticArray>();
        round_trip::<CalibrateRequest>();
        round_trip::<CalibrateResponse>();
        round_trip::<Calibration>();
    }

    #[test]
    fn round_trip_of_defaults_and_empty_sequences() {
        let bytes = to_cdr(&RawScan::default()).unwrap();
        assert_eq!(from_cdr::<RawScan>(&bytes).unwrap(), RawScan::default());
        let bytes = to_cdr(&Contour::default()).unwrap();
        assert_eq!(from_cdr::<Contour>(&bytes).unwrap(), Contour::default());
        let bytes = to_cdr(&CalibrateResponse::default()).unwrap();
        assert_eq!(from_cdr::<CalibrateResponse>(&bytes).unwrap(), CalibrateResponse::default());
    }

    #[test]
    fn big_endian_input_is_decoded() {
        // CalibrateRequest { scan_id: 0x01020304, dry_run: true } in big-endian CDR.
        let bytes = [0x00, 0x00, 0x00, 0x00, 0x01, 0x02, 0x03, 0x04, 0x01];
        let req: CalibrateRequest = from_cdr(&bytes).unwrap();
        assert_eq!(req, CalibrateRequest { scan_id: 0x0102_0304, dry_run: true });
    }

    #[test]
    fn bad_cdr_is_rejected() {
        assert_eq!(from_cdr::<CalibrateRequest>(&[0, 1]), Err(CdrError::TooShort(2)));
        let xcdr2 = [0x00, 0x07, 0x00, 0x00, 1, 0, 0, 0, 1];
        assert_eq!(from_cdr::<CalibrateRequest>(&xcdr2), Err(CdrError::Encapsulation([0x00, 0x07])));
        // bool must be 0 or 1
        let bad_bool = [0x00, 0x01, 0x00, 0x00, 1, 0, 0, 0, 2];
        assert!(matches!(from_cdr::<CalibrateRequest>(&bad_bool), Err(CdrError::Codec(_))));
        // padding to 4 is fine, a whole extra word is not
        let padded = [0x00, 0x01, 0x00, 0x03, 1, 0, 0, 0, 1, 0, 0, 0];
        assert_eq!(from_cdr::<CalibrateRequest>(&padded).unwrap(), CalibrateRequest { scan_id: 1, dry_run: true });
        let mut long = padded.to_vec();
        long.extend([0, 0, 0, 0]);
        assert_eq!(from_cdr::<CalibrateRequest>(&long), Err(CdrError::TrailingBytes(7)));
    }

    // ---------------------------------------------------------------- byte-exact layout

    #[test]
    fn raw_scan_bytes_match_hand_computed_cdr() {
        let scan = RawScan {
            header: Header { stamp: Time::new(1, 2), frame_id: "ab".into() },
            scan_id: 7,
            target: RawScan::TARGET_CALIBRATION_PLATE,
            steps_per_revolution: 400,
            step: vec![0, 1],
            counts: vec![-1, 5],
        };
        #[rustfmt::skip]
        let expected: &[u8] = &[
            0x00, 0x01, 0x00, 0x00, // encapsulation: CDR little-endian, options 0
            0x01, 0x00, 0x00, 0x00, // [0]  header.stamp.sec = 1
            0x02, 0x00, 0x00, 0x00, // [4]  header.stamp.nanosec = 2
            0x03, 0x00, 0x00, 0x00, // [8]  header.frame_id length 3 (incl. NUL)
            b'a', b'b', 0x00,       // [12] "ab\0"
            0x00,                   // [15] pad to 4
            0x07, 0x00, 0x00, 0x00, // [16] scan_id = 7
            0x01,                   // [20] target = 1
            0x00, 0x00, 0x00,       // [21] pad to 4
            0x90, 0x01, 0x00, 0x00, // [24] steps_per_revolution = 400
            0x02, 0x00, 0x00, 0x00, // [28] step: 2 elements
            0x00, 0x00, 0x00, 0x00, // [32] 0
            0x01, 0x00, 0x00, 0x00, // [36] 1
            0x02, 0x00, 0x00, 0x00, // [40] counts: 2 elements
            0xff, 0xff, 0xff, 0xff, // [44] -1
            0x05, 0x00, 0x00, 0x00, // [48] 5
        ];
        let bytes = to_cdr(&scan).unwrap();
        assert_eq!(bytes, expected);
        assert_eq!(from_cdr::<RawScan>(expected).unwrap(), scan);
    }

    #[test]
    fn calibrate_response_bytes_align_f64_after_the_header() {
        let resp = CalibrateResponse {
            success: true,
            message: "ok".into(),
            alpha0: 1.0,
            offset: -2.0,
            delta_l: 0.5,
            stddev: vec![0.25],
            rms_residual: 4.0,
            iterations: 3,
            samples_used: 400,
            scale: 1.5,
            scale_stddev: 0.125,
        };
        let mut expected = CDR_LE_HEADER.to_vec();
        expected.extend([0x01]); // [0] success
        expected.extend([0, 0, 0]); // [1] pad to 4
        expected.extend(3u32.to_le_bytes()); // [4] "ok\0" length
        expected.extend(b"ok\0"); // [8]
        expected.extend([0, 0, 0, 0, 0]); // [11] pad to 8 (counted after the header)
        expected.extend(1.0f64.to_le_bytes()); // [16] alpha0
        expected.extend((-2.0f64).to_le_bytes()); // [24] offset
        expected.extend(0.5f64.to_le_bytes()); // [32] delta_l
        expected.extend(1u32.to_le_bytes()); // [40] stddev count
        expected.extend([0, 0, 0, 0]); // [44] pad to 8
        expected.extend(0.25f64.to_le_bytes()); // [48] stddev[0]
        expected.extend(4.0f64.to_le_bytes()); // [56] rms_residual
        expected.extend(3u32.to_le_bytes()); // [64] iterations
        expected.extend(400u32.to_le_bytes()); // [68] samples_used
        expected.extend(1.5f64.to_le_bytes()); // [72] scale
        expected.extend(0.125f64.to_le_bytes()); // [80] scale_stddev
        assert_eq!(to_cdr(&resp).unwrap(), expected);
        assert_eq!(from_cdr::<CalibrateResponse>(&expected).unwrap(), resp);
    }

    #[test]
    fn diagnostic_level_is_one_octet() {
        let status = DiagnosticStatus { level: DiagnosticStatus::STALE, ..Default::default() };
        let bytes = to_cdr(&status).unwrap();
        // level, pad 3, then three empty strings (length 1, NUL, pad 3), then a 0 count.
        let mut expected = CDR_LE_HEADER.to_vec();
        expected.extend([3, 0, 0, 0]);
        for _ in 0..3 {
            expected.extend([1, 0, 0, 0, 0, 0, 0, 0]);
        }
        expected.extend([0, 0, 0, 0]);
        assert_eq!(bytes, expected);
    }

    // ---------------------------------------------------------------- names

    #[test]
    fn type_names_follow_ros_conventions() {
        assert_eq!(type_names::RAW_SCAN.ros_name(), "tracer_calib_msgs/msg/RawScan");
        assert_eq!(type_names::RAW_SCAN.dds_type_name(), "tracer_calib_msgs::msg::dds_::RawScan_");
        assert_eq!(type_names::CONTOUR.dds_type_name(), "tracer_calib_msgs::msg::dds_::Contour_");
        assert_eq!(type_names::POLYGON_STAMPED.ros_name(), "geometry_msgs/msg/PolygonStamped");
        assert_eq!(type_names::DIAGNOSTIC_ARRAY.dds_type_name(), "diagnostic_msgs::msg::dds_::DiagnosticArray_");
        assert_eq!(type_names::HEADER.dds_type_name(), "std_msgs::msg::dds_::Header_");
        assert_eq!(type_names::CALIBRATE_REQUEST.dds_type_name(), "tracer_calib_msgs::srv::dds_::Calibrate_Request_");
        assert_eq!(type_names::CALIBRATE_RESPONSE.dds_type_name(), "tracer_calib_msgs::srv::dds_::Calibrate_Response_");
        // ros2-client's own forms.
        let m = RawScan::NAME.message_type_name();
        assert_eq!(m.dds_msg_type(), "tracer_calib_msgs::msg::dds_::RawScan_");
        let s = Calibrate::type_name();
        assert_eq!((s.package_name(), s.type_name()), ("tracer_calib_msgs", "Calibrate"));
        // The request/response halves are named after the service.
        assert_eq!(<Calibrate as RosService>::Request::NAME.name, format!("{}_Request", Calibrate::NAME.name));
        assert_eq!(<Calibrate as RosService>::Response::NAME.name, format!("{}_Response", Calibrate::NAME.name));
    }

    #[test]
    #[should_panic(expected = "is not a message type")]
    fn service_names_are_not_message_type_names() {
        let _ = type_names::CALIBRATE.message_type_name();
    }

    #[test]
    fn calibrate_response_json_has_the_contract_fields_in_order() {
        let json = serde_json::to_string(&CalibrateResponse::sample()).unwrap();
        let keys = [
            "success",
            "message",
            "alpha0",
            "offset",
            "delta_l",
            "stddev",
            "rms_residual",
            "iterations",
            "samples_used",
            "scale",
            "scale_stddev",
        ];
        let mut at = 0;
        for key in keys {
            let pos = json[at..].find(&format!("\"{key}\":")).unwrap_or_else(|| panic!("{key} missing in {json}"));
            at += pos + 1;
        }
    }

    // ---------------------------------------------------------------- shape recorder
    //
    // A serde Serializer that records the *shape* a value serializes to: struct names, field
    // names in order, primitive kinds, sequence element kinds. This is what CDR sees, so if it
    // matches the .msg field list, the wire layout matches too.

    #[derive(Debug, Clone, PartialEq)]
    enum Shape {
        Prim(&'static str),
        Seq(Vec<Shape>),
        Tuple(Vec<Shape>),
        Struct(&'static str, Vec<(&'static str, Shape)>),
    }

    #[derive(Debug)]
    struct RecordError(String);
    impl fmt::Display for RecordError {
        fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
            f.write_str(&self.0)
        }
    }
    impl std::error::Error for RecordError {}
    impl ser::Error for RecordError {
        fn custom<T: fmt::Display>(msg: T) -> Self {
            RecordError(msg.to_string())
        }
    }

    struct Recorder;

    struct SeqRecorder {
        tuple: bool,
        items: Vec<Shape>,
    }

    struct StructRecorder {
        name: &'static str,
        fields: Vec<(&'static str, Shape)>,
    }

    fn unsupported<T>(what: &str) -> Result<T, RecordError> {
        Err(RecordError(format!("{what} has no ROS 2 message equivalent")))
    }

    impl ser::Serializer for Recorder {
        type Ok = Shape;
        type Error = RecordError;
        type SerializeSeq = SeqRecorder;
        type SerializeTuple = SeqRecorder;
        type SerializeTupleStruct = SeqRecorder;
        type SerializeTupleVariant = Impossible<Shape, RecordError>;
        type SerializeMap = Impossible<Shape, RecordError>;
        type SerializeStruct = StructRecorder;
        type SerializeStructVariant = Impossible<Shape, RecordError>;

        fn serialize_bool(self, _: bool) -> Result<Shape, RecordError> {
            Ok(Shape::Prim("bool"))
        }
        fn serialize_i8(self, _: i8) -> Result<Shape, RecordError> {
            Ok(Shape::Prim("i8"))
        }
        fn serialize_i16(self, _: i16) -> Result<Shape, RecordError> {
            Ok(Shape::Prim("i16"))
        }
        fn serialize_i32(self, _: i32) -> Result<Shape, RecordError> {
            Ok(Shape::Prim("i32"))
        }
        fn serialize_i64(self, _: i64) -> Result<Shape, RecordError> {
            Ok(Shape::Prim("i64"))
        }
        fn serialize_u8(self, _: u8) -> Result<Shape, RecordError> {
            Ok(Shape::Prim("u8"))
        }
        fn serialize_u16(self, _: u16) -> Result<Shape, RecordError> {
            Ok(Shape::Prim("u16"))
        }
        fn serialize_u32(self, _: u32) -> Result<Shape, RecordError> {
            Ok(Shape::Prim("u32"))
        }
        fn serialize_u64(self, _: u64) -> Result<Shape, RecordError> {
            Ok(Shape::Prim("u64"))
        }
        fn serialize_f32(self, _: f32) -> Result<Shape, RecordError> {
            Ok(Shape::Prim("f32"))
        }
        fn serialize_f64(self, _: f64) -> Result<Shape, RecordError> {
            Ok(Shape::Prim("f64"))
        }
        fn serialize_char(self, _: char) -> Result<Shape, RecordError> {
            unsupported("a Rust char (4 bytes in CDR)")
        }
        fn serialize_str(self, _: &str) -> Result<Shape, RecordError> {
            Ok(Shape::Prim("str"))
        }
        fn serialize_bytes(self, _: &[u8]) -> Result<Shape, RecordError> {
            Ok(Shape::Seq(vec![Shape::Prim("u8")]))
        }
        fn serialize_none(self) -> Result<Shape, RecordError> {
            unsupported("Option")
        }
        fn serialize_some<T: ?Sized + Serialize>(self, _: &T) -> Result<Shape, RecordError> {
            unsupported("Option")
        }
        fn serialize_unit(self) -> Result<Shape, RecordError> {
            unsupported("()")
        }
        fn serialize_unit_struct(self, name: &'static str) -> Result<Shape, RecordError> {
            unsupported(name)
        }
        fn serialize_unit_variant(self, name: &'static str, _: u32, _: &'static str) -> Result<Shape, RecordError> {
            unsupported(name)
        }
        fn serialize_newtype_struct<T: ?Sized + Serialize>(
            self,
            name: &'static str,
            _: &T,
        ) -> Result<Shape, RecordError> {
            unsupported(name)
        }
        fn serialize_newtype_variant<T: ?Sized + Serialize>(
            self,
            name: &'static str,
            _: u32,
            _: &'static str,
            _: &T,
        ) -> Result<Shape, RecordError> {
            unsupported(name)
        }
        fn serialize_seq(self, _: Option<usize>) -> Result<SeqRecorder, RecordError> {
            Ok(SeqRecorder { tuple: false, items: Vec::new() })
        }
        fn serialize_tuple(self, _: usize) -> Result<SeqRecorder, RecordError> {
            Ok(SeqRecorder { tuple: true, items: Vec::new() })
        }
        fn serialize_tuple_struct(self, _: &'static str, _: usize) -> Result<SeqRecorder, RecordError> {
            Ok(SeqRecorder { tuple: true, items: Vec::new() })
        }
        fn serialize_tuple_variant(
            self,
            name: &'static str,
            _: u32,
            _: &'static str,
            _: usize,
        ) -> Result<Self::SerializeTupleVariant, RecordError> {
            unsupported(name)
        }
        fn serialize_map(self, _: Option<usize>) -> Result<Self::SerializeMap, RecordError> {
            unsupported("a map")
        }
        fn serialize_struct(self, name: &'static str, _: usize) -> Result<StructRecorder, RecordError> {
            Ok(StructRecorder { name, fields: Vec::new() })
        }
        fn serialize_struct_variant(
            self,
            name: &'static str,
            _: u32,
            _: &'static str,
            _: usize,
        ) -> Result<Self::SerializeStructVariant, RecordError> {
            unsupported(name)
        }
    }

    impl ser::SerializeSeq for SeqRecorder {
        type Ok = Shape;
        type Error = RecordError;
        fn serialize_element<T: ?Sized + Serialize>(&mut self, value: &T) -> Result<(), RecordError> {
            self.items.push(value.serialize(Recorder)?);
            Ok(())
        }
        fn end(self) -> Result<Shape, RecordError> {
            Ok(if self.tuple { Shape::Tuple(self.items) } else { Shape::Seq(self.items) })
        }
    }
    impl ser::SerializeTuple for SeqRecorder {
        type Ok = Shape;
        type Error = RecordError;
        fn serialize_element<T: ?Sized + Serialize>(&mut self, value: &T) -> Result<(), RecordError> {
            ser::SerializeSeq::serialize_element(self, value)
        }
        fn end(self) -> Result<Shape, RecordError> {
            ser::SerializeSeq::end(self)
        }
    }
    impl ser::SerializeTupleStruct for SeqRecorder {
        type Ok = Shape;
        type Error = RecordError;
        fn serialize_field<T: ?Sized + Serialize>(&mut self, value: &T) -> Result<(), RecordError> {
            ser::SerializeSeq::serialize_element(self, value)
        }
        fn end(self) -> Result<Shape, RecordError> {
            ser::SerializeSeq::end(self)
        }
    }
    impl ser::SerializeStruct for StructRecorder {
        type Ok = Shape;
        type Error = RecordError;
        fn serialize_field<T: ?Sized + Serialize>(&mut self, key: &'static str, value: &T) -> Result<(), RecordError> {
            self.fields.push((key, value.serialize(Recorder)?));
            Ok(())
        }
        fn skip_field(&mut self, key: &'static str) -> Result<(), RecordError> {
            Err(RecordError(format!("field {key} is skipped: it would be missing on the wire")))
        }
        fn end(self) -> Result<Shape, RecordError> {
            Ok(Shape::Struct(self.name, self.fields))
        }
    }

    fn shape_kind(shape: &Shape) -> Result<String, String> {
        Ok(match shape {
            Shape::Prim(p) => (*p).to_string(),
            Shape::Struct(name, _) => format!("struct {name}"),
            Shape::Seq(items) => {
                let first = items.first().ok_or("a sample sequence is empty: its element type is unknown")?;
                let kind = shape_kind(first)?;
                for item in items {
                    if shape_kind(item)? != kind {
                        return Err("sequence elements of different kinds".into());
                    }
                }
                format!("sequence of {kind}")
            }
            Shape::Tuple(items) => {
                let kind = match items.first() {
                    Some(first) => shape_kind(first)?,
                    None => "nothing".into(),
                };
                format!("array of {} {kind}", items.len())
            }
        })
    }

    /// The serde kind a ROS field type must serialize to.
    fn ros_kind(ros_type: &str) -> Result<String, String> {
        if let Some(open) = ros_type.find('[') {
            let (base, suffix) = ros_type.split_at(open);
            let inner = suffix.strip_prefix('[').and_then(|s| s.strip_suffix(']')).ok_or("bad array suffix")?;
            let elem = ros_kind(base)?;
            return Ok(if inner.is_empty() || inner.starts_with("<=") {
                format!("sequence of {elem}")
            } else {
                let n: usize = inner.parse().map_err(|_| format!("bad array size in {ros_type}"))?;
                format!("array of {n} {elem}")
            });
        }
        let prim = match ros_type {
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
            "string" => "str",
            t if t.starts_with("string<=") => "str",
            t if t == "wstring" || t.starts_with("wstring<=") => return Err("wstring is not mirrored".into()),
            t => {
                let name = t.rsplit('/').next().unwrap_or(t);
                return Ok(format!("struct {name}"));
            }
        };
        Ok(prim.to_string())
    }

    /// Checks that `value` serializes exactly as the field list says: same field names, same
    /// order, same kinds.
    fn check_struct_against_fields<T: Serialize>(value: &T, fields: &[FieldDef]) -> Result<(), String> {
        let shape = value.serialize(Recorder).map_err(|e| e.to_string())?;
        let Shape::Struct(name, recorded) = shape else {
            return Err(format!("not a struct: {shape:?}"));
        };
        let rust: Vec<(String, String)> = recorded
            .iter()
            .map(|(field, shape)| Ok(((*field).to_string(), shape_kind(shape)?)))
            .collect::<Result<_, String>>()?;
        let ros: Vec<(String, String)> = fields
            .iter()
            .map(|(ty, field)| Ok(((*field).to_string(), ros_kind(ty)?)))
            .collect::<Result<_, String>>()?;
        if rust != ros {
            return Err(format!("struct {name} serializes as\n  {rust:?}\nbut its FIELDS say\n  {ros:?}"));
        }
        Ok(())
    }

    fn check_type<T: RosMsg + Sample>() {
        if let Err(e) = check_struct_against_fields(&T::sample(), T::FIELDS) {
            panic!("{}: {e}", T::NAME.ros_name());
        }
    }

    #[test]
    fn every_struct_serializes_as_its_field_list() {
        check_type::<Time>();
        check_type::<Header>();
        check_type::<RawScan>();
        check_type::<Contour>();
        check_type::<Point>();
        check_type::<Point32>();
        check_type::<Polygon>();
        check_type::<PolygonStamped>();
        check_type::<KeyValue>();
        check_type::<DiagnosticStatus>();
        check_type::<DiagnosticArray>();
        check_type::<CalibrateRequest>();
        check_type::<CalibrateResponse>();
    }

    #[test]
    fn the_struct_check_catches_rust_side_drift() {
        #[derive(Serialize)]
        struct Reordered {
            scan_id: u32,
            dry_run: bool,
            extra: u8,
        }
        #[derive(Serialize)]
        struct Swapped {
            dry_run: bool,
            scan_id: u32,
        }
        #[derive(Serialize)]
        struct Renamed {
            scan: u32,
            dry_run: bool,
        }
        #[derive(Serialize)]
        struct Retyped {
            scan_id: u64,
            dry_run: bool,
        }
        #[derive(Serialize)]
        struct Skips {
            scan_id: u32,
            #[serde(skip_serializing_if = "std::ops::Not::not")]
            dry_run: bool,
        }
        let fields = CalibrateRequest::FIELDS;
        assert!(check_struct_against_fields(&Reordered { scan_id: 1, dry_run: true, extra: 2 }, fields).is_err());
        assert!(check_struct_against_fields(&Swapped { dry_run: true, scan_id: 1 }, fields).is_err());
        assert!(check_struct_against_fields(&Renamed { scan: 1, dry_run: true }, fields).is_err());
        assert!(check_struct_against_fields(&Retyped { scan_id: 1, dry_run: true }, fields).is_err());
        assert!(check_struct_against_fields(&Skips { scan_id: 1, dry_run: false }, fields).is_err());
        // and a correct twin passes
        #[derive(Serialize)]
        struct Twin {
            scan_id: u32,
            dry_run: bool,
        }
        assert_eq!(check_struct_against_fields(&Twin { scan_id: 1, dry_run: true }, fields), Ok(()));
        // nested types are compared by name
        let mut wrong_nested: Vec<FieldDef> = Contour::FIELDS.to_vec();
        wrong_nested[4] = ("geometry_msgs/Point32[]", "points");
        assert!(check_struct_against_fields(&Contour::sample(), &wrong_nested).is_err());
    }

    // ---------------------------------------------------------------- .msg / .srv drift

    /// A parsed interface definition section: fields and constants, types normalized.
    #[derive(Debug, Default, PartialEq)]
    struct Section {
        fields: Vec<(String, String)>,
        constants: Vec<(String, String, String)>,
    }

    fn is_primitive(base: &str) -> bool {
        matches!(
            base,
            "bool"
                | "byte"
                | "char"
                | "int8"
                | "uint8"
                | "int16"
                | "uint16"
                | "int32"
                | "uint32"
                | "int64"
                | "uint64"
                | "float32"
                | "float64"
                | "string"
                | "wstring"
        ) || base.starts_with("string<=")
            || base.starts_with("wstring<=")
    }

    /// `Header` in package p -> `p/Header`; `pkg/msg/T` -> `pkg/T`; primitives unchanged.
    fn normalize_type(ty: &str, own_package: &str) -> String {
        let (base, suffix) = match ty.find('[') {
            Some(i) => ty.split_at(i),
            None => (ty, ""),
        };
        if is_primitive(base) {
            return ty.to_string();
        }
        let parts: Vec<&str> = base.split('/').collect();
        let base = match parts.as_slice() {
            [name] => format!("{own_package}/{name}"),
            [pkg, name] => format!("{pkg}/{name}"),
            [pkg, _, name] => format!("{pkg}/{name}"),
            _ => base.to_string(),
        };
        format!("{base}{suffix}")
    }

    /// Parses a .msg or .srv file: comments stripped, `---` separates sections.
    fn parse_interface(text: &str, own_package: &str) -> Result<Vec<Section>, String> {
        let mut sections = vec![Section::default()];
        for (number, raw) in text.lines().enumerate() {
            let line = raw.split('#').next().unwrap_or("").trim();
            if line.is_empty() {
                continue;
            }
            if line == "---" {
                sections.push(Section::default());
                continue;
            }
            let (ty, rest) = line
                .split_once(char::is_whitespace)
                .ok_or_else(|| format!("line {}: expected 'TYPE NAME', got '{line}'", number + 1))?;
            let ty = normalize_type(ty, own_package);
            let rest = rest.trim();
            let section = sections.last_mut().expect("at least one section");
            if let Some((name, value)) = rest.split_once('=') {
                section.constants.push((ty, name.trim().to_string(), value.trim().to_string()));
            } else {
                // A field, possibly with a default value after the name (not on the wire).
                let name = rest.split_whitespace().next().unwrap_or(rest);
                section.fields.push((ty, name.to_string()));
            }
        }
        Ok(sections)
    }

    fn section_of<T: RosMsg>() -> Section {
        let own = T::NAME.package;
        Section {
            fields: T::FIELDS.iter().map(|(ty, name)| (normalize_type(ty, own), (*name).to_string())).collect(),
            constants: T::CONSTANTS
                .iter()
                .map(|(ty, name, value)| (normalize_type(ty, own), (*name).to_string(), (*value).to_string()))
                .collect(),
        }
    }

    fn compare_section(file: &str, index: usize, parsed: &Section, rust: &Section) -> Result<(), String> {
        if parsed != rust {
            return Err(format!(
                "{file} section {index} and the Rust mirror differ:\n  file: {parsed:?}\n  rust: {rust:?}\n\
                 update src/ros/msgs.rs (struct, FIELDS, CONSTANTS) together with the interface file"
            ));
        }
        Ok(())
    }

    fn check_msg_text<T: RosMsg>(file: &str, text: &str) -> Result<(), String> {
        let sections = parse_interface(text, T::NAME.package)?;
        if sections.len() != 1 {
            return Err(format!("{file}: a message has no '---'"));
        }
        compare_section(file, 0, &sections[0], &section_of::<T>())
    }

    fn check_srv_text<S: RosService>(file: &str, text: &str) -> Result<(), String> {
        let sections = parse_interface(text, S::NAME.package)?;
        if sections.len() != 2 {
            return Err(format!("{file}: a service has exactly one '---', found {}", sections.len() - 1));
        }
        compare_section(file, 0, &sections[0], &section_of::<S::Request>())?;
        compare_section(file, 1, &sections[1], &section_of::<S::Response>())
    }

    fn read_interface(relative: &str) -> String {
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join(relative);
        std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("cannot read {}: {e}", path.display()))
    }

    #[test]
    fn mirrors_match_the_interface_files() {
        let raw_scan = read_interface("msg/msg/RawScan.msg");
        check_msg_text::<RawScan>("msg/msg/RawScan.msg", &raw_scan).unwrap();
        let contour = read_interface("msg/msg/Contour.msg");
        check_msg_text::<Contour>("msg/msg/Contour.msg", &contour).unwrap();
        let calibrate = read_interface("msg/srv/Calibrate.srv");
        check_srv_text::<Calibrate>("msg/srv/Calibrate.srv", &calibrate).unwrap();
    }

    /// Upstream definitions (ROS 2 Jazzy/Kilted), comments dropped.
    const UPSTREAM: &[(&str, &str)] = &[
        ("builtin_interfaces/Time", "int32 sec\nuint32 nanosec\n"),
        ("std_msgs/Header", "builtin_interfaces/Time stamp\nstring frame_id\n"),
        ("geometry_msgs/Point", "float64 x\nfloat64 y\nfloat64 z\n"),
        ("geometry_msgs/Point32", "float32 x\nfloat32 y\nfloat32 z\n"),
        ("geometry_msgs/Polygon", "Point32[] points\n"),
        ("geometry_msgs/PolygonStamped", "std_msgs/Header header\nPolygon polygon\n"),
        ("diagnostic_msgs/KeyValue", "string key  # what to label this value\nstring value\n"),
        (
            "diagnostic_msgs/DiagnosticStatus",
            "byte OK=0\nbyte WARN=1\nbyte ERROR=2\nbyte STALE=3\n\
             byte level\nstring name\nstring message\nstring hardware_id\nKeyValue[] values\n",
        ),
        ("diagnostic_msgs/DiagnosticArray", "std_msgs/Header header\nDiagnosticStatus[] status\n"),
    ];

    fn upstream(name: &str) -> &'static str {
        UPSTREAM.iter().find(|(n, _)| *n == name).map(|(_, text)| *text).expect("known upstream type")
    }

    fn check_upstream<T: RosMsg>() {
        let key = format!("{}/{}", T::NAME.package, T::NAME.name);
        check_msg_text::<T>(&key, upstream(&key)).unwrap();
    }

    #[test]
    fn standard_mirrors_match_the_upstream_definitions() {
        check_upstream::<Time>();
        check_upstream::<Header>();
        check_upstream::<Point>();
        check_upstream::<Point32>();
        check_upstream::<Polygon>();
        check_upstream::<PolygonStamped>();
        check_upstream::<KeyValue>();
        check_upstream::<DiagnosticStatus>();
        check_upstream::<DiagnosticArray>();
    }

    #[test]
    fn the_file_check_catches_interface_drift() {
        let original = read_interface("msg/msg/RawScan.msg");
        let file = "RawScan.msg (edited)";
        assert_eq!(check_msg_text::<RawScan>(file, &original), Ok(()));
        // a field added
        let added = format!("{original}float64 temperature\n");
        assert!(check_msg_text::<RawScan>(file, &added).is_err());
        // a field renamed
        let renamed = original.replace("int32[] counts", "int32[] count");
        assert_ne!(renamed, original);
        assert!(check_msg_text::<RawScan>(file, &renamed).is_err());
        // a field retyped
        let retyped = original.replace("uint32 scan_id", "uint64 scan_id");
        assert_ne!(retyped, original);
        assert!(check_msg_text::<RawScan>(file, &retyped).is_err());
        // two fields swapped
        let swapped = original
            .replace("uint32[] step", "@@STEP@@")
            .replace("int32[] counts", "uint32[] step")
            .replace("@@STEP@@", "int32[] counts");
        assert!(check_msg_text::<RawScan>(file, &swapped).is_err());
        // a constant changed or added
        let constant = original.replace("TARGET_LENS=3", "TARGET_LENS=4");
        assert_ne!(constant, original);
        assert!(check_msg_text::<RawScan>(file, &constant).is_err());
        let more = format!("uint8 TARGET_PATTERN=4\n{original}");
        assert!(check_msg_text::<RawScan>(file, &more).is_err());
        // comments and blank lines do not matter
        let commented = format!("# a new comment\n\n{}", original.replace('#', "  # more #"));
        assert_eq!(check_msg_text::<RawScan>(file, &commented), Ok(()));
        // `Header` vs `std_msgs/Header` vs `std_msgs/msg/Header` are the same type
        let long = original.replace("std_msgs/Header", "std_msgs/msg/Header");
        assert_eq!(check_msg_text::<RawScan>(file, &long), Ok(()));

        let srv = read_interface("msg/srv/Calibrate.srv");
        assert_eq!(check_srv_text::<Calibrate>("Calibrate.srv", &srv), Ok(()));
        let moved = srv.replacen("---\n", "", 1).replacen("string message", "---\nstring message", 1);
        assert!(check_srv_text::<Calibrate>("Calibrate.srv", &moved).is_err());
        let no_sep = srv.replacen("---", "", 1);
        assert!(check_srv_text::<Calibrate>("Calibrate.srv", &no_sep).is_err());
        let response_field = srv.replace("uint32 samples_used", "uint32 samples");
        assert!(check_srv_text::<Calibrate>("Calibrate.srv", &response_field).is_err());
    }

    #[test]
    fn constants_match_their_associated_consts() {
        let rust: &[(&str, u8)] = &[
            ("TARGET_UNKNOWN", RawScan::TARGET_UNKNOWN),
            ("TARGET_CALIBRATION_PLATE", RawScan::TARGET_CALIBRATION_PLATE),
            ("TARGET_FRAME", RawScan::TARGET_FRAME),
            ("TARGET_LENS", RawScan::TARGET_LENS),
        ];
        let declared: Vec<(&str, u8)> =
            RawScan::CONSTANTS.iter().map(|(_, name, value)| (*name, value.parse().unwrap())).collect();
        assert_eq!(declared, rust);
        let rust: &[(&str, u8)] = &[
            ("OK", DiagnosticStatus::OK),
            ("WARN", DiagnosticStatus::WARN),
            ("ERROR", DiagnosticStatus::ERROR),
            ("STALE", DiagnosticStatus::STALE),
        ];
        let declared: Vec<(&str, u8)> =
            DiagnosticStatus::CONSTANTS.iter().map(|(_, name, value)| (*name, value.parse().unwrap())).collect();
        assert_eq!(declared, rust);
    }
}
