//! The managed node's lifecycle interface, as rcl_lifecycle makes it (`managed: true`):
//!
//! | kind | name | type |
//! |---|---|---|
//! | service | `~/change_state` | `lifecycle_msgs/srv/ChangeState` |
//! | service | `~/get_state` | `lifecycle_msgs/srv/GetState` |
//! | service | `~/get_available_states` | `lifecycle_msgs/srv/GetAvailableStates` |
//! | service | `~/get_available_transitions` | `lifecycle_msgs/srv/GetAvailableTransitions` |
//! | service | `~/get_transition_graph` | `lifecycle_msgs/srv/GetAvailableTransitions` |
//! | publisher | `~/transition_event` | `lifecycle_msgs/msg/TransitionEvent` |
//!
//! QoS as rcl's defaults for services and publishers (reliable, volatile, keep last 10).
//! The state machine and the node's callbacks are the cell's ([`crate::cell::lifecycle`],
//! [`crate::cell::managed`]); this maps them onto `lifecycle_msgs`. Each transition taken is
//! one `transition_event` (rcl publishes the start and goal states; the transition's id and
//! label and the timestamp, on the node's clock in nanoseconds, are filled in too). A
//! transition the current state does not offer is logged at ERROR and answered
//! `success: false`, as rclcpp_lifecycle does.

use futures::{StreamExt, stream};
use log::{debug, error, info, warn};
use ros2_client::dds::{Node, Publisher, Server, ServiceMapping};
use ros2_client::{Name, service::RmwRequestId};

use super::{Shared, entities::reliable, log_history_read};
use crate::cell::lifecycle::{self, STATES, TRANSITIONS, Transition};
use crate::interfaces::{
    ChangeState, ChangeStateRequest, ChangeStateResponse, GetAvailableStates, GetAvailableStatesRequest,
    GetAvailableStatesResponse, GetAvailableTransitions, GetAvailableTransitionsRequest,
    GetAvailableTransitionsResponse, GetState, GetStateRequest, GetStateResponse, LifecycleState, LifecycleTransition,
    RosMsg, RosService, TransitionDescription, TransitionEvent,
};
use crate::ros::names::ros2_name;

type TransitionsServer = Server<GetAvailableTransitionsRequest, GetAvailableTransitionsResponse>;

/// The lifecycle services and the transition event publisher.
pub(super) struct LifecycleEntities {
    change_state: Server<ChangeStateRequest, ChangeStateResponse>,
    get_state: Server<GetStateRequest, GetStateResponse>,
    get_available_states: Server<GetAvailableStatesRequest, GetAvailableStatesResponse>,
    get_available_transitions: TransitionsServer,
    get_transition_graph: TransitionsServer,
    transition_event: Publisher<TransitionEvent>,
}

impl LifecycleEntities {
    /// Made on `node`, whose fully qualified name is `fqn`.
    pub fn create(node: &mut Node, fqn: &str) -> Result<Self, String> {
        let name = |suffix: &str| ros2_name(&format!("{fqn}/{suffix}")).map_err(|e| e.to_string());
        let mk = |e: ros2_client::CreateError| format!("cannot create a lifecycle entity: {e:?}");
        fn server<S: RosService>(
            node: &mut Node,
            name: &Name,
        ) -> Result<Server<S::Request, S::Response>, ros2_client::CreateError> {
            node.create_server::<S::Request, S::Response>(
                ServiceMapping::Enhanced,
                name,
                &S::type_name(),
                reliable(10),
                reliable(10),
            )
        }
        let topic = node
            .create_topic(&name("transition_event")?, TransitionEvent::NAME.message_type_name(), &reliable(10))
            .map_err(mk)?;
        Ok(LifecycleEntities {
            change_state: server::<ChangeState>(node, &name("change_state")?).map_err(mk)?,
            get_state: server::<GetState>(node, &name("get_state")?).map_err(mk)?,
            get_available_states: server::<GetAvailableStates>(node, &name("get_available_states")?).map_err(mk)?,
            get_available_transitions: server::<GetAvailableTransitions>(node, &name("get_available_transitions")?)
                .map_err(mk)?,
            get_transition_graph: server::<GetAvailableTransitions>(node, &name("get_transition_graph")?)
                .map_err(mk)?,
            transition_event: node.create_publisher::<TransitionEvent>(&topic, None).map_err(mk)?,
        })
    }
}

fn state_msg(s: lifecycle::State) -> LifecycleState {
    LifecycleState { id: s.id, label: s.label.to_string() }
}

fn transition_msg(t: &Transition) -> LifecycleTransition {
    LifecycleTransition { id: t.id, label: t.label.to_string() }
}

fn description(t: &Transition) -> TransitionDescription {
    TransitionDescription {
        transition: transition_msg(t),
        start_state: state_msg(t.start),
        goal_state: state_msg(t.goal),
    }
}

