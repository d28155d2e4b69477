//! The node's endpoints (names and QoS resolved by [`super::endpoints`]) and the DDS
//! entities made from them.
//!
//! | kind | name | QoS |
//! |---|---|---|
//! | subscription | `raw_scan` | reliable, keep last 100, volatile |
//! | publisher | `contour`, `contour_polygon` | reliable, keep last 10, volatile |
//! | service | `calibrate` (Fast DDS "Enhanced" mapping) | reliable, keep last 1000 |
//! | publisher | `calibrate/_service_event` (its introspection, when `calibrate.introspection` is not `off`) | reliable, keep last 10, volatile (ROS's services default) |
//! | publisher | `/diagnostics`, 1 Hz | reliable, keep last 10 |
//! | publisher | `calibration` (the calibration in force) | reliable, transient local, keep last 1 |
//! | service | `~/get_type_description` (REP-2016) | reliable, keep last 10 |
//! | services, publisher | `~/change_state`, ... `~/transition_event` (managed only: [`super::lifecycle`]) | reliable, keep last 10 |
//!
//! Every endpoint, ros2-client's own included, announces its type's hash
//! ([`crate::rmw::dds::context`]).
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
//! Memory is bounded by these depths at any scan rate: the patched rustdds
//! (`vendor/rustdds/PATCHES.md`) releases a written contour once it is out of the
//! depth and acknowledged by every reliable subscriber, and the `raw_scan` reader's
//! cache keeps at most its depth (BENCHMARKS.md, "Throughput and memory").

use std::time::Duration;

use crate::ros::logging::RosoutRecord;
use futures::{Stream, StreamExt};
use ros2_client::NodeOptions;
use ros2_client::dds::{Context, Publisher, Server, ServiceMapping, Subscription};
use ros2_client::rosout::RosoutRaw;
use ros2_client::service::RmwRequestId;

use super::Wire;
use super::endpoints::{Endpoints, NO_EVENT_PUBLISHER, introspection_refused, latched, private_name, reliable};
use super::lifecycle::LifecycleEntities;
use crate::interfaces::{
    Calibrate, CalibrateEvent, CalibrateRequest, CalibrateResponse, Contour, DiagnosticArray, GetTypeDescription,
    GetTypeDescriptionRequest, GetTypeDescriptionResponse, PolygonStamped, RawScan, RosMsg, RosService,
    tracer_calib_msgs as msgs,
};
use crate::names::NodeIdentity;
use crate::rmw::dds::TypesInUse;
use crate::rmw::{RosEnv, Security};

/// Calibrate requests waiting for the one-at-a-time fit. The DDS reader drops the
/// oldest unread sample past this depth, and a dropped request is a caller waiting
/// forever: with ROS's service default of 10, eleven calls arriving during one fit
/// would lose one. A request is a few bytes, so the bound is generous.
const CALIBRATE_QUEUE: usize = 1000;

/// The node's DDS entities: what the loops read from and write to.
pub(super) struct Entities {
    pub ctx: Context,
    pub node: ros2_client::dds::Node,
    pub raw_scans: Subscription<RawScan>,
    pub contours: Publisher<Contour>,
    pub polygons: Publisher<PolygonStamped>,
    pub diagnostics: Publisher<DiagnosticArray>,
    pub calibration: Publisher<msgs::Calibration>,
    pub calibrate: Server<CalibrateRequest, CalibrateResponse>,
    /// `None` if the middleware refused it (a secure cell's permissions without the topic).
    pub calibrate_events: Option<Publisher<CalibrateEvent>>,
    pub type_description: Server<GetTypeDescriptionRequest, GetTypeDescriptionResponse>,
    /// The lifecycle services and events of a managed node.
    pub lifecycle: Option<LifecycleEntities>,
    /// The types of the node's endpoints, which `type_description` describes.
    pub types_in_use: TypesInUse,
    /// rcl's logger name of the node (`cell1.tracer`), for its `/rosout` records.
    logger_name: String,
    spinner: smol::Task<ros2_client::CreateResult<()>>,
}

