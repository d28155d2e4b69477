//! The node's entities, on either middleware ([`super::backend`]): its endpoints (names and
//! QoS resolved by [`super::endpoints`]), made by the same code on both.
//!
//! | kind | name | QoS |
//! |---|---|---|
//! | subscription | `raw_scan` | reliable, keep last 100, volatile |
//! | publisher | `contour`, `contour_polygon` | reliable, keep last 10, volatile |
//! | service | `calibrate` (on DDS, Fast DDS' "Enhanced" mapping) | reliable, keep last 1000 |
//! | publisher | `calibrate/_service_event` (its introspection, when `calibrate.introspection` is not `off`) | reliable, keep last 10, volatile (ROS's services default) |
//! | publisher | `/diagnostics`, 1 Hz | reliable, keep last 10 |
//! | publisher | `calibration` (the calibration in force) | reliable, transient local, keep last 1 |
//! | service | `~/get_type_description` (REP-2016) | reliable, keep last 10 |
//! | services, publisher | `~/change_state`, ... `~/transition_event` (managed only: [`super::lifecycle`]) | reliable, keep last 10 |
//!
//! Every endpoint, ros2-client's own included, announces its type's hash (DDS:
//! [`crate::rmw::dds::context`]; Zenoh: [`super::zenoh`]).
//!
//! Why: every scan is a measurement an edger acts on, so delivery is reliable (as the
//! ROS default a tracer driver publishes with; a best-effort "sensor data" publisher
//! does not match a reliable subscription: the node warns, and
//! `qos_overrides./raw_scan.subscription.reliability: best_effort` serves it); the
//! subscription keeps 100 scans so a bag replayed at full speed is not thinned out;
//! contours are not latched (volatile): a late subscriber wants the next scan, not an
//! old one. The calibration in force is latched: whoever joins later must know which
//! calibration the contours it receives were corrected with.
//!
//! On DDS, memory is bounded by these depths at any scan rate: the patched rustdds
//! (`vendor/rustdds/PATCHES.md`) releases a written contour once it is out of the
//! depth and acknowledged by every reliable subscriber, and the `raw_scan` reader's
//! cache keeps at most its depth (BENCHMARKS.md, "Throughput and memory").

use std::sync::Mutex;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::{Duration, Instant};

use futures::{Stream, StreamExt};
use ros2_client::{MessageTypeName, Name, QosProfile, RmwRequestId};

use super::backend::{Backend, Opened};
use super::endpoints::{Endpoints, NO_EVENT_PUBLISHER, introspection_refused, latched, private_name, reliable};
use super::lifecycle::Lifecycle;
use super::{RateLimit, RosClock, Wire};
use crate::interfaces::{
    Calibrate, CalibrateEvent, CalibrateRequest, CalibrateResponse, Contour, DiagnosticArray, GetTypeDescription,
    GetTypeDescriptionRequest, GetTypeDescriptionResponse, PolygonStamped, RawScan, RosMsg, RosService,
    tracer_calib_msgs as msgs,
};
use crate::names::NodeIdentity;
use crate::rmw::dds::TypesInUse;
use crate::ros::logging::RosoutRecord;

/// Calibrate requests waiting for the one-at-a-time fit. The DDS reader drops the
/// oldest unread sample past this depth, and a dropped request is a caller waiting
/// forever: with ROS's service default of 10, eleven calls arriving during one fit
/// would lose one. A request is a few bytes, so the bound is generous.
const CALIBRATE_QUEUE: usize = 1000;

/// The node's entities on the backend `B`: what the loops read from and write to.
pub(super) struct Entities<B: Backend> {
    pub ctx: B::Context,
    pub node: B::Node,
    pub raw_scans: B::Subscription<RawScan>,
    pub contours: B::Publisher<Contour>,
    pub polygons: B::Publisher<PolygonStamped>,
    pub diagnostics: B::Publisher<DiagnosticArray>,
    pub calibration: B::Publisher<msgs::Calibration>,
    pub calibrate: B::Server<Calibrate>,
    /// `None` if the middleware refused it (a secure cell's permissions without the topic).
    pub calibrate_events: Option<B::Publisher<CalibrateEvent>>,
    pub type_description: B::Server<GetTypeDescription>,
    /// The lifecycle services and events of a managed node.
    pub lifecycle: Option<Lifecycle<B>>,
    /// The types of the node's endpoints, which `type_description` describes.
    pub types_in_use: TypesInUse,
    /// rcl's logger name of the node (`cell1.tracer`), for its `/rosout` records.
    logger_name: String,
    /// The `calibrate` requests that could not be read, where the backend does not count
    /// them itself ([`Backend::unreadable_requests`]).
    calibrate_unreadable: Unreadable,
    spinner: B::Spinner,
}

