//! `tracer_calib replay`: a bag's scans published into a live ROS graph, like
//! `ros2 bag play`.

use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use ros2_client::dds::{Node, Publisher};
use ros2_client::{NodeName, NodeOptions, QosProfile, qos::*};

use super::exit;
use crate::interfaces::standard::Clock;
use crate::interfaces::{Contour, RawScan, RosMsg, Time};
use crate::io::bag::Bag;
use crate::rmw::RosEnv;

/// Publish a bag's RawScan (and Contour) messages with their recorded timing.
///
/// Publishing starts once every topic has a subscriber (or after --wait), and the tool
/// stays until the last messages have had time to be delivered (--linger). DDS settings
/// come from the environment as for any ROS node: ROS_DOMAIN_ID, and
/// ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST to stay on 127.0.0.1.
///
/// With --clock, /clock (rosgraph_msgs/msg/Clock) carries the bag's time as it plays, as
/// `ros2 bag play --clock` publishes it: the first message's time while waiting for
/// subscribers, then advancing with --rate (back to the start on each --loop), at HZ
/// publications a second (default 40); nodes on `use_sim_time:=true` follow it.
///
/// Example:
///   tracer_calib replay --input scans.mcap --rate 2 --loop 3
///   tracer_calib replay --input plate.mcap --clock
#[derive(Debug, clap::Args)]
#[command(verbatim_doc_comment)]
pub struct Args {
    /// The bag: a directory with metadata.yaml, a .mcap or a .db3 file.
    #[arg(long, value_name = "BAG")]
    pub input: PathBuf,
    /// Only these topics (repeatable; default: every RawScan and Contour topic).
    #[arg(long = "topic", value_name = "TOPIC")]
    pub topics: Vec<String>,
    /// Playback speed factor (2 = twice as fast; 0 = as fast as possible).
    #[arg(long, default_value_t = 1.0)]
    pub rate: f64,
    /// Play the bag this many times.
    #[arg(long = "loop", default_value_t = 1)]
    pub loops: u32,
    /// Seconds to wait for subscribers before publishing anyway.
    #[arg(long, default_value_t = 10.0)]
    pub wait: f64,
    /// Seconds to stay after the last message, for reliable delivery to finish.
    #[arg(long, default_value_t = 1.0)]
    pub linger: f64,
    /// Also publish /clock from the bag's time, HZ times a second (default 40).
    #[arg(long, value_name = "HZ", num_args = 0..=1, default_missing_value = "40")]
    pub clock: Option<f64>,
}

/// The bag's time as the replay plays it: `bag_ns` at `at`, advancing `rate` times as fast
/// as the system clock while `running`.
#[derive(Debug, Clone, Copy)]
struct PlayClock {
    bag_ns: u64,
    at: Instant,
    rate: f64,
    running: bool,
}

impl PlayClock {
    fn now_ns(&self) -> u64 {
        if self.running {
            self.bag_ns + (self.at.elapsed().as_secs_f64() * self.rate * 1e9) as u64
        } else {
            self.bag_ns
        }
    }

    /// Stand (or run from) `bag_ns`, from now.
    fn set(&mut self, bag_ns: u64, running: bool) {
        *self = PlayClock { bag_ns, at: Instant::now(), running, ..*self };
    }
}

pub fn run(args: &Args) -> i32 {
    match replay(args) {
        Ok(summary) => {
            println!("{summary}");
            exit::OK
        }
        Err(e) => {
            eprintln!("tracer_calib replay: {e}");
            exit::BAD_INPUT
        }
    }
}

/// One message of the bag, for the topic at an index of [`Timeline::topics`].
enum Out {
    Raw(RawScan),
    Contour(Contour),
}

/// The message type of a topic replayed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Kind {
    Raw,
    Contour,
}

/// What the bag gives to replay: its RawScan and Contour topics (those asked for), and
/// their messages in log-time order.
struct Timeline {
    topics: Vec<(String, Kind)>,
    /// (log time, topic index, message)
    messages: Vec<(u64, usize, Out)>,
}

