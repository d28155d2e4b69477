//! The node's endpoints on Zenoh (`RMW_IMPLEMENTATION=rmw_zenoh_cpp`): the same names and
//! QoS as on DDS ([`super::endpoints::Endpoints`]), through ros2-client's Zenoh backend,
//! which speaks rmw_zenoh_cpp's protocol:
//!
//! - a liveliness token under `@ros2_lv/<domain>/...` for the node and each endpoint
//!   (what `ros2 node list`, `ros2 topic list -t` and `ros2 service list` read on Zenoh),
//!   with the endpoint's kind, name, type, RIHS01 type hash and QoS;
//! - each topic on the key `<domain>/<name>/<type>/<hash>`, every sample with the
//!   attachment (sequence number, source timestamp, publisher GID);
//! - each service a queryable on its key; the reply echoes the request's sequence number
//!   and client GID;
//! - `calibration` (transient local, depth 1) from a publisher with a cache of one sample
//!   and publisher detection, so a late rmw_zenoh subscriber gets the calibration in force
//!   (`vendor/ros2-client/PATCHES.md`);
//! - the parameter services and `/parameter_events`, rosout, `/clock` (`use_sim_time`);
//! - a managed node's lifecycle services and `~/transition_event` ([`ZenohLifecycle`]).
//!
//! The session, its router and the environment: [`crate::rmw::zenoh`].

use std::sync::Mutex;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::{Duration, Instant};

use crate::ros::logging::RosoutRecord;
use futures::{Stream, StreamExt};
use ros2_client::zenoh::{Context, Node, Publisher, Server, Subscription};
use ros2_client::{MessageTypeName, NodeOptions, RmwRequestId, ServiceTypeName};

use super::endpoints::{Endpoints, NO_EVENT_PUBLISHER, introspection_refused, latched, private_name, reliable};
use super::lifecycle::{Call, LifecycleWire, Reply, calls};
use super::{RateLimit, Shared, Wire};
use crate::interfaces::{
    Calibrate, CalibrateEvent, CalibrateRequest, CalibrateResponse, Contour, DiagnosticArray, GetTypeDescription,
    GetTypeDescriptionRequest, GetTypeDescriptionResponse, PolygonStamped, RawScan, RosMsg, RosService,
    tracer_calib_msgs as msgs,
};
use crate::interfaces::{
    ChangeState, ChangeStateRequest, ChangeStateResponse, GetAvailableStates, GetAvailableStatesRequest,
    GetAvailableStatesResponse, GetAvailableTransitions, GetAvailableTransitionsRequest,
    GetAvailableTransitionsResponse, GetState, GetStateRequest, GetStateResponse, TransitionEvent,
};
use crate::names::NodeIdentity;
use crate::rmw::RosEnv;
use crate::rmw::dds::TypesInUse;
use crate::rmw::zenoh::ZenohEnv;

/// The node's Zenoh entities.
pub(super) struct ZenohEntities {
    ctx: Context,
    node: Node,
    raw_scans: Subscription<RawScan>,
    contours: Publisher<Contour>,
    polygons: Publisher<PolygonStamped>,
    diagnostics: Publisher<DiagnosticArray>,
    calibration: Publisher<msgs::Calibration>,
    calibrate: Server<CalibrateRequest, CalibrateResponse>,
    /// `None` if it could not be made (as on DDS).
    calibrate_events: Option<Publisher<CalibrateEvent>>,
    type_description: Server<GetTypeDescriptionRequest, GetTypeDescriptionResponse>,
    /// The lifecycle services and events of a managed node.
    pub lifecycle: Option<ZenohLifecycle>,
    types_in_use: TypesInUse,
    /// `calibrate` requests that could not be read (a payload that is no request, no
    /// attachment), and the limit on warning of them (one a second).
    calibrate_unreadable: AtomicU64,
    unreadable_log: Mutex<RateLimit>,
}

fn type_name<M: RosMsg>() -> MessageTypeName {
    M::NAME.message_type_name()
}

fn service_type<S: RosService>() -> ServiceTypeName {
    S::type_name()
}

