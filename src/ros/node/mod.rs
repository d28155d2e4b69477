//! `tracer_calib_node`: the node's wiring. The cell's state ([`crate::cell::NodeState`]) and
//! the middleware's entities ([`entities`], written once over a [`backend`]: DDS, [`dds`];
//! Zenoh, under `RMW_IMPLEMENTATION=rmw_zenoh_cpp`, [`zenoh`]) are made first; then one
//! async loop per concern moves messages between them, written once against [`Wire`]:
//!
//! | loop | what |
//! |---|---|
//! | [`scans`] | `raw_scan` in, `contour` (and `contour_polygon`) out |
//! | [`calibrate`] | the `calibrate` service |
//! | [`calibration`] | the calibration in force, latched, at start-up and on each change |
//! | [`diagnostics`] | `/diagnostics` at 1 Hz |
//! | [`type_description`] | `~/get_type_description` (REP-2016) |
//! | [`graph`] | DDS: matches (polygons only when someone listens) and incompatible QoS (reported once a second) |
//! | [`lifecycle`] | a managed node's lifecycle services and transition events |
//! | [`zenoh::run_graph_and_parameters`] | Zenoh: the graph (polygons only when someone listens), the parameter services |
//!
//! The parameters ([`parameters`]) are served by ros2-client's parameter services, with
//! the cell's validation. Each loop reads the [`Wire`] and the [`Shared`] state and
//! nothing else: the middleware is chosen here, in one place.

// The map above names the private parts of the shell; they resolve in the documentation of
// the private items (`cargo doc --document-private-items`, as the test command builds it).
#![allow(rustdoc::private_intra_doc_links)]

mod backend;
mod bond;
mod calibrate;
mod calibration;
mod config;
mod dds;
mod diagnostics;
mod endpoints;
mod entities;
mod graph;
mod lifecycle;
#[cfg(test)]
mod memory;
mod parameters;
mod rate_limit;
mod scans;
mod shared;
#[cfg(test)]
mod tests;
mod type_description;
mod wire;
#[cfg(feature = "zenoh")]
mod zenoh;

use std::pin::Pin;
use std::time::{Duration, Instant};

use futures::{StreamExt, stream::FuturesUnordered};
use log::{error, info, warn};

use crate::cell::NodeState;
use crate::params::file as params_file;
use crate::rmw::Middleware;
use backend::Backend;
pub use config::Config;
use dds::Dds;
use endpoints::Endpoints;
use entities::Entities;
pub use rate_limit::RateLimit;
use shared::{RosClock, Shared, now_on};
use wire::Wire;

