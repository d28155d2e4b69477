//! nav2's bond: the heartbeat a lifecycle manager (nav2_lifecycle_manager) forms with each
//! node it manages, as bond_core's bondcpp and bondpy keep it (`bond/BondSM.sm`, the
//! state machine both run). No ROS types here: the node's shell publishes what
//! [`Bond::poll`] asks for as `bond/msg/Status` and feeds each status it receives to
//! [`Bond::on_status`].
//!
//! Two instances form one bond: same topic (`bond`), same id (nav2: the managed node's
//! name), each its own `instance_id` (a UUID). Each publishes `active: true` every
//! heartbeat period while waiting for its sister or alive; the first status of the
//! sister forms the bond; a sister silent for the heartbeat timeout, or saying
//! `active: false`, breaks it. Breaking from this side (`Die`) publishes `active: false`
//! (every [`DEAD_PUBLISH_PERIOD`] until the sister answers dead, or the disconnect
//! timeout).
//!
//! | state | sister alive | sister dead | heartbeat timeout | connect / disconnect timeout | die |
//! |---|---|---|---|---|---|
//! | waiting for sister | alive (formed) | dead (broken) | | dead (broken) | dead |
//! | alive | alive (heartbeat timer reset) | dead (broken) | dead (broken) | | awaiting sister's death |
//! | awaiting sister's death | | dead | | dead | |
//! | dead | | | | | |
//!
//! As bondcpp, the heartbeat timer starts with the first heartbeat after the bond formed,
//! and a dead sister's notice is answered at once with one `active: false` status.
//! bond_msgs' defaults: connect timeout 10 s, heartbeat timeout 4 s, disconnect timeout
//! 2 s, heartbeat period 1 s (nav2's managed nodes: 0.1 s, their `bond_heartbeat_period`).

use std::time::{Duration, Instant};

/// How often a dying instance says so (`bond/msg/Constants` `DEAD_PUBLISH_PERIOD`).
pub const DEAD_PUBLISH_PERIOD: Duration = Duration::from_millis(50);
/// `DEFAULT_CONNECT_TIMEOUT`: how long an instance waits for its sister.
pub const CONNECT_TIMEOUT: Duration = Duration::from_secs(10);
/// `DEFAULT_HEARTBEAT_TIMEOUT`: a sister silent this long is dead (nav2's too).
pub const HEARTBEAT_TIMEOUT: Duration = Duration::from_secs(4);
/// `DEFAULT_DISCONNECT_TIMEOUT`: how long a dying instance waits for its sister's answer.
pub const DISCONNECT_TIMEOUT: Duration = Duration::from_secs(2);

/// BondSM's states.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum BondState {
    /// Started, no status of the sister yet.
    WaitingForSister,
    /// Formed: the sister's heartbeats arrive.
    Alive,
    /// Broken from this side; waiting for the sister to say it knows.
    AwaitSisterDeath,
    /// Broken.
    Dead,
}

/// What happened to the bond, for the node to log.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum BondEvent {
    /// The sister's first status arrived.
    Formed,
    /// Broken, and why.
    Broken(&'static str),
}

/// What [`Bond::poll`] asks for now.
#[derive(Debug, Default, Clone, PartialEq)]
pub struct BondPoll {
    /// Publish a status with this `active` now.
    pub publish: Option<bool>,
    /// What changed.
    pub event: Option<BondEvent>,
}

/// A status received on the bond's topic, the fields the state machine reads.
#[derive(Debug, Clone, Copy)]
pub struct SisterStatus<'a> {
    /// The bond's id.
    pub id: &'a str,
    /// The sender's instance.
    pub instance_id: &'a str,
    /// Alive, or dying.
    pub active: bool,
}

/// A status of a third instance of the bond ([`Bond::on_status`]): one bond has two ends,
/// this node's and its sister's; the status is ignored.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("a third instance ({instance_id}) of bond {bond} (sister {sister}): only two may share a bond")]
pub struct ThirdInstance {
    /// The third instance's id.
    pub instance_id: String,
    /// The bond's id.
    pub bond: String,
    /// The sister's instance id (the bond's other end).
    pub sister: String,
}

