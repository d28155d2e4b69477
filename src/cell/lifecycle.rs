//! The managed node's life cycle: rcl_lifecycle's default state machine
//! (<https://design.ros2.org/articles/node_lifecycle.html>), as data, and the walk of one
//! requested transition through it.
//!
//! Four primary states: unconfigured (where a managed node starts), inactive, active,
//! finalized; and six transition states, one per callback: configuring, cleaningup,
//! activating, deactivating, shuttingdown, errorprocessing. A client requests one of the
//! seven *public* transitions of the primary state the node is in (configure, cleanup,
//! activate, deactivate, and shutdown from any of the first three). The node enters that
//! transition's transition state, runs its callback, and leaves by the callback's result:
//! `transition_success`, `transition_failure` (back where it came from; shutdown goes on to
//! finalized) or `transition_error` (errorprocessing, whose own callback leads to
//! unconfigured on success, to finalized otherwise).
//!
//! | from | transition (id) | via | success | failure |
//! |---|---|---|---|---|
//! | unconfigured | configure (1) | configuring | inactive | unconfigured |
//! | inactive | cleanup (2) | cleaningup | unconfigured | inactive |
//! | inactive | activate (3) | activating | active | inactive |
//! | active | deactivate (4) | deactivating | inactive | active |
//! | unconfigured, inactive, active | shutdown (5, 6, 7) | shuttingdown | finalized | finalized |
//!
//! Ids and labels are `lifecycle_msgs`' and rcl_lifecycle's, in its order of registration
//! ([`STATES`], [`TRANSITIONS`]), which is the order `get_available_states` and
//! `get_transition_graph` list them in. No ROS types here: the node's shell maps these onto
//! `lifecycle_msgs`.

/// A state: its `lifecycle_msgs/msg/State` id and rcl_lifecycle's label.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct State {
    pub id: u8,
    pub label: &'static str,
}

impl State {
    pub const UNKNOWN: State = State { id: 0, label: "unknown" };
    pub const UNCONFIGURED: State = State { id: 1, label: "unconfigured" };
    pub const INACTIVE: State = State { id: 2, label: "inactive" };
    pub const ACTIVE: State = State { id: 3, label: "active" };
    pub const FINALIZED: State = State { id: 4, label: "finalized" };
    pub const CONFIGURING: State = State { id: 10, label: "configuring" };
    pub const CLEANINGUP: State = State { id: 11, label: "cleaningup" };
    pub const SHUTTINGDOWN: State = State { id: 12, label: "shuttingdown" };
    pub const ACTIVATING: State = State { id: 13, label: "activating" };
    pub const DEACTIVATING: State = State { id: 14, label: "deactivating" };
    pub const ERRORPROCESSING: State = State { id: 15, label: "errorprocessing" };

    /// A primary state (ids below 10): one a transition can be requested from.
    pub fn is_primary(self) -> bool {
        self.id < 10
    }
}

/// Every state, in rcl_lifecycle's order.
pub const STATES: [State; 11] = [
    State::UNKNOWN,
    State::UNCONFIGURED,
    State::INACTIVE,
    State::ACTIVE,
    State::FINALIZED,
    State::CONFIGURING,
    State::CLEANINGUP,
    State::SHUTTINGDOWN,
    State::ACTIVATING,
    State::DEACTIVATING,
    State::ERRORPROCESSING,
];

/// A transition: its `lifecycle_msgs/msg/Transition` id and label, from `start` to `goal`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Transition {
    pub id: u8,
    pub label: &'static str,
    pub start: State,
    pub goal: State,
}

const fn t(id: u8, label: &'static str, start: State, goal: State) -> Transition {
    Transition { id, label, start, goal }
}

const SUCCESS: &str = "transition_success";
const FAILURE: &str = "transition_failure";
const ERROR: &str = "transition_error";

/// Every transition, in rcl_lifecycle's order: the public ones (ids below 10) from a primary
/// state into a transition state, and the callback results (10..62) out of it.
pub const TRANSITIONS: [Transition; 25] = {
    use State as S;
    [
        t(1, "configure", S::UNCONFIGURED, S::CONFIGURING),
        t(10, SUCCESS, S::CONFIGURING, S::INACTIVE),
        t(11, FAILURE, S::CONFIGURING, S::UNCONFIGURED),
        t(12, ERROR, S::CONFIGURING, S::ERRORPROCESSING),
        t(2, "cleanup", S::INACTIVE, S::CLEANINGUP),
        t(20, SUCCESS, S::CLEANINGUP, S::UNCONFIGURED),
        t(21, FAILURE, S::CLEANINGUP, S::INACTIVE),
        t(22, ERROR, S::CLEANINGUP, S::ERRORPROCESSING),
        t(3, "activate", S::INACTIVE, S::ACTIVATING),
        t(30, SUCCESS, S::ACTIVATING, S::ACTIVE),
        t(31, FAILURE, S::ACTIVATING, S::INACTIVE),
        t(32, ERROR, S::ACTIVATING, S::ERRORPROCESSING),
        t(4, "deactivate", S::ACTIVE, S::DEACTIVATING),
        t(40, SUCCESS, S::DEACTIVATING, S::INACTIVE),
        t(41, FAILURE, S::DEACTIVATING, S::ACTIVE),
        t(42, ERROR, S::DEACTIVATING, S::ERRORPROCESSING),
        t(5, "shutdown", S::UNCONFIGURED, S::SHUTTINGDOWN),
        t(6, "shutdown", S::INACTIVE, S::SHUTTINGDOWN),
        t(7, "shutdown", S::ACTIVE, S::SHUTTINGDOWN),
        t(50, SUCCESS, S::SHUTTINGDOWN, S::FINALIZED),
        t(51, FAILURE, S::SHUTTINGDOWN, S::FINALIZED),
        t(52, ERROR, S::SHUTTINGDOWN, S::ERRORPROCESSING),
        t(60, SUCCESS, S::ERRORPROCESSING, S::UNCONFIGURED),
        t(61, FAILURE, S::ERRORPROCESSING, S::FINALIZED),
        t(62, ERROR, S::ERRORPROCESSING, S::FINALIZED),
    ]
};