/// Requests that could not be read (a payload that is no request, no attachment), counted
/// by the shell, and the limit on warning of them (one a second).
struct Unreadable {
    count: AtomicU64,
    log: Mutex<RateLimit>,
}

impl Unreadable {
    /// One more, warned of if the limit allows.
    fn add(&self, err: &str) {
        let n = self.count.fetch_add(1, Ordering::Relaxed) + 1;
        if let Some(held) = self.log.lock().expect("rate limit lock").allow(Instant::now()) {
            log::warn!("an unreadable calibrate request, not answered: {err} ({n} so far, {held} not shown)");
        }
    }
}

/// The topic `name` for messages of type `M` with `qos`.
fn topic<B: Backend, M: RosMsg>(node: &mut B::Node, name: &Name, qos: &QosProfile) -> Result<B::Topic, String> {
    B::topic(node, name, M::NAME.message_type_name(), qos).map_err(|e| B::cannot_create(B::ENTITY, e))
}

impl<B: Backend> Entities<B> {
    /// On the node `opened` (`identity`), its endpoints (and the lifecycle's if
    /// `managed`), and its traffic moving ([`Backend::spin`]).
    pub fn create(
        opened: Opened<B>,
        identity: &NodeIdentity,
        endpoints: &Endpoints,
        managed: bool,
    ) -> Result<Self, String> {
        let Opened { ctx, mut node, types_in_use } = opened;
        let mk = |e: ros2_client::CreateError| B::cannot_create(B::ENTITY, e);
        let Endpoints { raw_scan, contour, polygon, diagnostics, calibration, calibrate, calibrate_event, bond } =
            endpoints;
        let raw_topic = topic::<B, RawScan>(&mut node, &raw_scan.0, &raw_scan.1)?;
        let contour_topic = topic::<B, Contour>(&mut node, &contour.0, &contour.1)?;
        let polygon_topic = topic::<B, PolygonStamped>(&mut node, &polygon.0, &polygon.1)?;
        let diag_topic = topic::<B, DiagnosticArray>(&mut node, diagnostics, &reliable(10))?;
        let calibration_topic = topic::<B, msgs::Calibration>(&mut node, calibration, &latched())?;
        let raw_scans = B::subscription::<RawScan>(&mut node, &raw_topic).map_err(mk)?;
        let contours = B::publisher::<Contour>(&mut node, &contour_topic).map_err(mk)?;
        let polygons = B::publisher::<PolygonStamped>(&mut node, &polygon_topic).map_err(mk)?;
        let diagnostics = B::publisher::<DiagnosticArray>(&mut node, &diag_topic).map_err(mk)?;
        let calibration = B::publisher::<msgs::Calibration>(&mut node, &calibration_topic).map_err(mk)?;
        let calibrate = B::server::<Calibrate>(&mut node, calibrate, reliable(CALIBRATE_QUEUE)).map_err(mk)?;
        // Optional: a secure cell whose permissions were signed before the node had it
        // (no grant for the topic) keeps its node; introspection then publishes nothing.
        let event_type: MessageTypeName = Calibrate::type_name().event_message_type_name();
        let calibrate_events = B::topic(&mut node, calibrate_event, event_type, &reliable(10))
            .and_then(|topic| B::publisher::<CalibrateEvent>(&mut node, &topic))
            .map_err(|e| introspection_refused(calibrate_event, mk(e)))
            .ok();
        let type_description_name = private_name(&identity.fully_qualified_name(), "get_type_description")?;
        let type_description =
            B::server::<GetTypeDescription>(&mut node, &type_description_name, reliable(10)).map_err(mk)?;
        let lifecycle =
            if managed { Some(Lifecycle::create(&mut node, &identity.fully_qualified_name(), bond)?) } else { None };
        let spinner = B::spin(&mut node).map_err(mk)?;
        Ok(Entities {
            ctx,
            node,
            raw_scans,
            contours,
            polygons,
            diagnostics,
            calibration,
            calibrate,
            calibrate_events,
            type_description,
            lifecycle,
            types_in_use,
            logger_name: identity.logger_name(),
            calibrate_unreadable: Unreadable {
                count: AtomicU64::new(0),
                log: Mutex::new(RateLimit::new(Duration::from_secs(1))),
            },
            spinner,
        })
    }

