//! What the node's loops share besides the middleware's entities: the cell's state (every
//! handler runs under its lock), the signal that the calibration in force changed, the
//! graph's findings, the node's ROS clock and nav2's bond. Made once in [`super::run`];
//! each loop takes it by reference.

use std::sync::atomic::AtomicBool;
use std::sync::{Arc, Mutex, OnceLock};

use ros2_client::dds::NodeClock;

use super::graph::QosReports;
use crate::cell::{NodeState, Now};

/// What the loops share besides the entities.
pub(super) struct Shared {
    /// The cell's state: every handler runs under this lock.
    pub(super) state: Arc<Mutex<NodeState>>,
    /// The calibration in force changed (a parameter set, a `/calibrate` that applied):
    /// the [`calibration`](super::calibration) loop publishes it.
    pub(super) calibration_changed: smol::channel::Sender<()>,
    /// Its receiving end, the [`calibration`](super::calibration) loop's.
    pub(super) calibration_changes: smol::channel::Receiver<()>,
    /// Whether anyone subscribes to the polygons (kept by [`graph`](super::graph), read by [`scans`](super::scans)).
    pub(super) polygon_wanted: AtomicBool,
    /// Remote endpoints with an incompatible QoS, reported once each.
    pub(super) qos_reports: Mutex<QosReports>,
    /// The node's clock (simulated under `use_sim_time`), once the node exists.
    pub(super) clock: Arc<OnceLock<RosClock>>,
    /// A managed node's end of nav2's bond, while it keeps one ([`bond`](super::bond)).
    pub(super) bond: Mutex<Option<crate::cell::bond::Bond>>,
}

/// The node's ROS clock, from its middleware's node: the last `/clock` under
/// `use_sim_time`, else the system time.
pub(super) enum RosClock {
    Dds(NodeClock),
    #[cfg(feature = "zenoh")]
    Zenoh(ros2_client::zenoh::NodeClock),
}

impl RosClock {
    pub(super) fn now(&self) -> ros2_client::ROSTime {
        match self {
            RosClock::Dds(c) => c.now(),
            #[cfg(feature = "zenoh")]
            RosClock::Zenoh(c) => c.now(),
        }
    }
}

impl Shared {
    /// The shared state of a node starting from `initial`: no calibration change pending, no
    /// polygon subscriber, no clock yet, no bond.
    pub(super) fn new(initial: NodeState) -> Shared {
        let state = Arc::new(Mutex::new(initial));
        let (calibration_changed, calibration_changes) = smol::channel::unbounded::<()>();
        Shared {
            qos_reports: Mutex::new(QosReports::new(state.clone())),
            state,
            calibration_changed,
            calibration_changes,
            polygon_wanted: AtomicBool::new(false),
            clock: Arc::new(OnceLock::new()),
            bond: Mutex::new(None),
        }
    }

    /// Now, on the system clock and on the node's ROS clock.
    pub(super) fn now(&self) -> Now {
        now_on(&self.clock)
    }
}

/// Now, on the system clock and on `clock` (the system clock too until it is set).
pub(super) fn now_on(clock: &OnceLock<RosClock>) -> Now {
    let now = Now::system();
    match clock.get() {
        Some(clock) => Now { ros: clock.now().into(), ..now },
        None => now,
    }
}