/// What a transition's callback returned (rclcpp_lifecycle's `CallbackReturn`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CallbackReturn {
    Success,
    Failure,
    Error,
}

impl CallbackReturn {
    fn label(self) -> &'static str {
        match self {
            CallbackReturn::Success => SUCCESS,
            CallbackReturn::Failure => FAILURE,
            CallbackReturn::Error => ERROR,
        }
    }
}

/// A transition requested as `lifecycle_msgs/srv/ChangeState` carries it: an id and a
/// label. A label, when given, names the transition (rclcpp_lifecycle: `ros2 service call`
/// leaves the id 0 when only the label is written); else the id does.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Request<'a> {
    pub id: u8,
    pub label: &'a str,
}

/// One requested transition walked to its end.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Walk {
    /// Every transition taken, in order: the requested one, then the callbacks' results
    /// (each is one `transition_event`).
    pub steps: Vec<Transition>,
    /// Whether the requested transition's callback succeeded: `ChangeState`'s `success`.
    pub success: bool,
}

/// A transition the current state does not offer, or a private one
/// ([`Lifecycle::find`]): rcl_lifecycle's words.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error(
    "Unable to start transition {requested} from current state {}: Transition is not registered. (available: {})",
    .current.label,
    listed(.available)
)]
pub struct NotRegistered {
    /// The transition asked for: its label, or its id when no label was given.
    pub requested: String,
    /// The state the node is in (unchanged).
    pub current: State,
    /// The public transitions the current state offers.
    pub available: Vec<Transition>,
}

/// `label [id], ...`, or `none`.
fn listed(available: &[Transition]) -> String {
    if available.is_empty() {
        return "none".to_string();
    }
    available.iter().map(|t| format!("{} [{}]", t.label, t.id)).collect::<Vec<_>>().join(", ")
}

/// The life cycle of one node: the state it is in.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Lifecycle {
    current: State,
}

impl Default for Lifecycle {
    fn default() -> Self {
        Lifecycle::new()
    }
}

impl Lifecycle {
    /// A new managed node: unconfigured.
    pub fn new() -> Self {
        Lifecycle { current: State::UNCONFIGURED }
    }

    /// The state the node is in.
    pub fn current(&self) -> State {
        self.current
    }