/// One end of a bond (bondcpp's `bond::Bond`, started).
#[derive(Debug, Clone)]
pub struct Bond {
    id: String,
    instance_id: String,
    heartbeat_period: Duration,
    heartbeat_timeout: Duration,
    state: BondState,
    sister: Option<String>,
    connect_deadline: Option<Instant>,
    heartbeat_deadline: Option<Instant>,
    disconnect_deadline: Option<Instant>,
    next_publish: Instant,
    /// A status to publish at the next poll whatever the period (an answer, a death).
    publish_now: Option<bool>,
}

impl Bond {
    /// Started at `now`: waiting for the sister, publishing at once and every
    /// `heartbeat_period`.
    pub fn start(id: &str, instance_id: &str, heartbeat_period: Duration, now: Instant) -> Bond {
        Bond {
            id: id.to_string(),
            instance_id: instance_id.to_string(),
            heartbeat_period,
            heartbeat_timeout: HEARTBEAT_TIMEOUT,
            state: BondState::WaitingForSister,
            sister: None,
            connect_deadline: Some(now + CONNECT_TIMEOUT),
            heartbeat_deadline: None,
            disconnect_deadline: None,
            next_publish: now,
            publish_now: None,
        }
    }

    /// The bond's id.
    pub fn id(&self) -> &str {
        &self.id
    }

    /// This end's instance id.
    pub fn instance_id(&self) -> &str {
        &self.instance_id
    }

    /// The heartbeat period and timeout this end announces in its statuses.
    pub fn timing(&self) -> (Duration, Duration) {
        (self.heartbeat_period, self.heartbeat_timeout)
    }

    /// Where the state machine is.
    pub fn state(&self) -> BondState {
        self.state
    }

    /// A status received at `now`. Another bond's, our own, or a third instance's (one
    /// bond has two ends) is ignored; `Err` says which third instance.
    pub fn on_status(&mut self, status: SisterStatus<'_>, now: Instant) -> Result<Option<BondEvent>, ThirdInstance> {
        if status.id != self.id || status.instance_id == self.instance_id {
            return Ok(None);
        }
        match &self.sister {
            None => self.sister = Some(status.instance_id.to_string()),
            Some(sister) if sister != status.instance_id => {
                return Err(ThirdInstance {
                    instance_id: status.instance_id.to_string(),
                    bond: self.id.clone(),
                    sister: sister.clone(),
                });
            }
            Some(_) => {}
        }
        Ok(if status.active { self.sister_alive(now) } else { self.sister_dead() })
    }

    fn sister_alive(&mut self, now: Instant) -> Option<BondEvent> {
        match self.state {
            BondState::WaitingForSister => {
                self.state = BondState::Alive;
                self.connect_deadline = None;
                Some(BondEvent::Formed)
            }
            BondState::Alive => {
                self.heartbeat_deadline = Some(now + self.heartbeat_timeout);
                None
            }
            BondState::AwaitSisterDeath | BondState::Dead => None,
        }
    }

    fn sister_dead(&mut self) -> Option<BondEvent> {
        match self.state {
            // The sister died first: answered at once with one dead status.
            BondState::WaitingForSister | BondState::Alive => {
                self.publish_now = Some(false);
                self.death();
                Some(BondEvent::Broken("the sister broke the bond"))
            }
            BondState::AwaitSisterDeath => {
                self.death();
                None
            }
            BondState::Dead => None,
        }
    }

