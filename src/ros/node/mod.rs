//! `tracer_calib_node`: the node's wiring. The cell's state ([`crate::cell::NodeState`]) and
//! the DDS entities ([`entities`]) are made first; then one async loop per concern moves
//! messages between them:
//!
//! | loop | what |
//! |---|---|
//! | [`scans`] | `raw_scan` in, `contour` (and `contour_polygon`) out |
//! | [`calibrate`] | the `calibrate` service |
//! | [`calibration`] | the calibration in force, latched, at start-up and on each change |
//! | [`diagnostics`] | `/diagnostics` at 1 Hz |
//! | [`graph`] | matches (polygons only when someone listens) and incompatible QoS |
//! | [`type_description`] | `~/get_type_description` (REP-2016) |
//! | [`lifecycle`] | a managed node's lifecycle services and transition events |
//!
//! The parameters ([`parameters`]) are served by ros2-client's parameter services, with
//! the cell's validation. Each loop reads the [`Entities`] and the [`Shared`] state and
//! nothing else, so a lifecycle state or a second middleware is added here, in one place.

mod calibrate;
mod calibration;
mod config;
mod diagnostics;
mod entities;
mod graph;
mod lifecycle;
mod parameters;
mod rate_limit;
mod scans;
mod type_description;

use std::pin::Pin;
use std::sync::atomic::AtomicBool;
use std::sync::{Arc, Mutex, OnceLock};
use std::time::Instant;

use futures::{StreamExt, stream::FuturesUnordered};
use log::{error, info, warn};

use ros2_client::NodeClock;

use crate::cell::{NodeState, Now};
use crate::params::file as params_file;
pub use config::Config;
use entities::{Endpoints, Entities};
use graph::QosReports;
pub use rate_limit::RateLimit;

/// The node's default name (CONTRACT.md).
pub const DEFAULT_NODE_NAME: &str = "tracer_calibrator";

/// What the loops share besides the entities.
struct Shared {
    /// The cell's state: every handler runs under this lock.
    state: Arc<Mutex<NodeState>>,
    /// The calibration in force changed (a parameter set, a `/calibrate` that applied):
    /// the [`calibration`] loop publishes it.
    calibration_changed: smol::channel::Sender<()>,
    /// Whether anyone subscribes to the polygons (kept by [`graph`], read by [`scans`]).
    polygon_wanted: AtomicBool,
    /// Remote endpoints with an incompatible QoS, reported once each.
    qos_reports: Mutex<QosReports>,
    /// The node's clock (simulated under `use_sim_time`), once the node exists.
    clock: Arc<OnceLock<NodeClock>>,
}

impl Shared {
    /// Now, on the system clock and on the node's ROS clock.
    fn now(&self) -> Now {
        now_on(&self.clock)
    }
}

/// Now, on the system clock and on `clock` (the system clock too until it is set).
fn now_on(clock: &OnceLock<NodeClock>) -> Now {
    let now = Now::system();
    match clock.get() {
        Some(clock) => Now { ros: clock.now().into(), ..now },
        None => now,
    }
}

/// The cell's state at start-up: the parameters, and what the history file says of the
/// calibration in force. A managed node starts unconfigured: it reads the history when
/// configured.
fn initial_state(fqn: &str, params: &crate::params::Parameters) -> NodeState {
    let mut initial = NodeState::new(fqn.to_string(), params.clone());
    if params.managed {
        initial.lifecycle = Some(crate::cell::lifecycle::Lifecycle::new());
        info!("{fqn}: managed (lifecycle) node, unconfigured");
    } else {
        log_history_read(&initial.read_history());
    }
    initial
}

/// What reading the history file gave, in the log.
fn log_history_read(read: &crate::cell::HistoryRead) {
    for w in &read.warnings {
        warn!("{w}");
    }
    if !read.note.is_empty() {
        info!("{}", read.note);
    }
}

/// Run the node until `shutdown` resolves (SIGINT/SIGTERM in the binary).
pub fn run(config: Config, shutdown: impl std::future::Future<Output = ()>) -> Result<(), String> {
    let Config { identity, args, env, params, mut qos, security } = config;
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
    let endpoints = Endpoints::resolve(&args, &identity, &mut qos)?;
    let mut initial = initial_state(&fqn, &params);
    initial.extra_params = qos.to_list();
    let state = Arc::new(Mutex::new(initial));
    let (calibration_changed, calibration_changes) = smol::channel::unbounded::<()>();
    let shared = Shared {
        qos_reports: Mutex::new(QosReports::new(state.clone())),
        state,
        calibration_changed,
        polygon_wanted: AtomicBool::new(false),
        clock: Arc::new(OnceLock::new()),
    };
    let options = parameters::options(&params, &qos, &shared);
    let entities = Entities::create(&env, &security, &identity, options, &endpoints, params.managed)?;
    let _ = shared.clock.set(entities.node.clock());
    info!(
        "{fqn}: listening on {} (raw scans), serving {}; domain {}, discovery {:?}",
        endpoints.raw_scan.0, endpoints.calibrate, env.domain_id, env.discovery_range
    );

    // Each loop is a future of its own, with its own waker: a scan arriving wakes the
    // scan loop alone. (Under one `select!`, every wake-up polled every loop, the
    // calibrate request stream and the diagnostics timer included: the latency bench
    // had the node ~15 µs slower, +62..+68 µs over the relay against +46..+55 µs.)
    // The first loop to end ends the node.
    let (e, shared) = (&entities, &shared);
    let mut loops: FuturesUnordered<Pin<Box<dyn Future<Output = ()> + '_>>> = FuturesUnordered::new();
    loops.push(Box::pin(graph::run(e, shared)));
    loops.push(Box::pin(async {
        scans::run(e, shared).await;
        error!("the raw scan stream ended")
    }));
    loops.push(Box::pin(async {
        calibrate::run(e, shared).await;
        error!("the calibrate request stream ended")
    }));
    loops.push(Box::pin(diagnostics::run(e, shared)));
    loops.push(Box::pin(async {
        type_description::run(e).await;
        error!("the type description request stream ended")
    }));
    loops.push(Box::pin(async {
        calibration::run(e, shared, calibration_changes).await;
        error!("the calibration change stream ended")
    }));
    if let Some(l) = &e.lifecycle {
        loops.push(Box::pin(async move {
            lifecycle::run(l, shared).await;
            error!("the lifecycle request streams ended")
        }));
    }
    loops.push(Box::pin(async {
        shutdown.await;
        info!("{fqn}: shutting down")
    }));
    smol::block_on(loops.next());
    drop(loops);
    shared.qos_reports.lock().expect("qos reports lock").flush(&entities.node, Instant::now(), true);
    entities.close();
    Ok(())
}
