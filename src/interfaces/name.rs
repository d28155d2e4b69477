//! ROS 2 interface type names: `pkg/msg/Name` and the forms DDS and ros2-client use.

use ros2_client::{MessageTypeName, ServiceTypeName};

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

    /// `msg` or `srv` (what `ros_message!` is given).
    ///
    /// # Panics
    ///
    /// On anything else: at compile time where the macro declares a type.
    pub const fn from_segment(segment: &str) -> Self {
        match segment.as_bytes() {
            b"msg" => InterfaceKind::Msg,
            b"srv" => InterfaceKind::Srv,
            _ => panic!("an interface kind is msg or srv"),
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
    /// A type name.
    pub const fn new(package: &'static str, kind: InterfaceKind, name: &'static str) -> Self {
        InterfaceName { package, kind, name }
    }

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
