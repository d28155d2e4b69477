//! DDS graph events: the polygon writer's matches (polygons only when someone listens), and
//! remote endpoints discovered with an incompatible QoS, each counted and reported once
//! (when its peer's node is known, or has not come in time: checked once a second).

use std::sync::atomic::Ordering;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use futures::StreamExt;
use log::{error, warn};
use ros2_client::dds::{Context, NodeEvent};

use super::dds::Dds;
use super::entities::Entities;
use super::{RateLimit, Shared};
use crate::cell::NodeState;

/// Keeps [`Shared::polygon_wanted`] from the polygon writer's match events (the scan loop
/// only reads the flag, so the first scan after a subscriber matched gets its polygon), and
/// hands incompatible-QoS events to the reports; once a second, reports those whose peer
/// node is known by now (or that waited long enough). Ends when the events do.
pub(super) async fn run(e: &Entities<Dds>, shared: &Shared) {
    let node = &e.node;
    let wanted = || e.polygons.get_subscription_count(node) > 0;
    let Some(events) = node.status_receiver() else {
        error!("no graph events: polygons are published always");
        shared.polygon_wanted.store(true, Ordering::Relaxed);
        return futures::future::pending().await;
    };
    // Matches before the receiver existed are in the map already.
    shared.polygon_wanted.store(wanted(), Ordering::Relaxed);
    let mut second = smol::Timer::interval(Duration::from_secs(1));
    loop {
        // `None`: a second has passed.
        let event = smol::future::or(async { Some(events.recv().await) }, async {
            second.next().await;
            None
        })
        .await;
        match event {
            None => shared.qos_reports.lock().expect("qos reports lock").flush(node, Instant::now(), false),
            Some(Err(_)) => return,
            Some(Ok(NodeEvent::Graph(_))) => shared.polygon_wanted.store(wanted(), Ordering::Relaxed),
            Some(Ok(NodeEvent::QosIncompatible { local, remote, local_is_writer, policy })) => {
                let topic = ctx_topic_of(&e.ctx, remote, local_is_writer);
                let mut reports = shared.qos_reports.lock().expect("qos reports lock");
                reports.add(local, remote, local_is_writer, policy, topic, Instant::now());
                reports.flush(node, Instant::now(), false);
            }
            Some(Ok(_)) => {}
        }
    }
}

/// The ROS name of the topic of a remote endpoint, from discovery (`rt/raw_scan` ->
/// `/raw_scan`; a service's DDS topic as it is).
fn ctx_topic_of(ctx: &Context, remote: rustdds::GUID, remote_is_reader: bool) -> String {
    let dp = ctx.domain_participant();
    let dds = if remote_is_reader {
        dp.discovered_readers()
            .into_iter()
            .find(|r| r.reader_proxy.remote_reader_guid == remote)
            .map(|r| r.subscription_topic_data.topic_name().clone())
    } else {
        dp.discovered_writers()
            .into_iter()
            .find(|w| w.writer_proxy.remote_writer_guid == remote)
            .map(|w| w.publication_topic_data.topic_name.clone())
    };
    match dds {
        Some(name) => match name.strip_prefix("rt/") {
            Some(ros) => format!("/{ros}"),
            None => name,
        },
        None => "an unknown topic".to_string(),
    }
}

/// How long a report of incompatible QoS waits for the peer's node name
/// (`ros_discovery_info` may come after the endpoint).
const QOS_REPORT_WAIT: Duration = Duration::from_secs(3);

/// Remote endpoints discovered with a QoS incompatible with the node's endpoint on their
/// topic: each counted (on `/diagnostics`) and reported once, as stock nodes do: a WARN
/// naming topic, peer node and policy, rate-limited to one a second.
pub(super) struct QosReports {
    state: Arc<Mutex<NodeState>>,
    seen: std::collections::HashSet<(rustdds::GUID, rustdds::GUID)>,
    pending: Vec<PendingQos>,
    limit: RateLimit,
}

struct PendingQos {
    remote: rustdds::GUID,
    local_is_writer: bool,
    policy: Option<rustdds::qos::QosPolicyId>,
    topic: String,
    since: Instant,
}

impl QosReports {
    pub(super) fn new(state: Arc<Mutex<NodeState>>) -> Self {
        QosReports {
            state,
            seen: Default::default(),
            pending: Vec::new(),
            limit: RateLimit::new(Duration::from_secs(1)),
        }
    }

    fn add(
        &mut self,
        local: rustdds::GUID,
        remote: rustdds::GUID,
        local_is_writer: bool,
        policy: Option<rustdds::qos::QosPolicyId>,
        topic: String,
        now: Instant,
    ) {
        if !self.seen.insert((local, remote)) {
            return;
        }
        let mut st = self.state.lock().expect("state lock");
        st.stats.qos_incompatible += 1;
        st.stats.last_qos_incompatible = format!("{topic}: {}", policy_name(policy));
        drop(st);
        self.pending.push(PendingQos { remote, local_is_writer, policy, topic, since: now });
    }

    /// Report what is pending whose node is known, or has waited long enough.
    pub(super) fn flush(&mut self, node: &ros2_client::dds::Node, now: Instant, force: bool) {
        let (state, limit) = (&self.state, &mut self.limit);
        self.pending.retain(|p| {
            let name = node.remote_node_of_endpoint(p.remote);
            if name.is_none() && !force && now.duration_since(p.since) < QOS_REPORT_WAIT {
                return true;
            }
            let who = name.unwrap_or_else(|| format!("unknown (participant {:?})", p.remote.prefix));
            let (kind, verb, flow) = if p.local_is_writer {
                ("subscription", "requesting", "No messages will be sent to it")
            } else {
                ("publisher", "offering", "No messages will be received from it")
            };
            let policy = policy_name(p.policy);
            state.lock().expect("state lock").stats.last_qos_incompatible =
                format!("{kind} of node {who} on {}: {policy}", p.topic);
            if let Some(held) = limit.allow(now) {
                let more = if held > 0 { format!(" ({held} more not shown)") } else { String::new() };
                warn!(
                    "New {kind} discovered on topic '{}' (node {who}), {verb} incompatible QoS. {flow}. \
                     Last incompatible policy: {policy}{more}",
                    p.topic
                );
            }
            false
        });
    }
}

/// A QoS policy's name as ROS prints it (`RELIABILITY`).
fn policy_name(policy: Option<rustdds::qos::QosPolicyId>) -> String {
    match policy {
        Some(p) => format!("{p:?}").to_uppercase(),
        None => "UNKNOWN".to_string(),
    }
}