impl Entities {
    /// The DDS participant (`ROS_DOMAIN_ID`, `ROS_AUTOMATIC_DISCOVERY_RANGE` and
    /// `ROS_STATIC_PEERS` as rmw_fastrtps reads them: [`crate::rmw::dds`]; secured with
    /// `security`'s enclave: [`crate::rmw::security`]), the node with its
    /// parameters (`options`), its endpoints (and the lifecycle's if `managed`), and its
    /// spinner running.
    pub fn create(
        env: &RosEnv,
        security: &Security,
        identity: &NodeIdentity,
        options: NodeOptions,
        endpoints: &Endpoints,
        managed: bool,
    ) -> Result<Self, String> {
        let participant = crate::rmw::dds::participant_from_env(env, security)?;
        let (ctx, types_in_use) = crate::rmw::dds::context(participant)?;
        let node_name = identity.ros2_node_name().map_err(|e| e.to_string())?;
        let mut node = ctx.new_node(node_name, options).map_err(|e| format!("cannot create the node: {e:?}"))?;
        let mk = |e: ros2_client::CreateError| format!("cannot create a DDS entity: {e:?}");
        let Endpoints { raw_scan, contour, polygon, diagnostics, calibration, calibrate, calibrate_event } = endpoints;
        let raw_topic = node.create_topic(&raw_scan.0, RawScan::NAME.message_type_name(), &raw_scan.1).map_err(mk)?;
        let contour_topic = node.create_topic(&contour.0, Contour::NAME.message_type_name(), &contour.1).map_err(mk)?;
        let polygon_topic =
            node.create_topic(&polygon.0, PolygonStamped::NAME.message_type_name(), &polygon.1).map_err(mk)?;
        let diag_topic =
            node.create_topic(diagnostics, DiagnosticArray::NAME.message_type_name(), &reliable(10)).map_err(mk)?;
        let calibration_topic =
            node.create_topic(calibration, msgs::Calibration::NAME.message_type_name(), &latched()).map_err(mk)?;
        let raw_scans = node.create_subscription::<RawScan>(&raw_topic, None).map_err(mk)?;
        let contours = node.create_publisher::<Contour>(&contour_topic, None).map_err(mk)?;
        let polygons = node.create_publisher::<PolygonStamped>(&polygon_topic, None).map_err(mk)?;
        let diagnostics = node.create_publisher::<DiagnosticArray>(&diag_topic, None).map_err(mk)?;
        let calibration = node.create_publisher::<msgs::Calibration>(&calibration_topic, None).map_err(mk)?;
        let calibrate = node
            .create_server::<<Calibrate as RosService>::Request, <Calibrate as RosService>::Response>(
                ServiceMapping::Enhanced,
                calibrate,
                &Calibrate::type_name(),
                reliable(CALIBRATE_QUEUE),
                reliable(CALIBRATE_QUEUE),
            )
            .map_err(mk)?;
        // Optional: a secure cell whose permissions were signed before the node had it
        // (no grant for the topic) keeps its node; introspection then publishes nothing.
        let event_type = Calibrate::type_name().event_message_type_name();
        let calibrate_events = node
            .create_topic(calibrate_event, event_type, &reliable(10))
            .and_then(|topic| node.create_publisher::<CalibrateEvent>(&topic, None))
            .map_err(|e| introspection_refused(calibrate_event, mk(e)))
            .ok();
        let type_description_name = private_name(&identity.fully_qualified_name(), "get_type_description")?;
        let type_description = node
            .create_server::<GetTypeDescriptionRequest, GetTypeDescriptionResponse>(
                ServiceMapping::Enhanced,
                &type_description_name,
                &GetTypeDescription::type_name(),
                reliable(10),
                reliable(10),
            )
            .map_err(mk)?;
        let lifecycle =
            if managed { Some(LifecycleEntities::create(&mut node, &identity.fully_qualified_name())?) } else { None };
        let spinner = smol::spawn(node.spinner().map_err(mk)?.spin());
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
            spinner,
        })
    }

    /// Tear down in order: dropping each endpoint makes discovery announce it gone; the
    /// participant's event loop must still be running to send that, so it goes last,
    /// after a moment. Without this, peers keep the node's topics and services in their
    /// graphs for the lease duration.
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
            spinner,
        } = self;
        drop((raw_scans, contours, polygons, diagnostics, calibration, calibrate, calibrate_events));
        drop((type_description, lifecycle));
        drop(node);
        std::thread::sleep(Duration::from_millis(150));
        smol::block_on(spinner.cancel());
        drop(ctx);
    }
}