/// A request to one of the five services.
enum Call {
    ChangeState(ChangeStateRequest),
    GetState,
    GetAvailableStates,
    GetAvailableTransitions,
    GetTransitionGraph,
}

/// The five request streams merged into one.
type Calls<'a> = std::pin::Pin<Box<dyn futures::Stream<Item = Result<(RmwRequestId, Call), String>> + 'a>>;

/// Each request to the five services answered in turn, transitions one at a time (the
/// cell's state is locked for each). Ends when the request streams do.
pub(super) async fn run(l: &LifecycleEntities, shared: &Shared) {
    fn calls<'a, R: 'a>(
        s: impl futures::Stream<Item = ros2_client::ReadResult<(RmwRequestId, R)>> + 'a,
        call: fn(R) -> Call,
    ) -> Calls<'a> {
        Box::pin(s.map(move |r| r.map(|(id, req)| (id, call(req))).map_err(|e| format!("{e:?}"))))
    }
    let mut requests = stream::select_all([
        calls(l.change_state.receive_request_stream(), Call::ChangeState),
        calls(l.get_state.receive_request_stream(), |_| Call::GetState),
        calls(l.get_available_states.receive_request_stream(), |_| Call::GetAvailableStates),
        calls(l.get_available_transitions.receive_request_stream(), |_| Call::GetAvailableTransitions),
        calls(l.get_transition_graph.receive_request_stream(), |_| Call::GetTransitionGraph),
    ]);
    while let Some(item) = requests.next().await {
        let (id, call) = match item {
            Ok(r) => r,
            Err(err) => {
                warn!("cannot read a lifecycle request: {err}");
                continue;
            }
        };
        let sent = match call {
            Call::ChangeState(req) => {
                let success = change_state(l, shared, &req).await;
                l.change_state.async_send_response(id, ChangeStateResponse { success }).await
            }
            Call::GetState => {
                let current = current_state(shared);
                l.get_state.async_send_response(id, GetStateResponse { current_state: state_msg(current) }).await
            }
            Call::GetAvailableStates => {
                let available_states = STATES.iter().copied().map(state_msg).collect();
                l.get_available_states.async_send_response(id, GetAvailableStatesResponse { available_states }).await
            }
            Call::GetAvailableTransitions => {
                let available_transitions = {
                    let st = shared.state.lock().expect("state lock");
                    st.lifecycle.as_ref().map(|lc| lc.available().map(description).collect()).unwrap_or_default()
                };
                let response = GetAvailableTransitionsResponse { available_transitions };
                l.get_available_transitions.async_send_response(id, response).await
            }
            Call::GetTransitionGraph => {
                let response = GetAvailableTransitionsResponse {
                    available_transitions: TRANSITIONS.iter().map(description).collect(),
                };
                l.get_transition_graph.async_send_response(id, response).await
            }
        };
        if let Err(err) = sent {
            warn!("cannot send a lifecycle response: {err:?}");
        }
    }
}

fn current_state(shared: &Shared) -> lifecycle::State {
    let st = shared.state.lock().expect("state lock");
    st.lifecycle.as_ref().map_or(lifecycle::State::UNKNOWN, |lc| lc.current())
}

/// One requested transition walked through the cell: each step published as a
/// `transition_event`, the calibration in force republished (configure and cleanup change
/// what it rests on). Returns `ChangeState`'s `success`.
async fn change_state(l: &LifecycleEntities, shared: &Shared, req: &ChangeStateRequest) -> bool {
    let request = lifecycle::Request { id: req.transition.id, label: &req.transition.label };
    let now = shared.now();
    let mut history = None;
    let (walked, fqn) = {
        let mut st = shared.state.lock().expect("state lock");
        (st.change_lifecycle(&request, now, &mut history), st.fqn.clone())
    };
    let walk = match walked {
        Ok(walk) => walk,
        Err(e) => {
            error!("{fqn}: {e}");
            return false;
        }
    };
    if let Some(read) = &history {
        log_history_read(read);
    }
    let timestamp = u64::try_from(now.ros.to_nanos()).unwrap_or(0);
    for step in &walk.steps {
        debug!("{fqn}: transition {} [{}]: {} -> {}", step.label, step.id, step.start.label, step.goal.label);
        let event = TransitionEvent {
            timestamp,
            transition: transition_msg(step),
            start_state: state_msg(step.start),
            goal_state: state_msg(step.goal),
        };
        if let Err(err) = l.transition_event.async_publish(event).await {
            warn!("cannot publish a transition event: {err:?}");
        }
    }
    let (first, last) = (walk.steps[0], walk.steps[walk.steps.len() - 1]);
    info!("{fqn}: {} [{}]: {} -> {}", first.label, first.id, first.start.label, last.goal.label);
    let _ = shared.calibration_changed.try_send(());
    walk.success
}