impl ZenohEntities {
    /// The session (and its router: [`crate::rmw::zenoh::context`]), the node with its
    /// parameters (`options`) and its endpoints.
    pub fn create(
        env: &RosEnv,
        zenoh: &ZenohEnv,
        identity: &NodeIdentity,
        options: NodeOptions,
        endpoints: &Endpoints,
        managed: bool,
    ) -> Result<Self, String> {
        let types_in_use = TypesInUse::default();
        let ctx = crate::rmw::zenoh::context(zenoh, env.domain_id, types_in_use.hashing_resolver())?;
        let node_name = identity.ros2_node_name().map_err(|e| e.to_string())?;
        let node = ctx.new_node(node_name, options).map_err(|e| format!("cannot create the node on Zenoh: {e}"))?;
        let mk = |e: ros2_client::CreateError| format!("cannot create a Zenoh entity: {e}");
        let Endpoints { raw_scan, contour, polygon, diagnostics, calibration, calibrate, calibrate_event } = endpoints;
        let raw_topic = node.create_topic(&raw_scan.0, type_name::<RawScan>(), &raw_scan.1);
        let contour_topic = node.create_topic(&contour.0, type_name::<Contour>(), &contour.1);
        let polygon_topic = node.create_topic(&polygon.0, type_name::<PolygonStamped>(), &polygon.1);
        let diag_topic = node.create_topic(diagnostics, type_name::<DiagnosticArray>(), &reliable(10));
        let calibration_topic = node.create_topic(calibration, type_name::<msgs::Calibration>(), &latched());
        let raw_scans = node.create_subscription::<RawScan>(&raw_topic, None).map_err(mk)?;
        let contours = node.create_publisher::<Contour>(&contour_topic, None).map_err(mk)?;
        let polygons = node.create_publisher::<PolygonStamped>(&polygon_topic, None).map_err(mk)?;
        let diagnostics = node.create_publisher::<DiagnosticArray>(&diag_topic, None).map_err(mk)?;
        let calibration = node.create_publisher::<msgs::Calibration>(&calibration_topic, None).map_err(mk)?;
        let calibrate = node.create_server(calibrate, &service_type::<Calibrate>()).map_err(mk)?;
        let event_type = service_type::<Calibrate>().event_message_type_name();
        let event_topic = node.create_topic(calibrate_event, event_type, &reliable(10));
        let calibrate_events = node
            .create_publisher::<CalibrateEvent>(&event_topic, None)
            .map_err(|e| introspection_refused(calibrate_event, mk(e)))
            .ok();
        let type_description_name = private_name(&identity.fully_qualified_name(), "get_type_description")?;
        let type_description =
            node.create_server(&type_description_name, &service_type::<GetTypeDescription>()).map_err(mk)?;
        let lifecycle =
            if managed { Some(ZenohLifecycle::create(&node, &identity.fully_qualified_name())?) } else { None };
        Ok(ZenohEntities {
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
            calibrate_unreadable: AtomicU64::new(0),
            unreadable_log: Mutex::new(RateLimit::new(Duration::from_secs(1))),
        })
    }

    /// The node's clock (`use_sim_time`, `/clock`).
    pub fn clock(&self) -> ros2_client::zenoh::NodeClock {
        self.node.clock()
    }

    /// Keeps [`Shared::polygon_wanted`] from the graph (a subscription on the polygons'
    /// topic, anywhere on the router), and serves the parameter services. Never ends.
    pub async fn run_graph_and_parameters(&self, shared: &Shared) {
        let events = self.node.graph_event_stream();
        let wanted = || self.polygons.get_subscription_count(&self.node) > 0;
        shared.polygon_wanted.store(wanted(), Ordering::Relaxed);
        let graph = async {
            while events.recv().await.is_ok() {
                shared.polygon_wanted.store(wanted(), Ordering::Relaxed);
            }
            futures::future::pending::<()>().await
        };
        let parameters = async {
            match self.node.parameter_server() {
                Some(server) => server.serve().await,
                None => futures::future::pending().await,
            }
        };
        futures::future::join(graph, parameters).await;
    }

