//! The node's loops in-process, through the in-memory [`MemoryWire`]: scans in and
//! contours out, `/calibrate` (the parameters mirrored by the node's own validator and set
//! action, the calibration latched), introspection, diagnostics and type descriptions, a
//! managed node's lifecycle and nav2's bond, each in milliseconds. What only a middleware shows (wire compatibility, discovery,
//! QoS, security, loss) the interop suites test against stock peers.

use std::time::Duration;

use nalgebra::Vector2;
use rand::SeedableRng;
use smol::channel::Receiver;

use super::lifecycle::{Call, Reply};
use super::memory::{LifecycleOut, MemoryLifecycle, MemoryWire};
use super::shared::Shared;
use super::{bond, calibrate, calibration, diagnostics, lifecycle, scans, type_description};
use crate::cell::NodeState;
use crate::cell::bond::BondState;
use crate::cell::lifecycle::State as CellState;
use crate::engine::geometry::Mounting;
use crate::engine::model::PlateSpec;
use crate::engine::shape::{Ellipse, Shape};
use crate::engine::simulate::{HeightOptions, SimOptions, SimScan, simulate, simulate_heights};
use crate::interfaces::{
    BondStatus, CalibrateRequest, CalibrateResponse, ChangeStateRequest, GetTypeDescriptionRequest,
    LifecycleTransition, RawScan, ServiceEventInfo,
};
use crate::params::{Introspection, Parameters};

/// The tracer these tests trace with.
const TRUTH: Mounting = Mounting { alpha0: 0.02, offset: 0.004, delta_l: 0.001, scale: 1.0 };

fn sim(shape: &impl Shape, seed: u64) -> SimScan {
    let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
    simulate(shape, &TRUTH, &SimOptions { noise: 2e-6, ..SimOptions::default() }, &mut rng).unwrap()
}

fn msg(scan_id: u32, target: u8, sim: &SimScan) -> RawScan {
    RawScan::of_simulation(scan_id, target, sim, 1e-6)
}

fn plate(scan_id: u32) -> RawScan {
    msg(scan_id, RawScan::TARGET_CALIBRATION_PLATE, &sim(&PlateSpec::default().at(Vector2::new(5e-4, -3e-4)), 1))
}

fn lens(scan_id: u32) -> RawScan {
    let ellipse = Ellipse { center: Vector2::new(3e-4, 2e-4), a: 0.025, b: 0.015, angle: 0.1 };
    msg(scan_id, RawScan::TARGET_LENS, &sim(&ellipse, 2))
}

fn node(params: Parameters) -> Shared {
    Shared::new(NodeState::new("/tracer_calibrator".into(), params))
}

/// The next message on `rx`, within 5 s.
async fn next<T>(rx: &Receiver<T>, what: &str) -> T {
    let timeout = async {
        smol::Timer::after(Duration::from_secs(5)).await;
        panic!("no {what} within 5 s")
    };
    futures::future::select(std::pin::pin!(rx.recv()), std::pin::pin!(timeout))
        .await
        .factor_first()
        .0
        .unwrap_or_else(|_| panic!("the {what} channel closed"))
}

/// Until `cond` holds, checked every 10 ms, 5 s at most.
async fn until(cond: impl Fn() -> bool, what: &str) {
    let start = std::time::Instant::now();
    while !cond() {
        assert!(start.elapsed() < Duration::from_secs(5), "not {what} within 5 s");
        smol::Timer::after(Duration::from_millis(10)).await;
    }
}

/// Run `test` while the node's loops run (until `test` ends).
fn with_loops(shared: &Shared, wire: &MemoryWire, test: impl Future<Output = ()>) {
    smol::block_on(async {
        let loops = async {
            futures::join!(
                scans::run(wire, shared),
                calibrate::run(wire, shared),
                calibration::run(wire, shared, shared.calibration_changes.clone()),
                diagnostics::run(wire, shared),
                type_description::run(wire),
            )
        };
        futures::future::select(std::pin::pin!(loops), std::pin::pin!(test)).await;
    });
}