    /// Break the bond from this side (the node leaves the active state, or shuts down):
    /// `active: false` at once, then every [`DEAD_PUBLISH_PERIOD`] until the sister
    /// answers or the disconnect timeout.
    pub fn die(&mut self, now: Instant) -> Option<BondEvent> {
        match self.state {
            BondState::WaitingForSister => {
                self.publish_now = Some(false);
                self.death();
                Some(BondEvent::Broken("broken before it formed"))
            }
            BondState::Alive => {
                self.publish_now = Some(false);
                self.state = BondState::AwaitSisterDeath;
                self.heartbeat_deadline = None;
                self.disconnect_deadline = Some(now + DISCONNECT_TIMEOUT);
                self.next_publish = now + DEAD_PUBLISH_PERIOD;
                None
            }
            BondState::AwaitSisterDeath | BondState::Dead => None,
        }
    }

    fn death(&mut self) {
        self.state = BondState::Dead;
        self.connect_deadline = None;
        self.heartbeat_deadline = None;
        self.disconnect_deadline = None;
    }

    /// At `now`: the timeouts due, and the status to publish if one is due.
    pub fn poll(&mut self, now: Instant) -> BondPoll {
        let mut event = None;
        let passed = |deadline: Option<Instant>| deadline.is_some_and(|d| now >= d);
        if passed(self.connect_deadline) {
            self.death();
            event = Some(BondEvent::Broken("the sister never came (connect timeout)"));
        } else if passed(self.heartbeat_deadline) {
            self.death();
            event = Some(BondEvent::Broken("the sister went silent (heartbeat timeout)"));
        } else if passed(self.disconnect_deadline) {
            self.death();
            event = Some(BondEvent::Broken("the sister did not answer our death (disconnect timeout)"));
        }
        let mut publish = self.publish_now.take();
        let period = match self.state {
            BondState::WaitingForSister | BondState::Alive => Some((true, self.heartbeat_period)),
            BondState::AwaitSisterDeath => Some((false, DEAD_PUBLISH_PERIOD)),
            BondState::Dead => None,
        };
        if let Some((active, period)) = period
            && now >= self.next_publish
        {
            publish = publish.or(Some(active));
            self.next_publish = now + period;
        }
        BondPoll { publish, event }
    }

    /// When [`Bond::poll`] has something to do next (`None`: nothing ever, it is dead and
    /// has said so).
    pub fn next_poll(&self) -> Option<Instant> {
        if self.publish_now.is_some() {
            return Some(Instant::now());
        }
        let publishing = (self.state != BondState::Dead).then_some(self.next_publish);
        [publishing, self.connect_deadline, self.heartbeat_deadline, self.disconnect_deadline]
            .into_iter()
            .flatten()
            .min()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const PERIOD: Duration = Duration::from_millis(100);

    fn alive(instance_id: &str) -> SisterStatus<'_> {
        SisterStatus { id: "tracer", instance_id, active: true }
    }

