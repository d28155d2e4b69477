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
//! [`crate::cell::managed`]); this maps them onto `lifecycle_msgs`, through a
//! [`LifecycleWire`]: [`Lifecycle`], on either middleware ([`super::backend`]). Each
//! transition taken is one `transition_event` (rcl publishes the start and goal states; the
//! transition's id and label and the timestamp, on the node's clock in nanoseconds, are
//! filled in too). A transition the current state does not offer is logged at ERROR and
//! answered `success: false`, as rclcpp_lifecycle does.

use futures::{Stream, StreamExt, stream};
use log::{debug, error, info, warn};
use ros2_client::{Name, RmwRequestId};

use super::backend::Backend;
use super::endpoints::{private_name, reliable};
use super::{Shared, log_history_read};
use crate::cell::lifecycle::{self, STATES, TRANSITIONS, Transition};
use crate::interfaces::{
    BondStatus, ChangeState, ChangeStateRequest, ChangeStateResponse, GetAvailableStates, GetAvailableStatesResponse,
    GetAvailableTransitions, GetAvailableTransitionsResponse, GetState, GetStateResponse, LifecycleState,
    LifecycleTransition, RosMsg, TransitionDescription, TransitionEvent,
};

/// The lifecycle services and the transition event publisher, on the backend `B`.
pub(super) struct Lifecycle<B: Backend> {
    change_state: B::Server<ChangeState>,
    get_state: B::Server<GetState>,
    get_available_states: B::Server<GetAvailableStates>,
    get_available_transitions: B::Server<GetAvailableTransitions>,
    get_transition_graph: B::Server<GetAvailableTransitions>,
    transition_event: B::Publisher<TransitionEvent>,
    /// nav2's bond (`bond/msg/Status` on `bond`), if the node keeps one: its publisher and
    /// subscription ([`super::bond`]).
    bond: Option<(B::Publisher<BondStatus>, B::Subscription<BondStatus>)>,
}

impl<B: Backend> Lifecycle<B> {
    /// Made on `node`, whose fully qualified name is `fqn`; with the bond's endpoints on
    /// the topic `bond` if given (QoS as bondcpp's: reliable, volatile, keep last 5 for the
    /// publisher, 100 for the subscription).
    pub fn create(node: &mut B::Node, fqn: &str, bond: &Option<Name>) -> Result<Self, String> {
        let name = |suffix: &str| private_name(fqn, suffix);
        let mk = |e: ros2_client::CreateError| B::cannot_create(B::LIFECYCLE_ENTITY, e);
        let topic =
            B::topic(node, &name("transition_event")?, TransitionEvent::NAME.message_type_name(), &reliable(10))
                .map_err(mk)?;
        let bond = match bond {
            Some(bond) => {
                // A secure cell whose permissions predate the bond refuses it: say which
                // topic, and the two ways out.
                let mk = |e: ros2_client::CreateError| {
                    format!(
                        "{}; nav2's bond on {bond} (bond_heartbeat_period > 0) needs a publish and \
                         subscribe grant for it in the enclave's permissions \
                         (config/sros2_cell_policy.xml), or bond_heartbeat_period:=0 for no bond",
                        B::cannot_create(B::LIFECYCLE_ENTITY, e)
                    )
                };
                let type_name = BondStatus::NAME.message_type_name();
                let out = B::topic(node, bond, type_name.clone(), &reliable(5)).map_err(mk)?;
                let into = B::topic(node, bond, type_name, &reliable(100)).map_err(mk)?;
                Some((
                    B::publisher::<BondStatus>(node, &out).map_err(mk)?,
                    B::subscription::<BondStatus>(node, &into).map_err(mk)?,
                ))
            }
            None => None,
        };
        Ok(Lifecycle {
            change_state: B::server::<ChangeState>(node, &name("change_state")?, reliable(10)).map_err(mk)?,
            get_state: B::server::<GetState>(node, &name("get_state")?, reliable(10)).map_err(mk)?,
            get_available_states: B::server::<GetAvailableStates>(node, &name("get_available_states")?, reliable(10))
                .map_err(mk)?,
            get_available_transitions: B::server::<GetAvailableTransitions>(
                node,
                &name("get_available_transitions")?,
                reliable(10),
            )
            .map_err(mk)?,
            get_transition_graph: B::server::<GetAvailableTransitions>(
                node,
                &name("get_transition_graph")?,
                reliable(10),
            )
            .map_err(mk)?,
            transition_event: B::publisher::<TransitionEvent>(node, &topic).map_err(mk)?,
            bond,
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
pub(super) enum Call {
    ChangeState(ChangeStateRequest),
    GetState,
    GetAvailableStates,
    GetAvailableTransitions,
    GetTransitionGraph,
}

/// The answer to a [`Call`].
pub(super) enum Reply {
    ChangeState(ChangeStateResponse),
    GetState(GetStateResponse),
    GetAvailableStates(GetAvailableStatesResponse),
    GetAvailableTransitions(GetAvailableTransitionsResponse),
    GetTransitionGraph(GetAvailableTransitionsResponse),
}

/// A middleware's lifecycle services and transition event publisher: the seam the
/// lifecycle loop is written against (as [`super::Wire`] for the others).
pub(super) trait LifecycleWire {
    /// A service request's identity, to answer it with.
    type RequestId: std::fmt::Debug + Copy;
    /// The requests to the five services, merged.
    fn calls(&self) -> impl Stream<Item = Result<(Self::RequestId, Call), String>> + '_;
    /// Answer a request (`reply` is the answer to its kind of call).
    fn answer(&self, id: Self::RequestId, reply: Reply) -> impl Future<Output = Result<(), String>> + '_;
    /// Publish a transition event.
    fn publish_event(&self, event: TransitionEvent) -> impl Future<Output = Result<(), String>> + '_;
    /// The statuses on the bond's topic, if the node keeps nav2's bond (`None`: it does not).
    fn bond_statuses(&self) -> Option<impl Stream<Item = Result<BondStatus, String>> + '_>;
    /// Publish a status of the node's end of the bond (nothing if it keeps none).
    fn publish_bond(&self, status: BondStatus) -> impl Future<Output = Result<(), String>> + '_;
}

/// The five request streams merged into one.
type Calls<'a, Id> = std::pin::Pin<Box<dyn futures::Stream<Item = Result<(Id, Call), String>> + 'a>>;

/// `s`, a service's request stream, as [`Call`]s made by `call`.
fn calls<'a, Id: 'a, R: 'a>(
    s: impl futures::Stream<Item = Result<(Id, R), String>> + 'a,
    call: fn(R) -> Call,
) -> Calls<'a, Id> {
    Box::pin(s.map(move |r| r.map(|(id, req)| (id, call(req)))))
}

impl<B: Backend> LifecycleWire for Lifecycle<B> {
    type RequestId = RmwRequestId;

    fn calls(&self) -> impl Stream<Item = Result<(RmwRequestId, Call), String>> + '_ {
        stream::select_all([
            calls(B::requests(&self.change_state), Call::ChangeState),
            calls(B::requests(&self.get_state), |_| Call::GetState),
            calls(B::requests(&self.get_available_states), |_| Call::GetAvailableStates),
            calls(B::requests(&self.get_available_transitions), |_| Call::GetAvailableTransitions),
            calls(B::requests(&self.get_transition_graph), |_| Call::GetTransitionGraph),
        ])
    }

    async fn answer(&self, id: RmwRequestId, reply: Reply) -> Result<(), String> {
        match reply {
            Reply::ChangeState(r) => B::respond(&self.change_state, id, r).await,
            Reply::GetState(r) => B::respond(&self.get_state, id, r).await,
            Reply::GetAvailableStates(r) => B::respond(&self.get_available_states, id, r).await,
            Reply::GetAvailableTransitions(r) => B::respond(&self.get_available_transitions, id, r).await,
            Reply::GetTransitionGraph(r) => B::respond(&self.get_transition_graph, id, r).await,
        }
    }

    fn publish_event(&self, event: TransitionEvent) -> impl Future<Output = Result<(), String>> + '_ {
        B::publish(&self.transition_event, event)
    }

