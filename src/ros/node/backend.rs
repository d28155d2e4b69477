//! What differs between the node's two middlewares: ros2-client's DDS backend
//! ([`super::dds::Dds`]) and its Zenoh backend ([`super::zenoh::Zenoh`], under
//! `RMW_IMPLEMENTATION=rmw_zenoh_cpp`). A [`Backend`] names its node, topic, publisher,
//! subscription and server types and does the few operations the shell needs of them;
//! everything else, which endpoints the node has and how the loops use them, is written
//! once, over any backend: [`super::entities::Entities`] and [`super::lifecycle::Lifecycle`].
//!
//! Errors come out as text, each backend's in the words it has always had in the node's
//! log ([`Backend::text`]).

use std::fmt::{Debug, Display};

use futures::Stream;
use ros2_client::{CreateError, MessageTypeName, Name, QosProfile, RmwRequestId};

use super::RosClock;
use crate::interfaces::RosService;
use crate::rmw::dds::TypesInUse;
use crate::ros::logging::RosoutRecord;

/// What a topic of the node carries: a message ros2-client can write and read (and show:
/// DDS's error of a publish that failed holds the message, in the error's text).
pub(super) trait Msg: serde::Serialize + serde::de::DeserializeOwned + Debug + 'static {}

impl<M: serde::Serialize + serde::de::DeserializeOwned + Debug + 'static> Msg for M {}

/// What a server of the node serves: a ROS service type.
pub(super) trait Service: RosService + 'static {}

impl<S: RosService + 'static> Service for S {}

/// A backend's connection and node, opened (DDS: [`super::dds::Dds::open`]; Zenoh:
/// [`super::zenoh::Zenoh::open`]): what [`super::entities::Entities::create`] makes the node's
/// endpoints on.
pub(super) struct Opened<B: Backend> {
    /// The connection.
    pub ctx: B::Context,
    /// The node, with its parameters.
    pub node: B::Node,
    /// The types of the node's endpoints (recorded as their hashes are asked for).
    pub types_in_use: TypesInUse,
}

