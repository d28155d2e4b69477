//! The standard ROS 2 types the node and the tools use, with their `.msg` texts as ROS 2
//! ships them (`standard/msg/<package>/<Type>.msg`, copied verbatim from the Kilted
//! packages; Jazzy's are the same).

use super::{Definition, InterfaceName, RosMsg, ros_message};

/// `builtin_interfaces/msg/Time`: ros2-client's own type, reused (wire: `int32 sec`,
/// `uint32 nanosec`). Construct with [`Time::new`]`(sec, nanosec)` or `Time::from_nanos`.
///
/// In memory it is a signed nanosecond count, so a wire value with `nanosec >= 10^9` is
/// folded into the seconds on receipt (ros2-client logs a warning).
pub use ros2_client::builtin_interfaces::Time;

impl RosMsg for Time {
    const NAME: InterfaceName = InterfaceName::msg("builtin_interfaces", "Time");
    const DEFINITION: Definition = Definition::Msg(include_str!("standard/msg/builtin_interfaces/Time.msg"));
}

ros_message! {
    /// `std_msgs/msg/Header`: a timestamp and a coordinate frame id.
    #[derive(Debug, Clone, PartialEq)]
    pub struct Header(std_msgs/msg/Header, Definition::Msg(include_str!("standard/msg/std_msgs/Header.msg"))) {
        /// Time of the data.
        pub stamp: Time,
        /// Coordinate frame the data is expressed in.
        pub frame_id: String,
    }
}

impl Default for Header {
    fn default() -> Self {
        Header { stamp: Time::ZERO, frame_id: String::new() }
    }
}

ros_message! {
    /// `geometry_msgs/msg/Point`: a position, `float64` coordinates.
    #[derive(Debug, Clone, Copy, Default, PartialEq)]
    pub struct Point(geometry_msgs/msg/Point, Definition::Msg(include_str!("standard/msg/geometry_msgs/Point.msg"))) {
        /// x, metres.
        pub x: f64,
        /// y, metres.
        pub y: f64,
        /// z, metres.
        pub z: f64,
    }
}

ros_message! {
    /// `geometry_msgs/msg/Point32`: a position, `float32` coordinates.
    #[derive(Debug, Clone, Copy, Default, PartialEq)]
    pub struct Point32(
        geometry_msgs/msg/Point32,
        Definition::Msg(include_str!("standard/msg/geometry_msgs/Point32.msg"))
    ) {
        /// x, metres.
        pub x: f32,
        /// y, metres.
        pub y: f32,
        /// z, metres.
        pub z: f32,
    }
}

ros_message! {
    /// `geometry_msgs/msg/Polygon`: a closed polygon (the last point connects to the first).
    #[derive(Debug, Clone, Default, PartialEq)]
    pub struct Polygon(
        geometry_msgs/msg/Polygon,
        Definition::Msg(include_str!("standard/msg/geometry_msgs/Polygon.msg"))
    ) {
        /// The vertices.
        pub points: Vec<Point32>,
    }
}

ros_message! {
    /// `geometry_msgs/msg/PolygonStamped`: a polygon with a header.
    #[derive(Debug, Clone, Default, PartialEq)]
    pub struct PolygonStamped(
        geometry_msgs/msg/PolygonStamped,
        Definition::Msg(include_str!("standard/msg/geometry_msgs/PolygonStamped.msg"))
    ) {
        /// Time and frame of the polygon.
        pub header: Header,
        /// The polygon.
        pub polygon: Polygon,
    }
}

ros_message! {
    /// `diagnostic_msgs/msg/KeyValue`: one named value of a diagnostic status.
    #[derive(Debug, Clone, Default, PartialEq, Eq)]
    pub struct KeyValue(
        diagnostic_msgs/msg/KeyValue,
        Definition::Msg(include_str!("standard/msg/diagnostic_msgs/KeyValue.msg"))
    ) {
        /// What the value is.
        pub key: String,
        /// The value, as text.
        pub value: String,
    }
}

ros_message! {
    /// `diagnostic_msgs/msg/DiagnosticStatus`: the state of one component.
    #[derive(Debug, Clone, Default, PartialEq, Eq)]
    pub struct DiagnosticStatus(
        diagnostic_msgs/msg/DiagnosticStatus,
        Definition::Msg(include_str!("standard/msg/diagnostic_msgs/DiagnosticStatus.msg"))
    ) {
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

ros_message! {
    /// `diagnostic_msgs/msg/DiagnosticArray`: what is published on `/diagnostics`.
    #[derive(Debug, Clone, Default, PartialEq)]
    pub struct DiagnosticArray(
        diagnostic_msgs/msg/DiagnosticArray,
        Definition::Msg(include_str!("standard/msg/diagnostic_msgs/DiagnosticArray.msg"))
    ) {
        /// Time of the report.
        pub header: Header,
        /// One entry per component.
        pub status: Vec<DiagnosticStatus>,
    }
}