impl Timeline {
    /// The bag's RawScan and Contour topics (only `--topic`'s, if given: each must be one).
    fn read(args: &Args) -> Result<Timeline, String> {
        let bag = Bag::open(&args.input).map_err(|e| e.to_string())?;
        let wanted = |name: &str| args.topics.is_empty() || args.topics.iter().any(|t| t == name);
        let mut topics = Vec::new();
        let mut messages = Vec::new();
        for t in bag.topics() {
            if !wanted(&t.name) {
                continue;
            }
            let idx = topics.len();
            if t.type_name == RawScan::NAME.ros_name() {
                for (time, m) in bag.read::<RawScan>(&t.name).map_err(|e| e.to_string())? {
                    messages.push((time, idx, Out::Raw(m)));
                }
                topics.push((t.name.clone(), Kind::Raw));
            } else if t.type_name == Contour::NAME.ros_name() {
                for (time, m) in bag.read::<Contour>(&t.name).map_err(|e| e.to_string())? {
                    messages.push((time, idx, Out::Contour(m)));
                }
                topics.push((t.name.clone(), Kind::Contour));
            }
        }
        if let Some(t) = args.topics.iter().find(|t| !topics.iter().any(|(n, _)| n == *t)) {
            return Err(format!("{}: no RawScan or Contour topic {t}", args.input.display()));
        }
        if messages.is_empty() {
            return Err(format!("{}: no RawScan or Contour messages to replay", args.input.display()));
        }
        messages.sort_by_key(|(t, _, _)| *t);
        Ok(Timeline { topics, messages })
    }

    fn first_ns(&self) -> u64 {
        self.messages[0].0
    }

    fn last_ns(&self) -> u64 {
        self.messages.last().expect("a message").0
    }
}

/// The publisher of one topic, of its type.
enum TopicPublisher {
    Raw(Publisher<RawScan>),
    Contour(Publisher<Contour>),
}

impl TopicPublisher {
    fn subscription_count(&self, node: &Node) -> usize {
        match self {
            TopicPublisher::Raw(p) => p.get_subscription_count(node),
            TopicPublisher::Contour(p) => p.get_subscription_count(node),
        }
    }

    fn publish(&self, msg: &Out) -> Result<(), String> {
        match (self, msg) {
            (TopicPublisher::Raw(p), Out::Raw(m)) => p.publish(m.clone()).map_err(|e| format!("{e:?}")),
            (TopicPublisher::Contour(p), Out::Contour(m)) => p.publish(m.clone()).map_err(|e| format!("{e:?}")),
            _ => unreachable!("a topic's messages are of its type"),
        }
    }
}

fn create_error(e: ros2_client::CreateError) -> String {
    format!("cannot create a DDS entity: {e:?}")
}

/// A publisher for each topic, of the type its messages are (reliable, volatile, keep last 100).
fn publishers(node: &mut Node, timeline: &Timeline) -> Result<Vec<TopicPublisher>, String> {
    let qos = QosProfile::publisher_default()
        .reliability_reliable(WhenFull::DEFAULT)
        .durability(Durability::Volatile)
        .history(History::KeepLast { depth: 100 });
    let mut publishers = Vec::new();
    for (name, kind) in &timeline.topics {
        let n = ros2_client::Name::parse(name).map_err(|e| format!("invalid topic or service name '{name}': {e}"))?;
        publishers.push(match kind {
            Kind::Raw => {
                let topic = node.create_topic(&n, RawScan::NAME.message_type_name(), &qos).map_err(create_error)?;
                TopicPublisher::Raw(node.create_publisher::<RawScan>(&topic, None).map_err(create_error)?)
            }
            Kind::Contour => {
                let topic = node.create_topic(&n, Contour::NAME.message_type_name(), &qos).map_err(create_error)?;
                TopicPublisher::Contour(node.create_publisher::<Contour>(&topic, None).map_err(create_error)?)
            }
        });
    }
    Ok(publishers)
}

/// `/clock` from `play_clock`, `hz` times a second, on a thread of its own until `done`;
/// as rosbag2's player publishes it: rclcpp's ClockQoS (best effort, keep last 1).
fn start_clock(
    node: &mut Node,
    hz: f64,
    play_clock: Arc<Mutex<PlayClock>>,
    done: Arc<AtomicBool>,
) -> Result<std::thread::JoinHandle<()>, String> {
    let name = ros2_client::Name::new("/", "clock").expect("a valid name");
    let topic = node
        .create_topic(&name, Clock::NAME.message_type_name(), &QosProfile::subscription_default())
        .map_err(create_error)?;
    let publisher = node.create_publisher::<Clock>(&topic, None).map_err(create_error)?;
    Ok(std::thread::spawn(move || {
        while !done.load(Ordering::Relaxed) {
            let ns = play_clock.lock().expect("clock lock").now_ns();
            let msg = Clock { clock: Time::from_nanos(i64::try_from(ns).unwrap_or(i64::MAX)) };
            if let Err(e) = publisher.publish(msg) {
                eprintln!("tracer_calib replay: cannot publish /clock: {e:?}");
            }
            std::thread::sleep(Duration::from_secs_f64(1.0 / hz));
        }
    }))
}