/// One of ros2-client's backends, as the node shell uses it. Implemented by zero-sized
/// types; every operation is an associated function on the backend's own entities.
pub(super) trait Backend: Sized + 'static {
    /// The connection to the middleware the node lives in (DDS: the participant's
    /// context; Zenoh: the session's).
    type Context;
    /// The ROS node.
    type Node;
    /// A topic: name, type and QoS, from which a publisher or a subscription is made.
    type Topic;
    /// A publisher of `M`.
    type Publisher<M: Msg>;
    /// A subscription to `M`.
    type Subscription<M: Msg>;
    /// The server of a service of type `S`.
    type Server<S: Service>;
    /// What keeps the node's traffic moving once its endpoints are made (DDS: the node's
    /// spinner task; Zenoh: nothing, the session runs itself).
    type Spinner;

    /// What an entity of this backend is called in the error of making one.
    const ENTITY: &'static str;
    /// What a lifecycle entity of this backend is called in the error of making one.
    const LIFECYCLE_ENTITY: &'static str;

    /// An error of this backend in words, as the node has always logged it (DDS: the
    /// error's `Debug` form, `{e:?}`; Zenoh: its `Display` form, `{e}`).
    fn text<E: Debug + Display>(e: &E) -> String;

    /// The error of making one of the node's entities (`what`: [`Self::ENTITY`] or
    /// [`Self::LIFECYCLE_ENTITY`]).
    fn cannot_create(what: &str, e: CreateError) -> String {
        format!("cannot create {what}: {}", Self::text(&e))
    }

    /// The topic `name` of type `type_name` with `qos`.
    fn topic(
        node: &mut Self::Node,
        name: &Name,
        type_name: MessageTypeName,
        qos: &QosProfile,
    ) -> Result<Self::Topic, CreateError>;
    /// A publisher on `topic`, with the topic's QoS.
    fn publisher<M: Msg>(node: &mut Self::Node, topic: &Self::Topic) -> Result<Self::Publisher<M>, CreateError>;
    /// A subscription to `topic`, with the topic's QoS.
    fn subscription<M: Msg>(node: &mut Self::Node, topic: &Self::Topic) -> Result<Self::Subscription<M>, CreateError>;
    /// The server of the service `name`, its requests and responses with `qos` (where
    /// the backend has a QoS for them: DDS, Fast DDS' "Enhanced" mapping).
    fn server<S: Service>(node: &mut Self::Node, name: &Name, qos: QosProfile) -> Result<Self::Server<S>, CreateError>;
    /// Set the node's traffic moving, once its endpoints are made.
    fn spin(node: &mut Self::Node) -> Result<Self::Spinner, CreateError>;
    /// Leave, the node's endpoints already dropped: the node, then the connection.
    fn close(ctx: Self::Context, node: Self::Node, spinner: Self::Spinner);

    /// Publish `msg`.
    fn publish<M: Msg>(publisher: &Self::Publisher<M>, msg: M) -> impl Future<Output = Result<(), String>> + '_;
    /// The messages, as they arrive; an `Err` is one that did not decode.
    fn messages<M: Msg>(subscription: &Self::Subscription<M>) -> impl Stream<Item = Result<M, String>> + '_;
    /// How many publishers `subscription` (made on `node`) has matched.
    fn publisher_count<M: Msg>(subscription: &Self::Subscription<M>, node: &Self::Node) -> usize;
    /// The server's requests, as they arrive; an `Err` is one that could not be read.
    fn requests<S: Service>(
        server: &Self::Server<S>,
    ) -> impl Stream<Item = Result<(RmwRequestId, S::Request), String>> + '_;
    /// How many requests the server could not read, if it counts them itself (DDS: it
    /// does, and warns of them; Zenoh: `None`, the shell counts them).
    fn unreadable_requests<S: Service>(server: &Self::Server<S>) -> Option<u64>;
    /// Answer the request `id`.
    fn respond<S: Service>(
        server: &Self::Server<S>,
        id: RmwRequestId,
        response: S::Response,
    ) -> impl Future<Output = Result<(), String>> + '_;

    /// Set several of the node's parameters from within, all or none
    /// ([`super::wire::Wire::set_parameters`]).
    fn set_parameters(node: &Self::Node, params: Vec<ros2_client::Parameter>) -> Result<(), String>;
    /// A record on `/rosout`, under the node's rcl logger name `logger_name`.
    fn rosout(node: &Self::Node, logger_name: &str, record: &RosoutRecord);
    /// Whether the node's clock is simulated (`use_sim_time`).
    fn use_sim_time(node: &Self::Node) -> bool;
    /// The node's clock.
    fn clock(node: &Self::Node) -> RosClock;
}

/// The operations whose code is the same on both backends, word for word: ros2-client's DDS
/// and Zenoh types have methods of the same names and meanings but no trait in common, so
/// this one text serves both impls (`same_on_both_backends!();` inside `impl Backend for
/// ...`), each with its own types and its own error text ([`Backend::text`]).
macro_rules! same_on_both_backends {
    () => {
        fn publisher<M: $crate::ros::node::backend::Msg>(
            node: &mut Self::Node,
            topic: &Self::Topic,
        ) -> Result<Self::Publisher<M>, ros2_client::CreateError> {
            node.create_publisher(topic, None)
        }

        fn subscription<M: $crate::ros::node::backend::Msg>(
            node: &mut Self::Node,
            topic: &Self::Topic,
        ) -> Result<Self::Subscription<M>, ros2_client::CreateError> {
            node.create_subscription(topic, None)
        }

        async fn publish<M: $crate::ros::node::backend::Msg>(
            publisher: &Self::Publisher<M>,
            msg: M,
        ) -> Result<(), String> {
            publisher.async_publish(msg).await.map_err(|e| Self::text(&e))
        }

        fn messages<M: $crate::ros::node::backend::Msg>(
            subscription: &Self::Subscription<M>,
        ) -> impl futures::Stream<Item = Result<M, String>> + '_ {
            futures::StreamExt::map(subscription.async_stream(), |r| {
                r.map(|(msg, _info)| msg).map_err(|e| Self::text(&e))
            })
        }

        fn publisher_count<M: $crate::ros::node::backend::Msg>(
            subscription: &Self::Subscription<M>,
            node: &Self::Node,
        ) -> usize {
            subscription.get_publisher_count(node)
        }

        fn use_sim_time(node: &Self::Node) -> bool {
            node.clock().use_sim_time()
        }
    };
}

pub(super) use same_on_both_backends;