    /// Leave: every entity's liveliness token undeclared (peers see the node gone at
    /// once), then the session closed.
    pub fn close(self) {
        let ZenohEntities {
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
            calibrate_unreadable: _,
            unreadable_log: _,
        } = self;
        drop((raw_scans, contours, polygons, diagnostics, calibration, calibrate, calibrate_events));
        drop((type_description, lifecycle));
        drop(node);
        // Zenoh waits up to 10 s for its links to close; on a lossy link (TCP retransmitting
        // to the router) that held the node's exit past a supervisor's SIGTERM grace (the
        // harness' 5 s). The tokens are gone already; the close gets CLOSE_WAIT, then the
        // process leaves and the kernel closes the sockets.
        let (done, closed) = std::sync::mpsc::channel();
        std::thread::spawn(move || {
            let _ = done.send(zenoh::Wait::wait(ctx.session().close()));
        });
        match closed.recv_timeout(CLOSE_WAIT) {
            Ok(Ok(())) => {}
            Ok(Err(e)) => log::debug!("closing the Zenoh session: {e}"),
            Err(_) => log::warn!("the Zenoh session did not close within {CLOSE_WAIT:?}: leaving without it"),
        }
    }
}

/// How long the node waits for its Zenoh session to close when it leaves.
const CLOSE_WAIT: std::time::Duration = std::time::Duration::from_secs(2);

/// A server's requests as a stream (ros2-client's Zenoh server has an async receive).
fn requests<'a, Req: serde::de::DeserializeOwned + 'a, Resp: serde::Serialize + 'a>(
    server: &'a Server<Req, Resp>,
) -> impl Stream<Item = Result<(RmwRequestId, Req), String>> + 'a {
    futures::stream::unfold(server, |s| async move {
        let item = s.async_receive_request().await.map_err(|e| e.to_string());
        Some((item, s))
    })
}

impl Wire for ZenohEntities {
    type RequestId = RmwRequestId;

    fn raw_scans(&self) -> impl Stream<Item = Result<RawScan, String>> + '_ {
        self.raw_scans.async_stream().map(|r| r.map(|(msg, _info)| msg).map_err(|e| e.to_string()))
    }

    async fn publish_contour(&self, msg: Contour) -> Result<(), String> {
        self.contours.async_publish(msg).await.map_err(|e| e.to_string())
    }

    async fn publish_polygon(&self, msg: PolygonStamped) -> Result<(), String> {
        self.polygons.async_publish(msg).await.map_err(|e| e.to_string())
    }

    async fn publish_diagnostics(&self, msg: DiagnosticArray) -> Result<(), String> {
        self.diagnostics.async_publish(msg).await.map_err(|e| e.to_string())
    }

    async fn publish_calibration(&self, msg: msgs::Calibration) -> Result<(), String> {
        self.calibration.async_publish(msg).await.map_err(|e| e.to_string())
    }

    fn calibrate_requests(&self) -> impl Stream<Item = Result<(RmwRequestId, CalibrateRequest), String>> + '_ {
        // An unreadable request is counted (and warned of, once a second at most) here, as
        // the DDS server counts its own; it gets no reply.
        requests(&self.calibrate).inspect(|r| {
            if let Err(err) = r {
                let n = self.calibrate_unreadable.fetch_add(1, Ordering::Relaxed) + 1;
                if let Some(held) = self.unreadable_log.lock().expect("rate limit lock").allow(Instant::now()) {
                    log::warn!("an unreadable calibrate request, not answered: {err} ({n} so far, {held} not shown)");
                }
            }
        })
    }

    fn calibrate_unreadable(&self) -> u64 {
        self.calibrate_unreadable.load(Ordering::Relaxed)
    }

    async fn answer_calibrate(&self, id: RmwRequestId, response: CalibrateResponse) -> Result<(), String> {
        self.calibrate.send_response(id, response).map_err(|e| e.to_string())
    }

    async fn publish_calibrate_event(&self, msg: CalibrateEvent) -> Result<(), String> {
        match &self.calibrate_events {
            Some(p) => p.async_publish(msg).await.map_err(|e| e.to_string()),
            None => Err(NO_EVENT_PUBLISHER.to_string()),
        }
    }

    fn type_description_requests(
        &self,
    ) -> impl Stream<Item = Result<(RmwRequestId, GetTypeDescriptionRequest), String>> + '_ {
        requests(&self.type_description)
    }

    async fn answer_type_description(
        &self,
        id: RmwRequestId,
        response: GetTypeDescriptionResponse,
    ) -> Result<(), String> {
        self.type_description.send_response(id, response).map_err(|e| e.to_string())
    }

    fn types_in_use(&self) -> Vec<String> {
        self.types_in_use.names()
    }

    fn set_parameters(&self, params: Vec<ros2_client::Parameter>) -> Result<(), String> {
        match self.node.parameter_server() {
            Some(server) => server.set_parameters_atomically(params),
            None => Err("the node has no parameter server".to_string()),
        }
    }

    fn raw_scan_publishers(&self) -> usize {
        self.raw_scans.get_publisher_count(&self.node)
    }

    fn rosout(&self, r: &RosoutRecord) {
        // The logger's name is rcl's logger name of the node (vendor/ros2-client/PATCHES.md).
        if let Some(logger) = self.node.logger() {
            logger.log_at(r.level, &r.msg, &r.file, &r.function, r.line);
        }
    }

    fn use_sim_time(&self) -> bool {
        self.node.clock().use_sim_time()
    }
}

