//! The node's endpoints as names and QoS, before any middleware: their names (after
//! namespace and remaps) and their QoS (with the `qos_overrides.*` in force), and the
//! helpers both the node's entities ([`super::entities`]) and a managed node's lifecycle
//! entities ([`super::lifecycle`]) are made with. Which endpoints there are, with which
//! QoS and why: [`super::entities`].

use log::{info, warn};
use ros2_client::{
    Name, QosProfile,
    qos::{Durability, History, WhenFull},
};

use crate::names::{NodeIdentity, ros2_name};
use crate::ros::args::RosArgs;
use crate::ros::qos_overrides::{QosOverrides, Side};

/// Reliable, volatile, keep last `depth`: ROS's default for publishers, subscriptions and
/// services, at a depth of the endpoint's own.
pub(super) fn reliable(depth: usize) -> QosProfile {
    QosProfile::publisher_default()
        .reliability_reliable(WhenFull::DEFAULT)
        .durability(Durability::Volatile)
        .history(History::KeepLast { depth })
}

/// The `calibration` topic: reliable, transient local, depth 1, so a subscriber that
/// joins later gets the calibration in force at once.
pub(super) fn latched() -> QosProfile {
    QosProfile::publisher_default()
        .reliability_reliable(WhenFull::DEFAULT)
        .durability(Durability::TransientLocal)
        .history(History::KeepLast { depth: 1 })
}

/// A name in the node's private namespace (`~/suffix`, the node being `fqn`): its
/// type description and lifecycle services, on either middleware.
pub(super) fn private_name(fqn: &str, suffix: &str) -> Result<Name, String> {
    ros2_name(&format!("{fqn}/{suffix}")).map_err(|e| e.to_string())
}

/// The node's endpoints, resolved: names and QoS.
pub(super) struct Endpoints {
    pub raw_scan: (Name, QosProfile),
    pub contour: (Name, QosProfile),
    pub polygon: (Name, QosProfile),
    pub diagnostics: Name,
    pub calibration: Name,
    pub calibrate: Name,
    /// `<calibrate>/_service_event`, its introspection.
    pub calibrate_event: Name,
    /// `bond`, a managed node's bond with nav2's lifecycle manager ([`super::bond`]), if it
    /// keeps one.
    pub bond: Option<Name>,
}

impl Endpoints {
    /// Names resolved for `identity` with the remaps of `args`; the QoS overrides applied
    /// to the topics they are for (one warning for each that names no endpoint of the node;
    /// `qos` keeps only those in force). `bond`: the node keeps nav2's bond.
    pub fn resolve(
        args: &RosArgs,
        identity: &NodeIdentity,
        qos: &mut QosOverrides,
        bond: bool,
    ) -> Result<Self, String> {
        let topic = |name: &str| -> Result<Name, String> {
            let resolved = args.resolve_topic(name, identity).map_err(|e| e.to_string())?;
            ros2_name(&resolved).map_err(|e| e.to_string())
        };
        let (raw, contour, polygon) = (topic("raw_scan")?, topic("contour")?, topic("contour_polygon")?);
        let (raw_fq, contour_fq, polygon_fq) = (raw.to_string(), contour.to_string(), polygon.to_string());
        let overridable = [
            (raw_fq.as_str(), Side::Subscription),
            (contour_fq.as_str(), Side::Publisher),
            (polygon_fq.as_str(), Side::Publisher),
        ];
        for w in qos.unused(&overridable) {
            warn!("{w}");
        }
        qos.retain_for(&overridable);
        let raw_qos = qos.apply(&raw_fq, Side::Subscription, reliable(100));
        let contour_qos = qos.apply(&contour_fq, Side::Publisher, reliable(10));
        let polygon_qos = qos.apply(&polygon_fq, Side::Publisher, reliable(10));
        if !qos.is_empty() {
            info!("QoS overrides: {:?}", qos.to_list());
        }
        let calibrate = {
            let resolved = args.resolve_service("calibrate", identity).map_err(|e| e.to_string())?;
            ros2_name(&resolved).map_err(|e| e.to_string())?
        };
        let calibrate_event = ros2_name(&format!("{calibrate}/_service_event")).map_err(|e| e.to_string())?;
        Ok(Endpoints {
            raw_scan: (raw, raw_qos),
            contour: (contour, contour_qos),
            polygon: (polygon, polygon_qos),
            diagnostics: topic("/diagnostics")?,
            calibration: topic("calibration")?,
            calibrate,
            calibrate_event,
            bond: if bond { Some(topic("bond")?) } else { None },
        })
    }
}

/// Why an introspection event was not published: its publisher was refused at start-up.
pub(super) const NO_EVENT_PUBLISHER: &str =
    "no publisher on the service's _service_event topic (refused at start-up: see the warning then)";

/// Log that the middleware refused `calibrate`'s introspection publisher (`topic`).
pub(super) fn introspection_refused(topic: &Name, reason: String) {
    warn!(
        "{reason}: {topic} cannot be published (for a secure cell: not in the enclave's permissions); calibrate.introspection will publish nothing"
    );
}