impl Wire for Entities {
    type RequestId = RmwRequestId;

    fn raw_scans(&self) -> impl Stream<Item = Result<RawScan, String>> + '_ {
        self.raw_scans.async_stream().map(|r| r.map(|(msg, _info)| msg).map_err(|e| format!("{e:?}")))
    }

    async fn publish_contour(&self, msg: Contour) -> Result<(), String> {
        self.contours.async_publish(msg).await.map_err(|e| format!("{e:?}"))
    }

    async fn publish_polygon(&self, msg: PolygonStamped) -> Result<(), String> {
        self.polygons.async_publish(msg).await.map_err(|e| format!("{e:?}"))
    }

    async fn publish_diagnostics(&self, msg: DiagnosticArray) -> Result<(), String> {
        self.diagnostics.async_publish(msg).await.map_err(|e| format!("{e:?}"))
    }

    async fn publish_calibration(&self, msg: msgs::Calibration) -> Result<(), String> {
        self.calibration.async_publish(msg).await.map_err(|e| format!("{e:?}"))
    }

    fn calibrate_requests(&self) -> impl Stream<Item = Result<(RmwRequestId, CalibrateRequest), String>> + '_ {
        self.calibrate.receive_request_stream().map(|r| r.map_err(|e| format!("{e:?}")))
    }

    fn calibrate_unreadable(&self) -> u64 {
        self.calibrate.bad_request_count()
    }

    async fn answer_calibrate(&self, id: RmwRequestId, response: CalibrateResponse) -> Result<(), String> {
        self.calibrate.async_send_response(id, response).await.map_err(|e| format!("{e:?}"))
    }

    async fn publish_calibrate_event(&self, msg: CalibrateEvent) -> Result<(), String> {
        match &self.calibrate_events {
            Some(p) => p.async_publish(msg).await.map_err(|e| format!("{e:?}")),
            None => Err(NO_EVENT_PUBLISHER.to_string()),
        }
    }

    fn type_description_requests(
        &self,
    ) -> impl Stream<Item = Result<(RmwRequestId, GetTypeDescriptionRequest), String>> + '_ {
        self.type_description.receive_request_stream().map(|r| r.map_err(|e| format!("{e:?}")))
    }

    async fn answer_type_description(
        &self,
        id: RmwRequestId,
        response: GetTypeDescriptionResponse,
    ) -> Result<(), String> {
        self.type_description.async_send_response(id, response).await.map_err(|e| format!("{e:?}"))
    }

    fn types_in_use(&self) -> Vec<String> {
        self.types_in_use.names()
    }

    fn set_parameters(&self, params: Vec<ros2_client::Parameter>) -> Result<(), String> {
        self.node.set_parameters_atomically(params)
    }

    fn raw_scan_publishers(&self) -> usize {
        self.raw_scans.get_publisher_count(&self.node)
    }

    fn rosout(&self, r: &RosoutRecord) {
        let node = &self.node;
        node.rosout_raw(node.rosout_stamp(), r.level, &self.logger_name, &r.msg, &r.file, &r.function, r.line);
    }

    fn use_sim_time(&self) -> bool {
        self.node.clock().use_sim_time()
    }
}