/// Wait until every topic has a subscriber, `wait` seconds at most; warn if not.
fn wait_for_subscribers(node: &Node, publishers: &[TopicPublisher], wait: f64) {
    let deadline = Instant::now() + Duration::from_secs_f64(wait.max(0.0));
    loop {
        if publishers.iter().all(|p| p.subscription_count(node) > 0) {
            return;
        }
        if Instant::now() >= deadline {
            eprintln!(
                "tracer_calib replay: warning: not every topic has a subscriber after {wait} s; publishing anyway"
            );
            return;
        }
        std::thread::sleep(Duration::from_millis(20));
    }
}

/// Publish the timeline `args.loops` times at `args.rate` (0: as fast as possible), the
/// play clock following; the count of messages sent.
fn play(
    args: &Args,
    timeline: &Timeline,
    publishers: &[TopicPublisher],
    play_clock: &Mutex<PlayClock>,
) -> Result<u64, String> {
    let first = timeline.first_ns();
    let mut sent = 0u64;
    for _ in 0..args.loops {
        let start = Instant::now();
        play_clock.lock().expect("clock lock").set(first, args.rate > 0.0);
        for (time, idx, msg) in &timeline.messages {
            if args.rate == 0.0 {
                play_clock.lock().expect("clock lock").set(*time, false);
            } else {
                let due = Duration::from_nanos(((time - first) as f64 / args.rate) as u64);
                if let Some(wait) = due.checked_sub(start.elapsed()) {
                    std::thread::sleep(wait);
                }
            }
            publishers[*idx].publish(msg).map_err(|e| format!("cannot publish on {}: {e}", timeline.topics[*idx].0))?;
            sent += 1;
        }
    }
    Ok(sent)
}

fn replay(args: &Args) -> Result<String, String> {
    if !(args.rate >= 0.0 && args.rate.is_finite()) {
        return Err(format!("--rate must be a number >= 0, got {}", args.rate));
    }
    if let Some(hz) = args.clock.filter(|hz| !(*hz > 0.0 && hz.is_finite())) {
        return Err(format!("--clock must be a rate in Hz > 0, got {hz}"));
    }
    let timeline = Timeline::read(args)?;

    let env = RosEnv::from_env().map_err(|e| e.to_string())?;
    if env.middleware == crate::rmw::Middleware::Zenoh {
        // The node speaks Zenoh (src/ros/node/zenoh.rs); the replay publisher does not yet.
        return Err("RMW_IMPLEMENTATION=rmw_zenoh_cpp: replay publishes on DDS only; replay into a Zenoh cell with `ros2 bag play` on rmw_zenoh_cpp".into());
    }
    let security = crate::rmw::security::resolve(&env.security, None).map_err(|e| e.to_string())?;
    let participant = crate::rmw::dds::participant_from_env(&env, &security)?;
    let (ctx, _) = crate::rmw::dds::context(participant)?;
    let mut node = ctx
        .new_node(NodeName::new("/", "tracer_calib_replay").unwrap(), NodeOptions::new().enable_rosout(false))
        .map_err(|e| format!("{e:?}"))?;
    let publishers = publishers(&mut node, &timeline)?;
    let play_clock = Arc::new(Mutex::new(PlayClock {
        bag_ns: timeline.first_ns(),
        at: Instant::now(),
        rate: args.rate,
        running: false,
    }));
    let done = Arc::new(AtomicBool::new(false));
    let clock_thread = match args.clock {
        Some(hz) => Some(start_clock(&mut node, hz, play_clock.clone(), done.clone())?),
        None => None,
    };
    let spinner = smol::spawn(node.spinner().map_err(create_error)?.spin());

    wait_for_subscribers(&node, &publishers, args.wait);
    let sent = play(args, &timeline, &publishers, &play_clock)?;
    play_clock.lock().expect("clock lock").set(timeline.last_ns(), false);
    std::thread::sleep(Duration::from_secs_f64(args.linger.max(0.0)));
    done.store(true, Ordering::Relaxed);
    if let Some(t) = clock_thread {
        let _ = t.join();
    }
    drop(spinner);
    Ok(format!(
        "published {sent} messages on {}{} from {}",
        timeline.topics.iter().map(|(n, _)| n.as_str()).collect::<Vec<_>>().join(", "),
        if args.clock.is_some() { ", and /clock" } else { "" },
        args.input.display()
    ))
}
