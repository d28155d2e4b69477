//! `tracer_calib_node`: the node's wiring. Entities are created first, then one async
//! loop each moves messages between DDS and [`super::state::NodeState`].
//!
//! | kind | name | QoS |
//! |---|---|---|
//! | subscription | `raw_scan` | reliable, keep last 100, volatile |
//! | publisher | `contour`, `contour_polygon` | reliable, keep last 10, volatile |
//! | service | `calibrate` (Fast DDS "Enhanced" mapping) | reliable, keep last 1000 |
//! | publisher | `/diagnostics`, 1 Hz | reliable, keep last 10 |
//! | publisher | `calibration` (the calibration in force) | reliable, transient local, keep last 1 |
//!
//! Why: every scan is a measurement an edger acts on, so delivery is reliable (as the
//! ROS default a tracer driver publishes with; a best-effort "sensor data" publisher
//! does not match a reliable subscription, and has to be configured reliable); the
//! subscription keeps 100 scans so a bag replayed at full speed is not thinned out;
//! contours are not latched (volatile): a late subscriber wants the next scan, not an
//! old one. The calibration in force is latched: whoever joins later must know which
//! calibration the contours it receives were corrected with.

use std::net::{IpAddr, Ipv4Addr};
use std::pin::Pin;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use futures::{StreamExt, stream::FuturesUnordered};
use log::{debug, error, info, warn};
use ros2_client::{
    Context, Name, NodeOptions, ParameterValue as RosValue, QosProfile, ServiceMapping,
    builtin_interfaces::Time,
    qos::{Durability, History, WhenFull},
    rosout,
};
use rustdds::DomainParticipantBuilder;

use super::args::{NodeIdentity, RosArgs, RosEnv, ros2_name};
use super::msgs::Contour;
use super::msgs::{
    Calibrate, Calibration as CalibrationMsg, DiagnosticArray, PolygonStamped, RawScan, RosMsg, RosService, type_names,
};
use super::state::{NodeState, RateLimit};
use crate::params::{ParamValue, Parameters, file as params_file, names};
use crate::records;

/// The node's default name (CONTRACT.md).
pub const DEFAULT_NODE_NAME: &str = "tracer_calibrator";

/// Everything the node needs to start, from the command line, the environment and
/// the params files.
#[derive(Debug, Clone)]
pub struct Config {
    pub identity: NodeIdentity,
    pub args: RosArgs,
    pub env: RosEnv,
    pub params: Parameters,
}

impl Config {
    /// Defaults, then every `--params-file` in order, then `-p` overrides. A file that
    /// does not parse or has a wrong type stops the node (the error names the file,
    /// line and key); the file is not touched.
    pub fn load(args: RosArgs, env: RosEnv) -> Result<Config, String> {
        let identity = args.node_identity(DEFAULT_NODE_NAME, "/").map_err(|e| e.to_string())?;
        let fqn = identity.fully_qualified_name();
        let mut params = Parameters::default();
        // `history_file` defaults to beside `params_file`, unless set (even to "").
        let mut history_file_set = false;
        for path in args.params_files() {
            let file = params_file::read(path).map_err(|e| e.to_string())?;
            history_file_set |= file.entries_for(&fqn).any(|e| e.name == names::HISTORY_FILE);
            let unknown = params.apply_file(&file, &fqn, &path.display().to_string()).map_err(|e| e.to_string())?;
            for name in unknown {
                debug!("{}: ignoring parameter '{name}' (not a parameter of this node)", path.display());
            }
        }
        if let Some(last) = args.params_files().last() {
            params.params_file = last.display().to_string();
        }
        for o in args.param_overrides_for(&identity) {
            params.set(&o.name, &o.value).map_err(|e| format!("-p {}:={}: {e}", o.name, o.value))?;
            history_file_set |= o.name == names::HISTORY_FILE;
        }
        if !history_file_set {
            params.history_file = records::file::default_path(&params.params_file);
        }
        Ok(Config { identity, args, env, params })
    }
}