    fn bond_statuses(&self) -> Option<impl Stream<Item = Result<BondStatus, String>> + '_> {
        self.bond.as_ref().map(|(_, subscription)| B::messages(subscription))
    }

    async fn publish_bond(&self, status: BondStatus) -> Result<(), String> {
        match &self.bond {
            Some((publisher, _)) => B::publish(publisher, status).await,
            None => Ok(()),
        }
    }
}

/// Each request to the five services answered in turn, transitions one at a time (the
/// cell's state is locked for each). Ends when the request streams do.
pub(super) async fn run(l: &impl LifecycleWire, shared: &Shared) {
    let mut requests = std::pin::pin!(l.calls());
    while let Some(item) = requests.next().await {
        let (id, call) = match item {
            Ok(r) => r,
            Err(err) => {
                warn!("cannot read a lifecycle request: {err}");
                continue;
            }
        };
        let reply = match call {
            Call::ChangeState(req) => {
                let success = change_state(l, shared, &req).await;
                Reply::ChangeState(ChangeStateResponse { success })
            }
            Call::GetState => {
                let current = current_state(shared);
                Reply::GetState(GetStateResponse { current_state: state_msg(current) })
            }
            Call::GetAvailableStates => {
                let available_states = STATES.iter().copied().map(state_msg).collect();
                Reply::GetAvailableStates(GetAvailableStatesResponse { available_states })
            }
            Call::GetAvailableTransitions => {
                let available_transitions = {
                    let st = shared.state.lock().expect("state lock");
                    st.lifecycle.as_ref().map(|lc| lc.available().map(description).collect()).unwrap_or_default()
                };
                Reply::GetAvailableTransitions(GetAvailableTransitionsResponse { available_transitions })
            }
            Call::GetTransitionGraph => Reply::GetTransitionGraph(GetAvailableTransitionsResponse {
                available_transitions: TRANSITIONS.iter().map(description).collect(),
            }),
        };
        if let Err(err) = l.answer(id, reply).await {
            warn!("cannot send a lifecycle response: {err}");
        }
    }
}

/// The managed node's lifecycle state (`unknown` if it is not managed).
pub(super) fn current_state(shared: &Shared) -> lifecycle::State {
    let st = shared.state.lock().expect("state lock");
    st.lifecycle.as_ref().map_or(lifecycle::State::UNKNOWN, |lc| lc.current())
}

/// One requested transition walked through the cell: each step published as a
/// `transition_event`, the calibration in force republished (configure and cleanup change
/// what it rests on). Returns `ChangeState`'s `success`.
async fn change_state(l: &impl LifecycleWire, shared: &Shared, req: &ChangeStateRequest) -> bool {
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
        if let Err(err) = l.publish_event(event).await {
            warn!("cannot publish a transition event: {err}");
        }
    }
    let (first, last) = (walk.steps[0], walk.steps[walk.steps.len() - 1]);
    info!("{fqn}: {} [{}]: {} -> {}", first.label, first.id, first.start.label, last.goal.label);
    let _ = shared.calibration_changed.try_send(());
    walk.success
}
