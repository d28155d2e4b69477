//! A managed node's end of nav2's bond: while the node is active it keeps the bond
//! nav2's lifecycle manager forms with each node it manages, as a nav2 server does
//! (`nav2_util::LifecycleNode::createBond`, on activation; `destroyBond`, on deactivation):
//! `bond/msg/Status` on `bond` (under the node's namespace: `/bond` for a node at the
//! root), the bond's id the node's name, a fresh instance id per activation, a heartbeat
//! every `bond_heartbeat_period` (nav2's: 0.1 s), timeout 4 s. Leaving the active state
//! (deactivate, shutdown, the process stopping) breaks the bond with `active: false`, so
//! the manager knows at once; a node that dies without a word is noticed by the
//! manager's heartbeat timeout. The state machine is the cell's ([`crate::cell::bond`]).

use std::pin::pin;
use std::time::{Duration, Instant};

use futures::{FutureExt, StreamExt};
use log::{debug, info, warn};

use super::Shared;
use super::lifecycle::{LifecycleWire, current_state};
use crate::cell::bond::{Bond, BondEvent, BondState, DEAD_PUBLISH_PERIOD, SisterStatus};
use crate::cell::lifecycle;
use crate::interfaces::{BondStatus, Header};

/// The bond's heartbeat period from the parameters: `None` for no bond (an unmanaged
/// node, or `bond_heartbeat_period` 0).
pub(super) fn period(params: &crate::params::Parameters) -> Option<Duration> {
    (params.managed && params.bond_heartbeat_period > 0.0)
        .then(|| Duration::from_secs_f64(params.bond_heartbeat_period))
}

/// How often the loop looks at the lifecycle state when the bond has nothing due sooner.
const LOOK: Duration = Duration::from_millis(100);

/// Keeps the node's end of the bond `id` while the node is active. Never ends (a node
/// without the bond's endpoints waits for good: the loop that ends first ends the node).
pub(super) async fn run(l: &impl LifecycleWire, shared: &Shared, id: &str, period: Duration) {
    let Some(statuses) = l.bond_statuses() else { return futures::future::pending().await };
    let mut statuses = pin!(statuses.fuse());
    loop {
        let wake = {
            let bond = shared.bond.lock().expect("bond lock");
            bond.as_ref().and_then(Bond::next_poll).map_or(Instant::now() + LOOK, |t| t.min(Instant::now() + LOOK))
        };
        futures::select! {
            status = statuses.next() => match status {
                Some(Ok(status)) => received(shared, &status),
                Some(Err(err)) => debug!("an unreadable bond status: {err}"),
                None => return,
            },
            _ = FutureExt::fuse(smol::Timer::at(wake)) => {}
        }
        if let Some(status) = step(shared, id, period)
            && let Err(err) = l.publish_bond(status).await
        {
            debug!("cannot publish the bond's status: {err}");
        }
    }
}

/// A status from the bond's topic, to the node's end.
fn received(shared: &Shared, status: &BondStatus) {
    let mut bond = shared.bond.lock().expect("bond lock");
    let Some(b) = bond.as_mut() else { return };
    let sister = SisterStatus { id: &status.id, instance_id: &status.instance_id, active: status.active };
    match b.on_status(sister, Instant::now()) {
        Ok(event) => log_event(b, event),
        Err(third) => warn!("{third}"),
    }
}

/// Starts the bond when the node is active and has none, breaks it when the node left the
/// active state, drops it once it is over; the status to publish now, if any.
fn step(shared: &Shared, id: &str, period: Duration) -> Option<BondStatus> {
    let active = current_state(shared) == lifecycle::State::ACTIVE;
    let now = Instant::now();
    let mut guard = shared.bond.lock().expect("bond lock");
    if guard.is_none() && active {
        let b = Bond::start(id, &instance_id(), period, now);
        info!("bond {id}: kept with the lifecycle manager while active (heartbeat every {period:?})");
        *guard = Some(b);
    }
    let b = guard.as_mut()?;
    if !active {
        let event = b.die(now);
        log_event(b, event);
    }
    let poll = b.poll(now);
    log_event(b, poll.event);
    let status = poll.publish.map(|active| status_msg(shared, b, active));
    if !active && b.state() == BondState::Dead && poll.publish.is_none() {
        *guard = None; // over: a new one on the next activation, as nav2's
    }
    status
}

/// Leaving (the node stops): the bond broken as a dying bondcpp breaks it, `active: false`
/// every 50 ms until the sister answers it (with its own `active: false`), here for at most
/// [`LEAVE_WAIT`]. Said more than once whatever the state: the node's endpoints close
/// right after, and one status only queued when they do may never leave.
pub(super) async fn leave(l: &impl LifecycleWire, shared: &Shared) {
    let last = {
        let mut guard = shared.bond.lock().expect("bond lock");
        let Some(b) = guard.as_mut() else { return };
        if b.state() == BondState::Dead {
            return;
        }
        let event = b.die(Instant::now());
        log_event(b, event);
        info!("bond {}: broken, the node is leaving", b.id());
        status_msg(shared, b, false)
    };
    say_broken(l, last, LEAVE_WAIT).await;
}