/// Calibrate requests waiting for the one-at-a-time fit. The DDS reader drops the
/// oldest unread sample past this depth, and a dropped request is a caller waiting
/// forever: with ROS's service default of 10, eleven calls arriving during one fit
/// would lose one. A request is a few bytes, so the bound is generous.
const CALIBRATE_QUEUE: usize = 1000;

fn reliable(depth: usize) -> QosProfile {
    QosProfile::publisher_default()
        .reliability_reliable(WhenFull::DEFAULT)
        .durability(Durability::Volatile)
        .history(History::KeepLast { depth })
}

/// The `calibration` topic: reliable, transient local, depth 1, so a subscriber that
/// joins later gets the calibration in force at once.
fn latched() -> QosProfile {
    QosProfile::publisher_default()
        .reliability_reliable(WhenFull::DEFAULT)
        .durability(Durability::TransientLocal)
        .history(History::KeepLast { depth: 1 })
}

/// The DDS participant: `ROS_DOMAIN_ID`, and with
/// `ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST` only 127.0.0.1.
fn context(env: &RosEnv) -> Result<Context, String> {
    let domain =
        u16::try_from(env.domain_id).map_err(|_| format!("ROS_DOMAIN_ID {} is out of range", env.domain_id))?;
    let mut builder = DomainParticipantBuilder::new(domain);
    if env.discovery_range.is_local_only() {
        builder = builder.with_only_networks([IpAddr::V4(Ipv4Addr::LOCALHOST)]);
    }
    let participant = builder.build().map_err(|e| format!("cannot create the DDS participant: {e:?}"))?;
    Context::from_domain_participant(participant).map_err(|e| format!("cannot create the ROS context: {e:?}"))
}

fn from_ros(v: &RosValue) -> Option<ParamValue> {
    Some(match v {
        RosValue::Boolean(b) => ParamValue::Bool(*b),
        RosValue::Integer(i) => ParamValue::Integer(*i),
        RosValue::Double(d) => ParamValue::Double(*d),
        RosValue::String(s) => ParamValue::String(s.clone()),
        RosValue::BooleanArray(v) => ParamValue::BoolArray(v.clone()),
        RosValue::IntegerArray(v) => ParamValue::IntegerArray(v.clone()),
        RosValue::DoubleArray(v) => ParamValue::DoubleArray(v.clone()),
        RosValue::StringArray(v) => ParamValue::StringArray(v.clone()),
        RosValue::NotSet | RosValue::ByteArray(_) => return None,
    })
}

/// Free heap below which the node gives nothing back to the OS (bytes). Memory given
/// back costs a page fault per 4 kB page when it is used again. A steady stream of
/// scans keeps a few MB in flight in rustdds' caches (about 10 MB at 100 scans a
/// second); trimming that every 5 s, as the node did, had the scans after each trim
/// fault the released pages in again (+12.6..+14.1 % instead of +7.3..+8.2 % over the
/// bare relay in 3000-round runs of `scripts/bench_latency.sh`).
const KEEP_FREE_HEAP: usize = 32 << 20;

/// After a burst, give memory the allocator holds but no longer uses back to the OS.
/// rustdds frees the samples its reader and writer caches no longer need every 4-6 s;
/// after a bag replayed at full speed (thousands of scans a second) glibc would
/// otherwise keep the peak resident for good. Up to [`KEEP_FREE_HEAP`] of free heap
/// is kept: that memory is what the next scans will use.
fn release_freed_memory() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    // SAFETY: mallinfo2 only reads the allocator's statistics and malloc_trim only
    // releases free heap memory; neither takes pointers.
    unsafe {
        if libc::mallinfo2().fordblks > KEEP_FREE_HEAP {
            libc::malloc_trim(0);
        }
    }
}

