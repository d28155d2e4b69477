//! The node on DDS, the ROS 2 default: ros2-client's DDS backend on rustdds. The
//! participant (`ROS_DOMAIN_ID`, `ROS_AUTOMATIC_DISCOVERY_RANGE` and `ROS_STATIC_PEERS` as
//! rmw_fastrtps reads them: [`crate::rmw::dds`]; secured with an enclave:
//! [`crate::rmw::security`]) and its context are made by [`Dds::open`]; services use Fast
//! DDS' "Enhanced" mapping, and a spinner task runs the node's discovery and events.
//! The graph (matches, incompatible QoS) is watched by [`super::graph`].

use std::fmt::{Debug, Display};
use std::time::Duration;

use futures::{Stream, StreamExt};
use ros2_client::dds::{Context, Node, ServiceMapping};
use ros2_client::rosout::RosoutRaw;
use ros2_client::{CreateError, MessageTypeName, Name, NodeOptions, QosProfile, RmwRequestId};
use rustdds::Topic;

use super::RosClock;
use super::backend::{Backend, Msg, Opened, Service, same_on_both_backends};
use crate::names::NodeIdentity;
use crate::rmw::{RosEnv, Security};
use crate::ros::logging::RosoutRecord;

/// ros2-client's DDS backend.
pub(super) struct Dds;

impl Dds {
    /// The DDS participant from `env`, secured with `security`'s enclave, its context,
    /// and the node `identity` with its parameters (`options`).
    pub fn open(
        env: &RosEnv,
        security: &Security,
        identity: &NodeIdentity,
        options: NodeOptions,
    ) -> Result<Opened<Dds>, String> {
        let participant = crate::rmw::dds::participant_from_env(env, security)?;
        let (ctx, types_in_use) = crate::rmw::dds::context(participant)?;
        let node_name = identity.ros2_node_name().map_err(|e| e.to_string())?;
        let node = ctx.new_node(node_name, options).map_err(|e| format!("cannot create the node: {e:?}"))?;
        Ok(Opened { ctx, node, types_in_use })
    }
}

impl Backend for Dds {
    type Context = ros2_client::dds::Context;
    type Node = ros2_client::dds::Node;
    type Topic = rustdds::Topic;
    type Publisher<M: Msg> = ros2_client::dds::Publisher<M>;
    type Subscription<M: Msg> = ros2_client::dds::Subscription<M>;
    type Server<S: Service> = ros2_client::dds::Server<S::Request, S::Response>;
    type Spinner = smol::Task<ros2_client::CreateResult<()>>;

    const ENTITY: &'static str = "a DDS entity";
    const LIFECYCLE_ENTITY: &'static str = "a lifecycle entity";

    same_on_both_backends!();

    fn text<E: Debug + Display>(e: &E) -> String {
        format!("{e:?}")
    }

    fn topic(node: &mut Node, name: &Name, type_name: MessageTypeName, qos: &QosProfile) -> Result<Topic, CreateError> {
        node.create_topic(name, type_name, qos)
    }

    fn server<S: Service>(node: &mut Node, name: &Name, qos: QosProfile) -> Result<Self::Server<S>, CreateError> {
        node.create_server::<S::Request, S::Response>(ServiceMapping::Enhanced, name, &S::type_name(), qos.clone(), qos)
    }

    fn spin(node: &mut Node) -> Result<Self::Spinner, CreateError> {
        Ok(smol::spawn(node.spinner()?.spin()))
    }

    /// Dropping each endpoint made discovery announce it gone; the participant's event
    /// loop must still be running to send that, so it goes last, after a moment. Without
    /// this, peers keep the node's topics and services in their graphs for the lease
    /// duration.
    fn close(ctx: Context, node: Node, spinner: Self::Spinner) {
        drop(node);
        std::thread::sleep(Duration::from_millis(150));
        smol::block_on(spinner.cancel());
        drop(ctx);
    }

    fn requests<S: Service>(
        server: &Self::Server<S>,
    ) -> impl Stream<Item = Result<(RmwRequestId, S::Request), String>> + '_ {
        server.receive_request_stream().map(|r| r.map_err(|e| Self::text(&e)))
    }

    fn unreadable_requests<S: Service>(server: &Self::Server<S>) -> Option<u64> {
        Some(server.bad_request_count())
    }

    async fn respond<S: Service>(
        server: &Self::Server<S>,
        id: RmwRequestId,
        response: S::Response,
    ) -> Result<(), String> {
        server.async_send_response(id, response).await.map_err(|e| Self::text(&e))
    }

    fn set_parameters(node: &Node, params: Vec<ros2_client::Parameter>) -> Result<(), String> {
        node.set_parameters_atomically(params)
    }

    fn rosout(node: &Node, logger_name: &str, r: &RosoutRecord) {
        node.rosout_raw(node.rosout_stamp(), r.level, logger_name, &r.msg, &r.file, &r.function, r.line);
    }

    fn clock(node: &Node) -> RosClock {
        RosClock::Dds(node.clock())
    }
}