/// The node's default name (docs/CONTRACT.md).
pub const DEFAULT_NODE_NAME: &str = "tracer_calibrator";

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
    let Config { identity, args, env, params, mut qos, security, persist_problem } = config;
    let middleware = env.middleware;
    for w in &env.warnings {
        warn!("{w}");
    }
    let fqn = identity.fully_qualified_name();
    crate::ros::logging::for_node(&args, &identity.logger_name());
    // The node's records from here on queue for /rosout; its loop publishes them. None
    // queue once `run` returns, however it does.
    let rosout = crate::ros::logging::attach_rosout();
    struct Detach;
    impl Drop for Detach {
        fn drop(&mut self) {
            crate::ros::logging::detach_rosout();
        }
    }
    let _detach = Detach;
    if !params.params_file.is_empty() {
        let removed = params_file::remove_stale_temp_files(std::path::Path::new(&params.params_file));
        if removed > 0 {
            info!("removed {removed} temporary file(s) a killed writer left beside {}", params.params_file);
        }
    }
    let bond_period = bond::period(&params);
    let endpoints = Endpoints::resolve(&args, &identity, &mut qos, bond_period.is_some())?;
    let mut initial = initial_state(&fqn, &params);
    initial.extra_params = qos.to_list();
    initial.persist_problem = persist_problem;
    initial.driver.topic = endpoints.raw_scan.0.to_string();
    let shared = Shared::new(initial);
    let bond = bond_period.map(|period| (identity.name.as_str(), period));
    let options = parameters::options(&params, &qos, &shared);
    match middleware {
        Middleware::Dds => {
            let opened = Dds::open(&env, &security, &identity, options)?;
            let entities = Entities::create(opened, &identity, &endpoints, params.managed)?;
            let _ = shared.clock.set(entities.clock());
            info!(
                "{fqn}: listening on {} (raw scans), serving {}; DDS, domain {}, discovery {:?}",
                endpoints.raw_scan.0, endpoints.calibrate, env.domain_id, env.discovery_range
            );
            let e = &entities;
            serve(e, &shared, Box::pin(graph::run(e, &shared)), shutdown, &fqn, rosout, bond);
            shared.qos_reports.lock().expect("qos reports lock").flush(&entities.node, Instant::now(), true);
            entities.close();
        }
        #[cfg(feature = "zenoh")]
        Middleware::Zenoh => {
            if let crate::rmw::Security::Enclave { name, .. } = &security {
                return Err(format!(
                    "ROS_SECURITY_ENABLE=true (enclave {name}): SROS2 is served on DDS only; on Zenoh (RMW_IMPLEMENTATION=rmw_zenoh_cpp) secure the router's links with Zenoh's TLS and access control"
                ));
            }
            let zenv = crate::rmw::zenoh::ZenohEnv::from_env();
            let opened = zenoh::Zenoh::open(&env, &zenv, &identity, options)?;
            let entities = Entities::create(opened, &identity, &endpoints, params.managed)?;
            let _ = shared.clock.set(entities.clock());
            info!(
                "{fqn}: listening on {} (raw scans), serving {}; Zenoh (rmw_zenoh_cpp), domain {}",
                endpoints.raw_scan.0, endpoints.calibrate, env.domain_id
            );
            let e = &entities;
            serve(e, &shared, Box::pin(zenoh::run_graph_and_parameters(e, &shared)), shutdown, &fqn, rosout, bond);
            entities.close();
        }
        #[cfg(not(feature = "zenoh"))]
        Middleware::Zenoh => {
            return Err(
                "RMW_IMPLEMENTATION=rmw_zenoh_cpp: this build has no Zenoh (built without the cargo feature `zenoh`)"
                    .into(),
            );
        }
    }
    Ok(())
}

/// One of the node's loops.
type Loop<'a> = Pin<Box<dyn Future<Output = ()> + 'a>>;

/// Run the loops every middleware has, the middleware's `graph` loop, and a managed
/// node's lifecycle loop (and its bond's, `bond`: its id and heartbeat period), until one
/// ends or `shutdown` resolves; then a bond kept is broken. `rosout`: the node's log
/// records to publish on `/rosout`.
#[allow(clippy::too_many_arguments)]
fn serve<'a, B: Backend>(
    e: &'a Entities<B>,
    shared: &'a Shared,
    graph: Loop<'a>,
    shutdown: impl std::future::Future<Output = ()> + 'a,
    fqn: &'a str,
    rosout: Option<smol::channel::Receiver<crate::ros::logging::RosoutRecord>>,
    bond: Option<(&'a str, Duration)>,
) {
    // Each loop is a future of its own, with its own waker: a scan arriving wakes the
    // scan loop alone. (Under one `select!`, every wake-up polled every loop, the
    // calibrate request stream and the diagnostics timer included: measurably slower,
    // BENCHMARKS.md, "Figures behind choices in the code".) The first loop to end ends
    // the node.
    let mut loops: FuturesUnordered<Loop<'a>> = FuturesUnordered::new();
    loops.push(graph);
    if let Some(l) = &e.lifecycle {
        loops.push(Box::pin(async {
            lifecycle::run(l, shared).await;
            error!("the lifecycle request streams ended")
        }));
        if let Some((id, period)) = bond {
            loops.push(Box::pin(async move {
                bond::run(l, shared, id, period).await;
                error!("the bond's status stream ended")
            }));
        }
    }
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
        calibration::run(e, shared, shared.calibration_changes.clone()).await;
        error!("the calibration change stream ended")
    }));
    loops.push(Box::pin(async move {
        shutdown.await;
        info!("{fqn}: shutting down")
    }));
    // The node's log records on /rosout ([`crate::ros::logging`]): what was logged since
    // the node started, then each as it comes.
    if let Some(records) = rosout {
        loops.push(Box::pin(async move {
            while let Ok(record) = records.recv().await {
                e.rosout(&record);
            }
        }));
    }
    smol::block_on(loops.next());
    drop(loops);
    if let Some(l) = &e.lifecycle {
        smol::block_on(bond::leave(l, shared));
    }
}