#[test]
fn scans_in_contours_out_and_bad_ones_counted() {
    let shared = node(Parameters::default());
    let (wire, out) = MemoryWire::new(&shared);
    smol::block_on(async {
        let test = async {
            wire.send_scan(Ok(lens(1)));
            let c = next(&out.contours, "contour").await;
            assert_eq!((c.scan_id, c.calibrated, c.points.len()), (1, false, 400));
            assert!(out.polygons.is_empty(), "a polygon only when someone listens");
            // One that did not decode, one malformed: counted, and the loop goes on.
            wire.send_scan(Err("CDR: buffer too short".into()));
            wire.send_scan(Ok(RawScan { steps_per_revolution: 0, ..lens(2) }));
            shared.polygon_wanted.store(true, std::sync::atomic::Ordering::Relaxed);
            wire.send_scan(Ok(lens(3)));
            let c = next(&out.contours, "contour").await;
            assert_eq!(c.scan_id, 3);
            assert_eq!(next(&out.polygons, "polygon").await.polygon.points.len(), 400);
            let st = shared.state.lock().unwrap();
            assert_eq!((st.stats.scans_received, st.stats.scans_rejected), (4, 2), "{:?}", st.stats);
            drop(st);
            wire.close();
        };
        futures::join!(scans::run(&wire, &shared), test);
    });
}

#[test]
fn calibrate_applies_mirrors_latches_and_corrects() {
    let shared = node(Parameters { introspection: Introspection::Contents, ..Parameters::default() });
    let (wire, out) = MemoryWire::new(&shared);
    with_loops(&shared, &wire, async {
        let first = next(&out.calibrations, "calibration at start-up").await;
        assert!(!first.valid);
        // Nothing to fit yet: refused, by code.
        wire.call_calibrate(1, CalibrateRequest::default());
        let (id, r) = next(&out.calibrate_answers, "calibrate answer").await;
        assert_eq!((id.sequence_number, r.success, r.error_code), (1, false, CalibrateResponse::ERROR_NO_PLATE_SCAN));
        wire.send_scan(Ok(plate(10)));
        next(&out.contours, "the plate's contour").await;
        let id = wire.call_calibrate(2, CalibrateRequest::default());
        let (answered, r) = next(&out.calibrate_answers, "calibrate answer").await;
        assert_eq!(answered, id);
        assert!(r.success && r.error_code == CalibrateResponse::ERROR_NONE, "{}", r.message);
        assert!((r.offset - TRUTH.offset).abs() < 2e-5, "{}", r.message);
        // Latched, and mirrored into the parameters as one set the validator took.
        let cal = next(&out.calibrations, "the new calibration").await;
        assert!(cal.valid && cal.scan_id == 10 && cal.offset == r.offset, "{cal:?}");
        let events = wire.parameter_events.lock().unwrap().clone();
        assert_eq!(events.len(), 1, "one calibration, one parameter event");
        assert!(events[0].iter().any(|p| p.name == "calibration.offset"));
        assert_eq!(shared.state.lock().unwrap().params.calibration.offset, r.offset);
        // Introspection: each request received and each response sent, with contents.
        let kinds: Vec<u8> =
            std::iter::from_fn(|| out.calibrate_events.try_recv().ok()).map(|e| e.info.event_type).collect();
        let (rx, tx) = (ServiceEventInfo::REQUEST_RECEIVED, ServiceEventInfo::RESPONSE_SENT);
        assert_eq!(kinds, [rx, tx, rx, tx], "request received, response sent, twice");
        // A scan now comes back corrected, traced to scan 10.
        wire.send_scan(Ok(lens(11)));
        let c = next(&out.contours, "a lens contour").await;
        assert!(c.calibrated && c.calibration_scan_id == 10);
        // A failed calibration leaves the one in force.
        wire.call_calibrate(3, CalibrateRequest { scan_id: 99, ..CalibrateRequest::default() });
        let (_, r) = next(&out.calibrate_answers, "calibrate answer").await;
        assert_eq!((r.success, r.error_code), (false, CalibrateResponse::ERROR_NO_PLATE_SCAN), "{}", r.message);
        assert_eq!(shared.state.lock().unwrap().params.calibration.offset, cal.offset);
        assert_eq!(wire.parameter_events.lock().unwrap().len(), 1);
        // An unreadable request is counted, not answered.
        wire.send_unreadable_calibrate("a layout no client uses");
        wire.call_calibrate(4, CalibrateRequest { scan_id: 99, ..CalibrateRequest::default() });
        let (id, _) = next(&out.calibrate_answers, "calibrate answer").await;
        assert_eq!(id.sequence_number, 4);
        assert_eq!(shared.state.lock().unwrap().stats.requests_unreadable, 1);
    });
}