/// Publishes `last` (the node's `active: false`) now and every [`DEAD_PUBLISH_PERIOD`],
/// the last time at `wait`, or until the sister says `active: false` too. Only the clock
/// publishes: the node's own statuses come back on its subscription (a ROS subscription
/// hears its own node's publisher), and one more status for each one heard said it
/// thousands of times in the wait (seen on Zenoh: 500 to 3900 in 300 ms).
async fn say_broken(l: &impl LifecycleWire, last: BondStatus, wait: Duration) {
    let Some(statuses) = l.bond_statuses() else { return };
    let mut statuses = pin!(statuses.fuse());
    let deadline = Instant::now() + wait;
    let mut next = Instant::now();
    loop {
        if Instant::now() >= next {
            if let Err(err) = l.publish_bond(last.clone()).await {
                debug!("cannot publish the bond's last status: {err}");
            }
            if Instant::now() >= deadline {
                return;
            }
            next = deadline.min(Instant::now() + DEAD_PUBLISH_PERIOD);
        }
        futures::select! {
            status = statuses.next() => if let Some(Ok(s)) = status
                && s.id == last.id && s.instance_id != last.instance_id && !s.active
            {
                return; // the sister knows
            },
            _ = FutureExt::fuse(smol::Timer::at(next)) => {}
        }
    }
}

/// How long a leaving node says it breaks the bond, waiting for the sister's answer.
const LEAVE_WAIT: Duration = Duration::from_millis(300);

fn log_event(b: &Bond, event: Option<BondEvent>) {
    match event {
        Some(BondEvent::Formed) => info!("bond {}: formed with the lifecycle manager", b.id()),
        Some(BondEvent::Broken(why)) => warn!("bond {}: broken: {why}", b.id()),
        None => {}
    }
}

/// The status `b` publishes.
fn status_msg(shared: &Shared, b: &Bond, active: bool) -> BondStatus {
    let (period, timeout) = b.timing();
    BondStatus {
        header: Header { stamp: shared.now().ros, frame_id: String::new() },
        id: b.id().to_string(),
        instance_id: b.instance_id().to_string(),
        active,
        heartbeat_timeout: timeout.as_secs_f32(),
        heartbeat_period: period.as_secs_f32(),
    }
}

/// A random (version 4) UUID, as bondcpp's and bondpy's instance ids.
fn instance_id() -> String {
    uuid::Uuid::new_v4().to_string()
}

#[cfg(test)]
mod tests {
    use std::cell::RefCell;

    use futures::{Stream, stream};

    use super::*;
    use crate::interfaces::TransitionEvent;
    use crate::ros::node::lifecycle::{Call, Reply};

    /// The bond's topic as a ROS subscription sees it: every status the node publishes
    /// (`published`) comes back to it, and the sister's, queued by the test, after them.
    struct Echo {
        published: RefCell<Vec<BondStatus>>,
        sender: smol::channel::Sender<BondStatus>,
        receiver: smol::channel::Receiver<BondStatus>,
    }

    impl Echo {
        fn new() -> Echo {
            let (sender, receiver) = smol::channel::unbounded();
            Echo { published: RefCell::default(), sender, receiver }
        }
    }

    impl LifecycleWire for Echo {
        type RequestId = ();

        fn calls(&self) -> impl Stream<Item = Result<((), Call), String>> + '_ {
            stream::pending()
        }

        async fn answer(&self, _: (), _: Reply) -> Result<(), String> {
            Ok(())
        }

        async fn publish_event(&self, _: TransitionEvent) -> Result<(), String> {
            Ok(())
        }

        fn bond_statuses(&self) -> Option<impl Stream<Item = Result<BondStatus, String>> + '_> {
            Some(self.receiver.clone().map(Ok))
        }

        async fn publish_bond(&self, status: BondStatus) -> Result<(), String> {
            self.published.borrow_mut().push(status.clone());
            self.sender.send(status).await.map_err(|e| e.to_string())
        }
    }

    fn status(instance_id: &str, active: bool) -> BondStatus {
        BondStatus {
            header: Header::default(),
            id: "tracer_calibrator".into(),
            instance_id: instance_id.into(),
            active,
            heartbeat_timeout: 4.0,
            heartbeat_period: 0.1,
        }
    }

    #[test]
    fn leaving_says_broken_on_the_clock_not_once_per_status_heard() {
        let wire = Echo::new();
        let started = Instant::now();
        smol::block_on(say_broken(&wire, status("ours", false), Duration::from_millis(300)));
        let took = started.elapsed();
        // At 0, 50, ..., 300 ms: 7 (one fewer if a timer fires late), not one more for each
        // of its own statuses heard back.
        let published = wire.published.borrow();
        assert!((5..=7).contains(&published.len()), "published {} times in {took:?}", published.len());
        assert!(took >= Duration::from_millis(300), "{took:?}");
        assert!(published.iter().all(|s| !s.active && s.instance_id == "ours"));
    }

    #[test]
    fn leaving_ends_when_the_sister_says_broken_too() {
        let wire = Echo::new();
        // The manager's heartbeat (alive) changes nothing; its `active: false` ends the wait.
        wire.sender.try_send(status("theirs", true)).unwrap();
        wire.sender.try_send(status("theirs", false)).unwrap();
        let started = Instant::now();
        smol::block_on(say_broken(&wire, status("ours", false), Duration::from_secs(5)));
        assert!(started.elapsed() < Duration::from_secs(1), "{:?}", started.elapsed());
        assert_eq!(wire.published.borrow().len(), 1);
    }
}
