//! `tracer_calib replay`: a bag's scans published into a live ROS graph, like
//! `ros2 bag play`.

use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

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

/// One message to publish.
enum Out {
    Raw(RawScan),
    Contour(Contour),
}

fn replay(args: &Args) -> Result<String, String> {
    if !(args.rate >= 0.0 && args.rate.is_finite()) {
        return Err(format!("--rate must be a number >= 0, got {}", args.rate));
    }
    if let Some(hz) = args.clock.filter(|hz| !(*hz > 0.0 && hz.is_finite())) {
        return Err(format!("--clock must be a rate in Hz > 0, got {hz}"));
    }
    let bag = Bag::open(&args.input).map_err(|e| e.to_string())?;
    let wanted = |name: &str| args.topics.is_empty() || args.topics.iter().any(|t| t == name);
    // (log time, topic index, message)
    let mut timeline: Vec<(u64, usize, Out)> = Vec::new();
    let mut topics: Vec<(String, &'static str)> = Vec::new();
    for t in bag.topics() {
        if !wanted(&t.name) {
            continue;
        }
        let idx = topics.len();
        if t.type_name == RawScan::NAME.ros_name() {
            for (time, m) in bag.read::<RawScan>(&t.name).map_err(|e| e.to_string())? {
                timeline.push((time, idx, Out::Raw(m)));
            }
            topics.push((t.name.clone(), "raw"));
        } else if t.type_name == Contour::NAME.ros_name() {
            for (time, m) in bag.read::<Contour>(&t.name).map_err(|e| e.to_string())? {
                timeline.push((time, idx, Out::Contour(m)));
            }
            topics.push((t.name.clone(), "contour"));
        }
    }
    for t in &args.topics {
        if !topics.iter().any(|(n, _)| n == t) {
            return Err(format!("{}: no RawScan or Contour topic {t}", args.input.display()));
        }
    }
    if timeline.is_empty() {
        return Err(format!("{}: no RawScan or Contour messages to replay", args.input.display()));
    }
    timeline.sort_by_key(|(t, _, _)| *t);

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
    let qos = QosProfile::publisher_default()
        .reliability_reliable(WhenFull::DEFAULT)
        .durability(Durability::Volatile)
        .history(History::KeepLast { depth: 100 });
    let mk = |e: ros2_client::CreateError| format!("cannot create a DDS entity: {e:?}");
    let mut raw_pubs = Vec::new();
    let mut contour_pubs = Vec::new();
    for (name, kind) in &topics {
        let n = ros2_client::Name::parse(name).map_err(|e| format!("invalid topic or service name '{name}': {e}"))?;
        if *kind == "raw" {
            let topic = node.create_topic(&n, RawScan::NAME.message_type_name(), &qos).map_err(mk)?;
            raw_pubs.push(Some(node.create_publisher::<RawScan>(&topic, None).map_err(mk)?));
            contour_pubs.push(None);
        } else {
            let topic = node.create_topic(&n, Contour::NAME.message_type_name(), &qos).map_err(mk)?;
            contour_pubs.push(Some(node.create_publisher::<Contour>(&topic, None).map_err(mk)?));
            raw_pubs.push(None);
        }
    }
    // /clock as rosbag2's player publishes it: rclcpp's ClockQoS (best effort, keep last 1).
    let clock_pub = match args.clock {
        Some(_) => {
            let name = ros2_client::Name::new("/", "clock").expect("a valid name");
            let topic = node
                .create_topic(&name, Clock::NAME.message_type_name(), &QosProfile::subscription_default())
                .map_err(mk)?;
            Some(node.create_publisher::<Clock>(&topic, None).map_err(mk)?)
        }
        None => None,
    };
    let spinner = smol::spawn(node.spinner().map_err(mk)?.spin());
    let first = timeline[0].0;
    let play_clock =
        Arc::new(Mutex::new(PlayClock { bag_ns: first, at: Instant::now(), rate: args.rate, running: false }));
    let done = Arc::new(AtomicBool::new(false));
    let clock_thread = match (clock_pub, args.clock) {
        (Some(publisher), Some(hz)) => {
            let (play_clock, done) = (play_clock.clone(), done.clone());
            Some(std::thread::spawn(move || {
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
        _ => None,
    };

    let deadline = Instant::now() + Duration::from_secs_f64(args.wait.max(0.0));
    let matched = loop {
        let all = (0..topics.len()).all(|i| {
            raw_pubs[i].as_ref().map_or(0, |p| p.get_subscription_count(&node)) > 0
                || contour_pubs[i].as_ref().map_or(0, |p| p.get_subscription_count(&node)) > 0
        });
        if all || Instant::now() >= deadline {
            break all;
        }
        std::thread::sleep(Duration::from_millis(20));
    };
    if !matched {
        eprintln!(
            "tracer_calib replay: warning: not every topic has a subscriber after {} s; publishing anyway",
            args.wait
        );
    }
    let mut sent = 0u64;
    for _ in 0..args.loops {
        let start = Instant::now();
        play_clock.lock().expect("clock lock").set(first, args.rate > 0.0);
        for (time, idx, msg) in &timeline {
            if args.rate == 0.0 {
                play_clock.lock().expect("clock lock").set(*time, false);
            }
            if args.rate > 0.0 {
                let due = Duration::from_nanos(((time - first) as f64 / args.rate) as u64);
                if let Some(wait) = due.checked_sub(start.elapsed()) {
                    std::thread::sleep(wait);
                }
            }
            let result = match msg {
                Out::Raw(m) => {
                    raw_pubs[*idx].as_ref().expect("raw publisher").publish(m.clone()).map_err(|e| format!("{e:?}"))
                }
                Out::Contour(m) => contour_pubs[*idx]
                    .as_ref()
                    .expect("contour publisher")
                    .publish(m.clone())
                    .map_err(|e| format!("{e:?}")),
            };
            result.map_err(|e| format!("cannot publish on {}: {e}", topics[*idx].0))?;
            sent += 1;
        }
    }
    let last = timeline.last().expect("a message").0;
    play_clock.lock().expect("clock lock").set(last, false);
    std::thread::sleep(Duration::from_secs_f64(args.linger.max(0.0)));
    done.store(true, Ordering::Relaxed);
    if let Some(t) = clock_thread {
        let _ = t.join();
    }
    drop(spinner);
    Ok(format!(
        "published {sent} messages on {}{} from {}",
        topics.iter().map(|(n, _)| n.as_str()).collect::<Vec<_>>().join(", "),
        if args.clock.is_some() { ", and /clock" } else { "" },
        args.input.display()
    ))
}