/// A plate traced with heights: the axis tilt fitted, mirrored into the parameters through
/// their validator (a covariance asymmetric in its last bits was refused there once).
#[test]
fn a_calibration_with_heights_is_mirrored_whole() {
    let shared = node(Parameters::default());
    let (wire, out) = MemoryWire::new(&shared);
    let s = sim(&PlateSpec::default().at(Vector2::new(5e-4, -3e-4)), 5);
    let mut rng = rand::rngs::StdRng::seed_from_u64(6);
    let opt = HeightOptions { zero: 0.0, tilt: [1.7e-3, 0.0], noise: 5e-6, quantum: 1e-6 };
    let heights = simulate_heights(&s, |_| 0.0, &opt, &mut rng).unwrap();
    let scan = RawScan {
        height_counts: heights.iter().map(|h| (h / 1e-6).round() as i32).collect(),
        ..msg(20, RawScan::TARGET_CALIBRATION_PLATE, &s)
    };
    with_loops(&shared, &wire, async {
        wire.send_scan(Ok(scan));
        next(&out.contours, "the plate's contour").await;
        wire.call_calibrate(1, CalibrateRequest::default());
        let (_, r) = next(&out.calibrate_answers, "calibrate answer").await;
        assert!(r.success, "{}", r.message);
        let events = wire.parameter_events.lock().unwrap().clone();
        assert_eq!(events.len(), 1, "the calibration mirrored into the parameters");
        let tilt = shared.state.lock().unwrap().params.axis_tilt;
        assert!((tilt.angles[0] - 1.7e-3).abs() < 2e-4, "{tilt:?}");
        assert_eq!(tilt.covariance[1], tilt.covariance[2]);
    });
}

#[test]
fn diagnostics_and_type_descriptions_are_served() {
    let shared = node(Parameters::default());
    let (wire, out) = MemoryWire::new(&shared);
    with_loops(&shared, &wire, async {
        let d = next(&out.diagnostics, "diagnostics").await;
        let keys: Vec<&str> = d.status.iter().flat_map(|s| s.values.iter().map(|kv| kv.key.as_str())).collect();
        assert!(keys.contains(&"scans_received"), "{keys:?}");
        let name = "tracer_calib_msgs/msg/RawScan";
        let type_hash = crate::interfaces::type_hash::type_hash(name).unwrap();
        let request = GetTypeDescriptionRequest { type_name: name.into(), type_hash, ..Default::default() };
        let id = wire.call_type_description(1, request);
        let (answered, response) = next(&out.type_description_answers, "type description").await;
        assert_eq!(answered, id);
        assert!(response.successful, "{}", response.failure_reason);
        assert_eq!(response.type_description.type_description.type_name, "tracer_calib_msgs/msg/RawScan");
    });
}

/// A managed node keeping nav2's bond (a heartbeat every 50 ms).
fn managed() -> Shared {
    let params = Parameters { managed: true, bond_heartbeat_period: 0.05, ..Parameters::default() };
    let mut st = NodeState::new("/tracer_calibrator".into(), params);
    st.lifecycle = Some(crate::cell::lifecycle::Lifecycle::new());
    Shared::new(st)
}