    fn dead(instance_id: &str) -> SisterStatus<'_> {
        SisterStatus { id: "tracer", instance_id, active: false }
    }

    fn ms(t0: Instant, ms: u64) -> Instant {
        t0 + Duration::from_millis(ms)
    }

    #[test]
    fn heartbeats_go_out_every_period_from_the_start() {
        let t0 = Instant::now();
        let mut b = Bond::start("tracer", "me", PERIOD, t0);
        assert_eq!(b.poll(t0).publish, Some(true));
        assert_eq!(b.poll(ms(t0, 50)).publish, None);
        assert_eq!(b.next_poll(), Some(ms(t0, 100)));
        assert_eq!(b.poll(ms(t0, 100)).publish, Some(true));
    }

    #[test]
    fn the_sisters_first_status_forms_the_bond_and_others_are_ignored() {
        let t0 = Instant::now();
        let mut b = Bond::start("tracer", "me", PERIOD, t0);
        // Another bond's status, and our own echo: nothing.
        assert_eq!(b.on_status(SisterStatus { id: "other", instance_id: "x", active: true }, t0), Ok(None));
        assert_eq!(b.on_status(alive("me"), t0), Ok(None));
        assert_eq!(b.state(), BondState::WaitingForSister);
        assert_eq!(b.on_status(alive("manager"), t0), Ok(Some(BondEvent::Formed)));
        assert_eq!(b.state(), BondState::Alive);
        let e = b.on_status(alive("intruder"), t0).unwrap_err();
        assert_eq!(e, ThirdInstance { instance_id: "intruder".into(), bond: b.id().into(), sister: "manager".into() });
        assert_eq!(
            e.to_string(),
            format!("a third instance (intruder) of bond {} (sister manager): only two may share a bond", b.id())
        );
        assert_eq!(b.state(), BondState::Alive);
    }

    #[test]
    fn a_silent_sister_breaks_the_bond_after_the_heartbeat_timeout() {
        let t0 = Instant::now();
        let mut b = Bond::start("tracer", "me", PERIOD, t0);
        b.on_status(alive("manager"), t0).unwrap();
        b.on_status(alive("manager"), ms(t0, 100)).unwrap();
        assert_eq!(b.poll(ms(t0, 4099)).event, None);
        let p = b.poll(ms(t0, 4100));
        assert!(matches!(p.event, Some(BondEvent::Broken(_))), "{p:?}");
        assert_eq!(b.state(), BondState::Dead);
        assert_eq!(p.publish, None, "a dead end publishes nothing");
        assert_eq!(b.next_poll(), None);
    }

    #[test]
    fn a_dying_sister_is_answered_at_once_with_one_dead_status() {
        let t0 = Instant::now();
        let mut b = Bond::start("tracer", "me", PERIOD, t0);
        b.on_status(alive("manager"), t0).unwrap();
        assert!(matches!(b.on_status(dead("manager"), ms(t0, 10)), Ok(Some(BondEvent::Broken(_)))));
        assert_eq!(b.poll(ms(t0, 10)).publish, Some(false));
        assert_eq!(b.poll(ms(t0, 500)).publish, None);
    }

    #[test]
    fn dying_says_so_until_the_sister_answers() {
        let t0 = Instant::now();
        let mut b = Bond::start("tracer", "me", PERIOD, t0);
        b.on_status(alive("manager"), t0).unwrap();
        assert_eq!(b.die(ms(t0, 20)), None);
        assert_eq!(b.state(), BondState::AwaitSisterDeath);
        assert_eq!(b.poll(ms(t0, 20)).publish, Some(false));
        assert_eq!(b.poll(ms(t0, 70)).publish, Some(false));
        // The sister's answer ends it, without an event of its own (broken already).
        assert_eq!(b.on_status(dead("manager"), ms(t0, 80)), Ok(None));
        assert_eq!(b.state(), BondState::Dead);
        assert_eq!(b.poll(ms(t0, 200)).publish, None);
    }

    #[test]
    fn a_sister_that_never_answers_our_death_times_out() {
        let t0 = Instant::now();
        let mut b = Bond::start("tracer", "me", PERIOD, t0);
        b.on_status(alive("manager"), t0).unwrap();
        b.die(t0);
        let p = b.poll(ms(t0, 2000));
        assert!(matches!(p.event, Some(BondEvent::Broken(_))));
        assert_eq!(b.state(), BondState::Dead);
        // Dying again changes nothing, says nothing.
        assert_eq!(b.die(ms(t0, 2100)), None);
        assert_eq!(b.poll(ms(t0, 2100)).publish, None);
        assert_eq!(b.next_poll(), None);
    }

    #[test]
    fn no_sister_within_the_connect_timeout_breaks_it() {
        let t0 = Instant::now();
        let mut b = Bond::start("tracer", "me", PERIOD, t0);
        assert_eq!(b.poll(ms(t0, 9_999)).event, None);
        assert!(matches!(b.poll(ms(t0, 10_000)).event, Some(BondEvent::Broken(_))));
        // Dying before the sister came: one dead status, broken.
        let mut b = Bond::start("tracer", "me", PERIOD, t0);
        assert!(matches!(b.die(t0), Some(BondEvent::Broken(_))));
        assert_eq!(b.poll(t0).publish, Some(false));
        assert_eq!(b.next_poll(), None);
    }
}