    /// The node's clock (simulated under `use_sim_time`).
    pub fn clock(&self) -> RosClock {
        B::clock(&self.node)
    }

    /// Tear down in order: each endpoint dropped first (DDS: discovery announces it gone;
    /// Zenoh: its liveliness token undeclared, so peers see it gone at once), then the node
    /// and the connection ([`Backend::close`]). Without this, DDS peers keep the node's
    /// topics and services in their graphs for the lease duration.
    pub fn close(self) {
        let Entities {
            ctx,
            node,
            raw_scans,
            contours,
            polygons,
            diagnostics,
            calibration,
            calibrate,
            calibrate_events,
            type_description,
            lifecycle,
            types_in_use: _,
            logger_name: _,
            calibrate_unreadable: _,
            spinner,
        } = self;
        drop((raw_scans, contours, polygons, diagnostics, calibration, calibrate, calibrate_events));
        drop((type_description, lifecycle));
        B::close(ctx, node, spinner);
    }
}

impl<B: Backend> Wire for Entities<B> {
    type RequestId = RmwRequestId;

    fn raw_scans(&self) -> impl Stream<Item = Result<RawScan, String>> + '_ {
        B::messages(&self.raw_scans)
    }

    fn publish_contour(&self, msg: Contour) -> impl Future<Output = Result<(), String>> + '_ {
        B::publish(&self.contours, msg)
    }

    fn publish_polygon(&self, msg: PolygonStamped) -> impl Future<Output = Result<(), String>> + '_ {
        B::publish(&self.polygons, msg)
    }

    fn publish_diagnostics(&self, msg: DiagnosticArray) -> impl Future<Output = Result<(), String>> + '_ {
        B::publish(&self.diagnostics, msg)
    }

    fn publish_calibration(&self, msg: msgs::Calibration) -> impl Future<Output = Result<(), String>> + '_ {
        B::publish(&self.calibration, msg)
    }

    fn calibrate_requests(&self) -> impl Stream<Item = Result<(RmwRequestId, CalibrateRequest), String>> + '_ {
        // Where the backend does not count the requests it cannot read (Zenoh), each is
        // counted (and warned of, once a second at most) here, as the DDS server counts
        // its own; it gets no reply.
        B::requests(&self.calibrate).inspect(|r| {
            if let Err(err) = r
                && B::unreadable_requests(&self.calibrate).is_none()
            {
                self.calibrate_unreadable.add(err);
            }
        })
    }

    fn calibrate_unreadable(&self) -> u64 {
        B::unreadable_requests(&self.calibrate)
            .unwrap_or_else(|| self.calibrate_unreadable.count.load(Ordering::Relaxed))
    }

    fn answer_calibrate(
        &self,
        id: RmwRequestId,
        response: CalibrateResponse,
    ) -> impl Future<Output = Result<(), String>> + '_ {
        B::respond(&self.calibrate, id, response)
    }

    async fn publish_calibrate_event(&self, msg: CalibrateEvent) -> Result<(), String> {
        match &self.calibrate_events {
            Some(p) => B::publish(p, msg).await,
            None => Err(NO_EVENT_PUBLISHER.to_string()),
        }
    }

    fn type_description_requests(
        &self,
    ) -> impl Stream<Item = Result<(RmwRequestId, GetTypeDescriptionRequest), String>> + '_ {
        B::requests(&self.type_description)
    }

    fn answer_type_description(
        &self,
        id: RmwRequestId,
        response: GetTypeDescriptionResponse,
    ) -> impl Future<Output = Result<(), String>> + '_ {
        B::respond(&self.type_description, id, response)
    }

    fn types_in_use(&self) -> Vec<String> {
        self.types_in_use.names()
    }

    fn set_parameters(&self, params: Vec<ros2_client::Parameter>) -> Result<(), String> {
        B::set_parameters(&self.node, params)
    }

    fn raw_scan_publishers(&self) -> usize {
        B::publisher_count(&self.raw_scans, &self.node)
    }

    fn rosout(&self, record: &RosoutRecord) {
        B::rosout(&self.node, &self.logger_name, record)
    }

    fn use_sim_time(&self) -> bool {
        B::use_sim_time(&self.node)
    }
}