fn transition(id: u8, label: &str) -> Call {
    Call::ChangeState(ChangeStateRequest { transition: LifecycleTransition { id, label: label.into() } })
}

async fn change_state(l: &MemoryLifecycle, out: &LifecycleOut, seq: i64, id: u8, label: &str) -> bool {
    let asked = l.call(seq, transition(id, label));
    match next(&out.answers, "change_state answer").await {
        (answered, Reply::ChangeState(r)) if answered == asked => r.success,
        _ => panic!("not the change_state answer"),
    }
}

async fn state_id(l: &MemoryLifecycle, out: &LifecycleOut, seq: i64) -> u8 {
    l.call(seq, Call::GetState);
    match next(&out.answers, "get_state answer").await {
        (_, Reply::GetState(r)) => r.current_state.id,
        _ => panic!("not the get_state answer"),
    }
}

/// The next status the node's end of the bond publishes with `active`.
async fn bond_status(out: &LifecycleOut, active: bool) -> BondStatus {
    loop {
        let s = next(&out.bond, "bond status").await;
        if s.active == active {
            return s;
        }
    }
}

/// A managed node through its lifecycle, with nav2's bond: unconfigured and inactive it
/// takes scans and publishes nothing, refuses `/calibrate` by code; configured, activated,
/// it serves and keeps the bond (formed when the manager's end answers); deactivated, it
/// breaks the bond at once.
#[test]
fn a_managed_node_through_its_lifecycle_keeps_the_bond_while_active() {
    let shared = managed();
    let (wire, out) = MemoryWire::new(&shared);
    let (life, life_out) = MemoryLifecycle::new(true);
    smol::block_on(async {
        let loops = async {
            futures::join!(
                scans::run(&wire, &shared),
                calibrate::run(&wire, &shared),
                lifecycle::run(&life, &shared),
                bond::run(&life, &shared, "tracer_calibrator", Duration::from_millis(50)),
            )
        };
        let test = async {
            assert_eq!(state_id(&life, &life_out, 1).await, CellState::UNCONFIGURED.id);
            wire.send_scan(Ok(lens(1)));
            wire.call_calibrate(1, CalibrateRequest::default());
            let (_, r) = next(&out.calibrate_answers, "calibrate answer").await;
            assert_eq!((r.success, r.error_code), (false, CalibrateResponse::ERROR_NOT_ACTIVE), "{}", r.message);
            assert!(out.contours.is_empty(), "nothing published before active");
            assert_eq!(shared.state.lock().unwrap().stats.scans_received, 1, "the scan taken and counted");

            assert!(change_state(&life, &life_out, 2, 1, "configure").await);
            let steps: Vec<(u8, u8)> = std::iter::from_fn(|| life_out.events.try_recv().ok())
                .map(|e| (e.start_state.id, e.goal_state.id))
                .collect();
            assert_eq!(steps.last().map(|s| s.1), Some(CellState::INACTIVE.id), "{steps:?}");
            assert!(life_out.bond.is_empty(), "no bond before active");

            assert!(change_state(&life, &life_out, 3, 3, "activate").await);
            let mine = bond_status(&life_out, true).await;
            assert_eq!(mine.id, "tracer_calibrator");
            // The lifecycle manager's end answers: formed.
            life.bond_status(BondStatus { instance_id: "manager".into(), ..mine.clone() });
            until(
                || shared.bond.lock().unwrap().as_ref().map(|b| b.state()) == Some(BondState::Alive),
                "the bond formed",
            )
            .await;
            wire.send_scan(Ok(lens(2)));
            assert_eq!(next(&out.contours, "a contour once active").await.scan_id, 2);

            assert!(change_state(&life, &life_out, 4, 4, "deactivate").await);
            let broken = bond_status(&life_out, false).await;
            assert_eq!(broken.instance_id, mine.instance_id, "the same end says it breaks");
            assert_eq!(state_id(&life, &life_out, 5).await, CellState::INACTIVE.id);
        };
        futures::future::select(std::pin::pin!(loops), std::pin::pin!(test)).await;
    });
}