type TransitionsServer = Server<GetAvailableTransitionsRequest, GetAvailableTransitionsResponse>;

/// A managed node's lifecycle services and transition event publisher on Zenoh (names,
/// types and QoS as on DDS: [`super::lifecycle`]).
pub(super) struct ZenohLifecycle {
    change_state: Server<ChangeStateRequest, ChangeStateResponse>,
    get_state: Server<GetStateRequest, GetStateResponse>,
    get_available_states: Server<GetAvailableStatesRequest, GetAvailableStatesResponse>,
    get_available_transitions: TransitionsServer,
    get_transition_graph: TransitionsServer,
    transition_event: Publisher<TransitionEvent>,
}

impl ZenohLifecycle {
    /// Made on `node`, whose fully qualified name is `fqn`.
    fn create(node: &Node, fqn: &str) -> Result<Self, String> {
        let name = |suffix: &str| private_name(fqn, suffix);
        let mk = |e: ros2_client::CreateError| format!("cannot create a lifecycle entity on Zenoh: {e}");
        let topic = node.create_topic(&name("transition_event")?, type_name::<TransitionEvent>(), &reliable(10));
        Ok(ZenohLifecycle {
            change_state: node.create_server(&name("change_state")?, &service_type::<ChangeState>()).map_err(mk)?,
            get_state: node.create_server(&name("get_state")?, &service_type::<GetState>()).map_err(mk)?,
            get_available_states: node
                .create_server(&name("get_available_states")?, &service_type::<GetAvailableStates>())
                .map_err(mk)?,
            get_available_transitions: node
                .create_server(&name("get_available_transitions")?, &service_type::<GetAvailableTransitions>())
                .map_err(mk)?,
            get_transition_graph: node
                .create_server(&name("get_transition_graph")?, &service_type::<GetAvailableTransitions>())
                .map_err(mk)?,
            transition_event: node.create_publisher::<TransitionEvent>(&topic, None).map_err(mk)?,
        })
    }
}

impl LifecycleWire for ZenohLifecycle {
    type RequestId = RmwRequestId;

    fn calls(&self) -> impl Stream<Item = Result<(RmwRequestId, Call), String>> + '_ {
        futures::stream::select_all([
            calls(requests(&self.change_state), Call::ChangeState),
            calls(requests(&self.get_state), |_| Call::GetState),
            calls(requests(&self.get_available_states), |_| Call::GetAvailableStates),
            calls(requests(&self.get_available_transitions), |_| Call::GetAvailableTransitions),
            calls(requests(&self.get_transition_graph), |_| Call::GetTransitionGraph),
        ])
    }

    async fn answer(&self, id: RmwRequestId, reply: Reply) -> Result<(), String> {
        match reply {
            Reply::ChangeState(r) => self.change_state.send_response(id, r),
            Reply::GetState(r) => self.get_state.send_response(id, r),
            Reply::GetAvailableStates(r) => self.get_available_states.send_response(id, r),
            Reply::GetAvailableTransitions(r) => self.get_available_transitions.send_response(id, r),
            Reply::GetTransitionGraph(r) => self.get_transition_graph.send_response(id, r),
        }
        .map_err(|e| e.to_string())
    }

    async fn publish_event(&self, event: TransitionEvent) -> Result<(), String> {
        self.transition_event.async_publish(event).await.map_err(|e| e.to_string())
    }
}