/// Run the node until `shutdown` resolves (SIGINT/SIGTERM in the binary).
pub fn run(config: Config, shutdown: impl std::future::Future<Output = ()>) -> Result<(), String> {
    let Config { identity, args, env, params } = config;
    for w in &env.warnings {
        warn!("{w}");
    }
    let fqn = identity.fully_qualified_name();
    if !params.params_file.is_empty() {
        let removed = params_file::remove_stale_temp_files(std::path::Path::new(&params.params_file));
        if removed > 0 {
            info!("removed {removed} temporary file(s) a killed writer left beside {}", params.params_file);
        }
    }
    let mut initial = NodeState::new(fqn.clone(), params.clone());
    if !params.history_file.is_empty() {
        match records::file::read(std::path::Path::new(&params.history_file)) {
            Ok(history) => {
                for skipped in &history.skipped {
                    warn!("{skipped}");
                }
                initial.adopt_history(&history);
                info!(
                    "{}: {} calibration record(s); the calibration in force comes from the {}",
                    params.history_file,
                    history.records.len(),
                    initial.in_force.source
                );
            }
            Err(e) => {
                warn!("{e}");
                initial.history_problem = e;
            }
        }
    }
    let state = Arc::new(Mutex::new(initial));
    // The calibration in force changed (a parameter set, a /calibrate that applied):
    // the `calibration` loop publishes it.
    let (calibration_changed, calibration_changes) = smol::channel::unbounded::<()>();

    // Parameters: validated by the same rules as the params file; a change is applied
    // to the state and persisted (only when the value really changes, so the start-up
    // round of set actions writes nothing). A failed write fails the set.
    let mut options = NodeOptions::new().enable_rosout(true);
    for (name, value) in params.to_list() {
        options = options.declare_parameter(&name, value.into());
    }
    let validator_state = state.clone();
    let action_state = state.clone();
    let action_changed = calibration_changed.clone();
    let options = options
        .parameter_validator(Box::new(move |name, value| {
            if !Parameters::is_known(name) {
                return Ok(());
            }
            let v = from_ros(value).ok_or_else(|| format!("{name}: unsupported value type"))?;
            let mut trial = validator_state.lock().expect("state lock").params.clone();
            trial.set(name, &v).map_err(|e| format!("{name}: {e}"))
        }))
        .parameter_set_action(Box::new(move |name, value| {
            if !Parameters::is_known(name) {
                return Ok(());
            }
            let v = from_ros(value).ok_or_else(|| format!("{name}: unsupported value type"))?;
            let mut st = action_state.lock().expect("state lock");
            if st.params.get(name).as_ref() == Some(&v) {
                return Ok(());
            }
            let before = st.params.clone();
            st.params.set(name, &v).map_err(|e| format!("{name}: {e}"))?;
            if let Err(e) = st.persist() {
                st.params = before;
                return Err(format!("{name}: not changed: {e}"));
            }
            if names::CALIBRATION_IN_FORCE.contains(&name) {
                st.calibration_set_by_parameters(std::time::SystemTime::now());
            }
            if name.starts_with("calibration.") {
                let _ = action_changed.try_send(());
            }
            info!("parameter {name} = {v}");
            Ok(())
        }));

    let ctx = context(&env)?;
    let node_name = identity.ros2_node_name().map_err(|e| e.to_string())?;
    let mut node = ctx.new_node(node_name, options).map_err(|e| format!("cannot create the node: {e:?}"))?;

    let resolve = |name: &str| -> Result<Name, String> {
        let resolved = args.resolve_topic(name, &identity).map_err(|e| e.to_string())?;
        ros2_name(&resolved).map_err(|e| e.to_string())
    };
    let raw_name = resolve("raw_scan")?;
    let contour_name = resolve("contour")?;
    let polygon_name = resolve("contour_polygon")?;
    let diag_name = resolve("/diagnostics")?;
    let calibration_name = resolve("calibration")?;
    let service_name = {
        let resolved = args.resolve_service("calibrate", &identity).map_err(|e| e.to_string())?;
        ros2_name(&resolved).map_err(|e| e.to_string())?
    };
    let mk = |e: ros2_client::CreateError| format!("cannot create a DDS entity: {e:?}");
    let raw_topic = node.create_topic(&raw_name, RawScan::NAME.message_type_name(), &reliable(100)).map_err(mk)?;
    let contour_topic =
        node.create_topic(&contour_name, Contour::NAME.message_type_name(), &reliable(10)).map_err(mk)?;
    let polygon_topic =
        node.create_topic(&polygon_name, type_names::POLYGON_STAMPED.message_type_name(), &reliable(10)).map_err(mk)?;
    let diag_topic =
        node.create_topic(&diag_name, type_names::DIAGNOSTIC_ARRAY.message_type_name(), &reliable(10)).map_err(mk)?;
    let calibration_topic =
        node.create_topic(&calibration_name, CalibrationMsg::NAME.message_type_name(), &latched()).map_err(mk)?;
    let subscription = node.create_subscription::<RawScan>(&raw_topic, None).map_err(mk)?;
    let contour_pub = node.create_publisher::<Contour>(&contour_topic, None).map_err(mk)?;
    let polygon_pub = node.create_publisher::<PolygonStamped>(&polygon_topic, None).map_err(mk)?;
    let diag_pub = node.create_publisher::<DiagnosticArray>(&diag_topic, None).map_err(mk)?;
    let calibration_pub = node.create_publisher::<CalibrationMsg>(&calibration_topic, None).map_err(mk)?;
    let server = node
        .create_server::<<Calibrate as RosService>::Request, <Calibrate as RosService>::Response>(
            ServiceMapping::Enhanced,
            &service_name,
            &Calibrate::type_name(),
            reliable(CALIBRATE_QUEUE),
            reliable(CALIBRATE_QUEUE),
        )
        .map_err(mk)?;
    let spinner = smol::spawn(node.spinner().map_err(mk)?.spin());
    info!(
        "{fqn}: listening on {raw_name} (raw scans), serving {service_name}; domain {}, discovery {:?}",
        env.domain_id, env.discovery_range
    );

    // Whether anyone subscribes to the polygons: asking costs ~70 µs (it walks the
    // discovered graph), too much per scan, so the diagnostics tick asks once a second.
    // By topic name over the discovered readers: `Publisher::get_subscription_count`
    // logs an error every time it is asked before a first subscriber ever matched.
    let polygon_topic_name = polygon_name.to_string();
    let polygon_wanted = AtomicBool::new(true);
    let scans = async {
        let mut stream = std::pin::pin!(subscription.async_stream());
        let mut limit = RateLimit::new(Duration::from_secs(1));
        while let Some(item) = stream.next().await {
            let msg = match item {
                Ok((msg, _info)) => msg,
                Err(e) => {
                    // A message that does not even decode: counted like a malformed scan.
                    let mut st = state.lock().expect("state lock");
                    st.stats.scans_received += 1;
                    st.stats.scans_rejected += 1;
                    st.stats.last_rejection = format!("undecodable message: {e:?}");
                    if let Some(held) = limit.allow(Instant::now()) {
                        warn!("rejected an undecodable raw scan: {e:?} ({held} more rejections not shown)");
                    }
                    continue;
                }
            };
            // The polygon (for RViz) only when someone listens to it.
            let with_polygon = polygon_wanted.load(Ordering::Relaxed);
            let outcome = state.lock().expect("state lock").on_raw_scan(&msg, with_polygon);
            match outcome {
                Ok(out) => {
                    if let Err(e) = contour_pub.async_publish(out.contour).await {
                        warn!("cannot publish a contour: {e:?}");
                    }
                    if let Some(polygon) = out.polygon
                        && let Err(e) = polygon_pub.async_publish(polygon).await
                    {
                        warn!("cannot publish a polygon: {e:?}");
                    }
                }
                Err(e) => {
                    if let Some(held) = limit.allow(Instant::now()) {
                        let total = state.lock().expect("state lock").stats.scans_rejected;
                        warn!("rejected raw scan {}: {e} ({total} rejected so far, {held} not shown)", msg.scan_id);
                    }
                }
            }
        }
    };

    let calls = async {
        let mut requests = std::pin::pin!(server.receive_request_stream());
        while let Some(item) = requests.next().await {
            let (id, req) = match item {
                Ok(r) => r,
                Err(e) => {
                    warn!("cannot read a calibrate request: {e:?}");
                    continue;
                }
            };
            debug!("calibrate request {id:?}: scan_id {}, dry_run {}", req.scan_id, req.dry_run);
            // One fit at a time: the loop handles a request to the end before the next.
            let outcome = state.lock().expect("state lock").on_calibrate(&req);
            if let Some(m) = outcome.applied {
                // Mirror into the ROS parameters (already persisted: the set action sees
                // equal values and writes nothing).
                for (name, value) in [
                    (names::ALPHA0, RosValue::Double(m.alpha0)),
                    (names::OFFSET, RosValue::Double(m.offset)),
                    (names::DELTA_L, RosValue::Double(m.delta_l)),
                    (names::SCALE, RosValue::Double(m.scale)),
                    (names::VALID, RosValue::Boolean(true)),
                ] {
                    if let Err(e) = node.set_parameter(name, value) {
                        error!("cannot mirror {name} into the ROS parameters: {e}");
                    }
                }
            }
            if outcome.applied.is_some() {
                let _ = calibration_changed.try_send(());
            }
            let r = &outcome.response;
            if r.success {
                rosout!(node, ros2_client::ros2::LogLevel::Info, "calibrate: {}", r.message);
            } else {
                rosout!(node, ros2_client::ros2::LogLevel::Warn, "calibrate: {}", r.message);
                warn!("calibrate: {}", r.message);
            }
            match server.async_send_response(id, outcome.response).await {
                Ok(()) => debug!("calibrate response {id:?} sent"),
                Err(e) => warn!("cannot send a calibrate response: {e:?}"),
            }
        }
    };

    // The calibration in force, latched: at start-up, then at every change (several
    // changes queued by one parameter set go out as one message).
    let calibration = async {
        loop {
            let msg = state.lock().expect("state lock").calibration_msg();
            debug!("publishing the calibration in force: {msg:?}");
            if let Err(e) = calibration_pub.async_publish(msg).await {
                warn!("cannot publish the calibration in force: {e:?}");
            }
            if calibration_changes.recv().await.is_err() {
                break;
            }
            while calibration_changes.try_recv().is_ok() {}
        }
    };

    let diagnostics = async {
        let mut tick = 0u64;
        loop {
            polygon_wanted.store(node.subscription_count(&polygon_topic_name) > 0, Ordering::Relaxed);
            let msg = state.lock().expect("state lock").diagnostics(Time::now());
            if let Err(e) = diag_pub.async_publish(msg).await {
                debug!("cannot publish diagnostics: {e:?}");
            }
            tick += 1;
            if tick.is_multiple_of(5) {
                release_freed_memory();
            }
            smol::Timer::after(Duration::from_secs(1)).await;
        }
    };

    // Each loop is a future of its own, with its own waker: a scan arriving wakes the
    // scan loop alone. (Under one `select!`, every wake-up polled every loop, the
    // calibrate request stream and the diagnostics timer included: the latency bench
    // had the node ~15 µs slower, +62..+68 µs over the relay against +46..+55 µs.)
    // The first loop to end ends the node.
    let mut loops: FuturesUnordered<Pin<Box<dyn Future<Output = ()> + '_>>> = FuturesUnordered::new();
    loops.push(Box::pin(async {
        scans.await;
        error!("the raw scan stream ended")
    }));
    loops.push(Box::pin(async {
        calls.await;
        error!("the calibrate request stream ended")
    }));
    loops.push(Box::pin(diagnostics));
    loops.push(Box::pin(async {
        calibration.await;
        error!("the calibration change stream ended")
    }));
    loops.push(Box::pin(async {
        shutdown.await;
        info!("{fqn}: shutting down")
    }));
    smol::block_on(loops.next());
    drop(loops);
    // Tear down in order: dropping each endpoint makes discovery announce it gone; the
    // participant's event loop must still be running to send that, so it goes last,
    // after a moment. Without this, peers keep the node's topics and services in their
    // graphs for the lease duration.
    drop((subscription, contour_pub, polygon_pub, diag_pub, calibration_pub, server));
    drop(node);
    std::thread::sleep(Duration::from_millis(150));
    smol::block_on(spinner.cancel());
    drop(ctx);
    Ok(())
}
