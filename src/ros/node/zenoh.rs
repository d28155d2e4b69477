//! The node on Zenoh (`RMW_IMPLEMENTATION=rmw_zenoh_cpp`): the same endpoints, names and
//! QoS as on DDS ([`super::entities`]), through ros2-client's Zenoh backend ([`Zenoh`]),
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
//! - a managed node's lifecycle services and `~/transition_event` ([`super::lifecycle`]).
//!
//! The graph (polygons only when someone listens) and the parameter services are served by
//! [`run_graph_and_parameters`]. The session, its router and the environment:
//! [`crate::rmw::zenoh`].

use std::fmt::{Debug, Display};
use std::sync::atomic::Ordering;

use futures::Stream;
use ros2_client::zenoh::{Context, Node, Topic};
use ros2_client::{CreateError, MessageTypeName, Name, NodeOptions, QosProfile, RmwRequestId};

use super::backend::{Backend, Msg, Opened, Service, same_on_both_backends};
use super::entities::Entities;
use super::{RosClock, Shared};
use crate::names::NodeIdentity;
use crate::rmw::RosEnv;
use crate::rmw::dds::TypesInUse;
use crate::rmw::zenoh::ZenohEnv;
use crate::ros::logging::RosoutRecord;

/// ros2-client's Zenoh backend.
pub(super) struct Zenoh;

impl Zenoh {
    /// The session (and its router: [`crate::rmw::zenoh::context`]) and the node
    /// `identity` with its parameters (`options`).
    pub fn open(
        env: &RosEnv,
        zenoh: &ZenohEnv,
        identity: &NodeIdentity,
        options: NodeOptions,
    ) -> Result<Opened<Zenoh>, String> {
        let types_in_use = TypesInUse::default();
        let ctx = crate::rmw::zenoh::context(zenoh, env.domain_id, types_in_use.hashing_resolver())?;
        let node_name = identity.ros2_node_name().map_err(|e| e.to_string())?;
        let node = ctx.new_node(node_name, options).map_err(|e| format!("cannot create the node on Zenoh: {e}"))?;
        Ok(Opened { ctx, node, types_in_use })
    }
}

/// How long the node waits for its Zenoh session to close when it leaves.
const CLOSE_WAIT: std::time::Duration = std::time::Duration::from_secs(2);

impl Backend for Zenoh {
    type Context = ros2_client::zenoh::Context;
    type Node = ros2_client::zenoh::Node;
    type Topic = ros2_client::zenoh::Topic;
    type Publisher<M: Msg> = ros2_client::zenoh::Publisher<M>;
    type Subscription<M: Msg> = ros2_client::zenoh::Subscription<M>;
    type Server<S: Service> = ros2_client::zenoh::Server<S::Request, S::Response>;
    type Spinner = ();

    const ENTITY: &'static str = "a Zenoh entity";
    const LIFECYCLE_ENTITY: &'static str = "a lifecycle entity on Zenoh";

    same_on_both_backends!();

    fn text<E: Debug + Display>(e: &E) -> String {
        e.to_string()
    }

    fn topic(node: &mut Node, name: &Name, type_name: MessageTypeName, qos: &QosProfile) -> Result<Topic, CreateError> {
        Ok(node.create_topic(name, type_name, qos))
    }

    /// A queryable; its QoS is rmw_zenoh's for services, whatever `_qos` says.
    fn server<S: Service>(node: &mut Node, name: &Name, _qos: QosProfile) -> Result<Self::Server<S>, CreateError> {
        node.create_server(name, &S::type_name())
    }

    fn spin(_node: &mut Node) -> Result<(), CreateError> {
        Ok(())
    }

    /// Every entity's liveliness token is undeclared by now (peers see the node gone at
    /// once): the node goes, then the session is closed.
    fn close(ctx: Context, node: Node, (): ()) {
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

    /// ros2-client's Zenoh server has an async receive: its requests as a stream.
    fn requests<S: Service>(
        server: &Self::Server<S>,
    ) -> impl Stream<Item = Result<(RmwRequestId, S::Request), String>> + '_ {
        futures::stream::unfold(server, |s| async move {
            let item = s.async_receive_request().await.map_err(|e| Self::text(&e));
            Some((item, s))
        })
    }

    fn unreadable_requests<S: Service>(_server: &Self::Server<S>) -> Option<u64> {
        None
    }

    async fn respond<S: Service>(
        server: &Self::Server<S>,
        id: RmwRequestId,
        response: S::Response,
    ) -> Result<(), String> {
        server.send_response(id, response).map_err(|e| Self::text(&e))
    }

    fn set_parameters(node: &Node, params: Vec<ros2_client::Parameter>) -> Result<(), String> {
        match node.parameter_server() {
            Some(server) => server.set_parameters_atomically(params),
            None => Err("the node has no parameter server".to_string()),
        }
    }

    /// The logger's name is rcl's logger name of the node already
    /// (vendor/ros2-client/PATCHES.md).
    fn rosout(node: &Node, _logger_name: &str, r: &RosoutRecord) {
        if let Some(logger) = node.logger() {
            logger.log_at(r.level, &r.msg, &r.file, &r.function, r.line);
        }
    }

    fn clock(node: &Node) -> RosClock {
        RosClock::Zenoh(node.clock())
    }
}

/// Keeps [`Shared::polygon_wanted`] from the graph (a subscription on the polygons'
/// topic, anywhere on the router), and serves the parameter services. Never ends.
pub(super) async fn run_graph_and_parameters(e: &Entities<Zenoh>, shared: &Shared) {
    let events = e.node.graph_event_stream();
    let wanted = || e.polygons.get_subscription_count(&e.node) > 0;
    shared.polygon_wanted.store(wanted(), Ordering::Relaxed);
    let graph = async {
        while events.recv().await.is_ok() {
            shared.polygon_wanted.store(wanted(), Ordering::Relaxed);
        }
        futures::future::pending::<()>().await
    };
    let parameters = async {
        match e.node.parameter_server() {
            Some(server) => server.serve().await,
            None => futures::future::pending().await,
        }
    };
    futures::future::join(graph, parameters).await;
}