    /// The transitions that can start from the current state.
    pub fn available(&self) -> impl Iterator<Item = &'static Transition> + use<> {
        let current = self.current;
        TRANSITIONS.iter().filter(move |t| t.start == current)
    }

    /// The public transition `request` names from the current state, or why there is none
    /// (rcl_lifecycle's words).
    pub fn find(&self, request: &Request) -> Result<&'static Transition, NotRegistered> {
        let found = if request.label.is_empty() {
            self.available().find(|t| t.id == request.id)
        } else {
            self.available().find(|t| t.label == request.label)
        };
        match found {
            Some(t) if t.id < 10 => Ok(t),
            _ => Err(NotRegistered {
                requested: if request.label.is_empty() { request.id.to_string() } else { request.label.to_string() },
                current: self.current,
                available: self.available().filter(|t| t.id < 10).copied().collect(),
            }),
        }
    }

    /// Walk `request`: into its transition state, run `callback` for that state (and, on an
    /// error, again for errorprocessing), out by each result. A transition the current state
    /// does not offer changes nothing and is an error; so is one asked while in a
    /// transition state.
    pub fn change(
        &mut self,
        request: &Request,
        mut callback: impl FnMut(State) -> CallbackReturn,
    ) -> Result<Walk, NotRegistered> {
        let first = self.find(request)?;
        let mut steps = vec![*first];
        self.current = first.goal;
        let result = callback(self.current);
        self.leave(result, &mut steps);
        if self.current == State::ERRORPROCESSING {
            let on_error = callback(State::ERRORPROCESSING);
            self.leave(on_error, &mut steps);
        }
        Ok(Walk { steps, success: result == CallbackReturn::Success })
    }

    /// Out of the current transition state by `result`.
    fn leave(&mut self, result: CallbackReturn, steps: &mut Vec<Transition>) {
        let current = self.current;
        let out = TRANSITIONS
            .iter()
            .find(|t| t.start == current && t.label == result.label())
            .expect("every transition state has a success, a failure and an error transition");
        steps.push(*out);
        self.current = out.goal;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn walk(lc: &mut Lifecycle, label: &str) -> Walk {
        lc.change(&Request { id: 0, label }, |_| CallbackReturn::Success).unwrap()
    }

    #[test]
    fn the_standard_walk() {
        let mut lc = Lifecycle::new();
        assert_eq!(lc.current(), State::UNCONFIGURED);
        let ids = |lc: &Lifecycle| lc.available().map(|t| t.id).collect::<Vec<_>>();
        assert_eq!(ids(&lc), [1, 5]);
        let w = walk(&mut lc, "configure");
        assert!(w.success);
        assert_eq!(
            w.steps.iter().map(|t| (t.id, t.goal.label)).collect::<Vec<_>>(),
            [(1, "configuring"), (10, "inactive")]
        );
        assert_eq!(ids(&lc), [2, 3, 6]);
        walk(&mut lc, "activate");
        assert_eq!(lc.current(), State::ACTIVE);
        assert_eq!(ids(&lc), [4, 7]);
        walk(&mut lc, "deactivate");
        walk(&mut lc, "cleanup");
        assert_eq!(lc.current(), State::UNCONFIGURED);
        // By id, as `ros2 lifecycle set NODE 5`.
        let w = lc.change(&Request { id: 5, label: "" }, |_| CallbackReturn::Success).unwrap();
        assert_eq!(w.steps.iter().map(|t| t.id).collect::<Vec<_>>(), [5, 50]);
        assert_eq!(lc.current(), State::FINALIZED);
        assert_eq!(ids(&lc), Vec::<u8>::new());
        let e = lc.find(&Request { id: 1, label: "" }).unwrap_err();
        assert!(e.available.is_empty() && e.to_string().ends_with("(available: none)"), "{e}");
    }

    #[test]
    fn a_transition_not_offered_changes_nothing() {
        let mut lc = Lifecycle::new();
        let e = lc.change(&Request { id: 3, label: "" }, |_| unreachable!()).unwrap_err();
        assert_eq!((e.requested.as_str(), e.current), ("3", State::UNCONFIGURED));
        assert_eq!(e.available.iter().map(|t| t.id).collect::<Vec<_>>(), [1, 5]);
        assert_eq!(
            e.to_string(),
            "Unable to start transition 3 from current state unconfigured: Transition is not registered. (available: configure [1], shutdown [5])"
        );
        // The label wins over the id (rclcpp_lifecycle), and private transitions are refused.
        assert!(lc.change(&Request { id: 1, label: "activate" }, |_| unreachable!()).is_err());
        assert!(lc.change(&Request { id: 10, label: "" }, |_| unreachable!()).is_err());
        assert!(lc.change(&Request { id: 0, label: "transition_success" }, |_| unreachable!()).is_err());
        assert_eq!(lc.current(), State::UNCONFIGURED);
        // shutdown is one label with an id per state.
        walk(&mut lc, "configure");
        let e = lc.change(&Request { id: 5, label: "" }, |_| unreachable!()).unwrap_err();
        assert!(e.to_string().contains("shutdown [6]"), "{e}");
    }

    #[test]
    fn failures_and_errors_go_where_the_standard_says() {
        let mut lc = Lifecycle::new();
        let w = lc.change(&Request { id: 1, label: "" }, |_| CallbackReturn::Failure).unwrap();
        assert!(!w.success);
        assert_eq!(lc.current(), State::UNCONFIGURED);
        // An error: errorprocessing, whose success leads back to unconfigured.
        let mut seen = Vec::new();
        let w = lc
            .change(&Request { id: 1, label: "" }, |s| {
                seen.push(s.label);
                if s == State::CONFIGURING { CallbackReturn::Error } else { CallbackReturn::Success }
            })
            .unwrap();
        assert_eq!(seen, ["configuring", "errorprocessing"]);
        assert_eq!(w.steps.iter().map(|t| t.id).collect::<Vec<_>>(), [1, 12, 60]);
        assert_eq!(lc.current(), State::UNCONFIGURED);
        // A failed shutdown still ends finalized.
        lc.change(&Request { id: 5, label: "" }, |_| CallbackReturn::Failure).unwrap();
        assert_eq!(lc.current(), State::FINALIZED);
    }

    #[test]
    fn every_transition_joins_known_states() {
        for t in TRANSITIONS {
            assert!(STATES.contains(&t.start) && STATES.contains(&t.goal), "{t:?}");
            assert_eq!(t.id < 10, t.start.is_primary(), "{t:?}");
        }
        // Each transition state has one way out per callback result.
        for s in STATES.iter().filter(|s| !s.is_primary()) {
            let outs: Vec<&str> = TRANSITIONS.iter().filter(|t| t.start == *s).map(|t| t.label).collect();
            assert_eq!(outs, [SUCCESS, FAILURE, ERROR], "{s:?}");
        }
    }
}
