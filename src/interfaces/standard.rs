//! The standard ROS 2 types the node and the tools use. Their `.msg` / `.srv` texts are ROS 2's
//! files, copied verbatim from the Kilted packages into `standard/msg/<package>/<Type>.msg` and
//! `standard/srv/<package>/<Service>.srv`; the structs are generated from them (`build.rs`).
//! Jazzy's are the same but for a longer comment in `builtin_interfaces/msg/Time.msg` (the
//! same hash). `type_description_interfaces/msg/KeyValue` is [`TypeKeyValue`]
//! (`diagnostic_msgs`' is [`KeyValue`]); `lifecycle_msgs/msg/State` and `Transition` are
//! [`LifecycleState`] and [`LifecycleTransition`]; `bond/msg/Status` (bond_core's, the
//! heartbeat of nav2's bond) is [`BondStatus`].

use super::{Definition, InterfaceName, RosMsg};

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

include!(concat!(env!("OUT_DIR"), "/standard.rs"));

/// ros2-client's [`Time`] has no `Default`: a header's is time zero, no frame.
impl Default for Header {
    fn default() -> Self {
        Header { stamp: Time::ZERO, frame_id: String::new() }
    }
}
