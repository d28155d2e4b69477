//! A [`Wire`] in memory, for the node's loops tested in-process: what a test sends goes to
//! the loops' request and scan streams, what the loops publish and answer comes out on
//! channels, and a parameter set runs the node's own validator and set action
//! ([`super::parameters::validate`], [`super::parameters::apply`]), all or none, as
//! ros2-client's parameter server does, each set recorded as one parameter event. A
//! managed node's lifecycle services, transition events and bond likewise
//! ([`MemoryLifecycle`]).
//!
//! Nothing of a middleware is here: discovery, QoS, serialization and loss are what the
//! interop suites test against stock peers.

use std::sync::{Arc, Mutex, OnceLock};

use futures::Stream;
use ros2_client::{Gid, RmwRequestId};
use smol::channel::{Receiver, Sender, unbounded};

use super::lifecycle::{Call, LifecycleWire, Reply};
use super::parameters;
use super::shared::{RosClock, Shared};
use super::wire::Wire;
use crate::cell::NodeState;
use crate::interfaces::{
    BondStatus, CalibrateEvent, CalibrateRequest, CalibrateResponse, Contour, DiagnosticArray,
    GetTypeDescriptionRequest, GetTypeDescriptionResponse, PolygonStamped, RawScan, TransitionEvent,
    tracer_calib_msgs as msgs,
};
use crate::ros::logging::RosoutRecord;

/// One end of a channel the loops read, the other the test's.
struct Inbound<T> {
    tx: Sender<T>,
    rx: Receiver<T>,
}

impl<T> Inbound<T> {
    fn new() -> Self {
        let (tx, rx) = unbounded();
        Inbound { tx, rx }
    }
}

/// What the loops sent out, for the test to read.
pub(super) struct Outbound {
    pub contours: Receiver<Contour>,
    pub polygons: Receiver<PolygonStamped>,
    pub diagnostics: Receiver<DiagnosticArray>,
    pub calibrations: Receiver<msgs::Calibration>,
    pub calibrate_answers: Receiver<(RmwRequestId, CalibrateResponse)>,
    pub calibrate_events: Receiver<CalibrateEvent>,
    pub type_description_answers: Receiver<(RmwRequestId, GetTypeDescriptionResponse)>,
}

/// The node's endpoints in memory.
pub(super) struct MemoryWire {
    raw_scans: Inbound<Result<RawScan, String>>,
    calibrate_requests: Inbound<Result<(RmwRequestId, CalibrateRequest), String>>,
    type_description_requests: Inbound<Result<(RmwRequestId, GetTypeDescriptionRequest), String>>,
    contours: Sender<Contour>,
    polygons: Sender<PolygonStamped>,
    diagnostics: Sender<DiagnosticArray>,
    calibrations: Sender<msgs::Calibration>,
    calibrate_answers: Sender<(RmwRequestId, CalibrateResponse)>,
    calibrate_events: Sender<CalibrateEvent>,
    type_description_answers: Sender<(RmwRequestId, GetTypeDescriptionResponse)>,
    /// The parameter server's side: the cell's state, the calibration's change signal, the clock.
    state: Arc<Mutex<NodeState>>,
    calibration_changed: Sender<()>,
    clock: Arc<OnceLock<RosClock>>,
    /// Each parameter set that went through, as `/parameter_events` would carry it.
    pub parameter_events: Mutex<Vec<Vec<ros2_client::Parameter>>>,
    /// The records the loops logged to `/rosout` through the wire.
    pub rosout: Mutex<Vec<String>>,
    /// How many publishers the raw scan subscription has matched.
    pub raw_scan_publishers: std::sync::atomic::AtomicUsize,
    /// Whether the node is on simulated time.
    pub use_sim_time: bool,
    /// Requests counted unreadable.
    unreadable: std::sync::atomic::AtomicU64,
}

impl MemoryWire {
    /// A wire over `shared`'s state, and what comes out of it.
    pub fn new(shared: &Shared) -> (MemoryWire, Outbound) {
        let (contours, contours_rx) = unbounded();
        let (polygons, polygons_rx) = unbounded();
        let (diagnostics, diagnostics_rx) = unbounded();
        let (calibrations, calibrations_rx) = unbounded();
        let (calibrate_answers, calibrate_answers_rx) = unbounded();
        let (calibrate_events, calibrate_events_rx) = unbounded();
        let (type_description_answers, type_description_answers_rx) = unbounded();
        let wire = MemoryWire {
            raw_scans: Inbound::new(),
            calibrate_requests: Inbound::new(),
            type_description_requests: Inbound::new(),
            contours,
            polygons,
            diagnostics,
            calibrations,
            calibrate_answers,
            calibrate_events,
            type_description_answers,
            state: shared.state.clone(),
            calibration_changed: shared.calibration_changed.clone(),
            clock: shared.clock.clone(),
            parameter_events: Mutex::new(Vec::new()),
            rosout: Mutex::new(Vec::new()),
            raw_scan_publishers: std::sync::atomic::AtomicUsize::new(1),
            use_sim_time: false,
            unreadable: std::sync::atomic::AtomicU64::new(0),
        };
        let out = Outbound {
            contours: contours_rx,
            polygons: polygons_rx,
            diagnostics: diagnostics_rx,
            calibrations: calibrations_rx,
            calibrate_answers: calibrate_answers_rx,
            calibrate_events: calibrate_events_rx,
            type_description_answers: type_description_answers_rx,
        };
        (wire, out)
    }

    /// A raw scan arrives (an `Err`: one that did not decode).
    pub fn send_scan(&self, scan: Result<RawScan, String>) {
        self.raw_scans.tx.try_send(scan).expect("unbounded");
    }

    /// A `calibrate` request arrives, as client request number `seq`.
    pub fn call_calibrate(&self, seq: i64, request: CalibrateRequest) -> RmwRequestId {
        let id = RmwRequestId { writer_gid: Gid::from([7u8; 16]), sequence_number: seq };
        self.calibrate_requests.tx.try_send(Ok((id, request))).expect("unbounded");
        id
    }

    /// A `calibrate` request arrives that no layout reads (the server counts it).
    pub fn send_unreadable_calibrate(&self, err: &str) {
        self.unreadable.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        self.calibrate_requests.tx.try_send(Err(err.to_string())).expect("unbounded");
    }

    /// A `~/get_type_description` request arrives, as client request number `seq`.
    pub fn call_type_description(&self, seq: i64, request: GetTypeDescriptionRequest) -> RmwRequestId {
        let id = RmwRequestId { writer_gid: Gid::from([8u8; 16]), sequence_number: seq };
        self.type_description_requests.tx.try_send(Ok((id, request))).expect("unbounded");
        id
    }

    /// The streams end, as a middleware's do when the node closes: the loops return.
    pub fn close(&self) {
        self.raw_scans.tx.close();
        self.calibrate_requests.tx.close();
        self.type_description_requests.tx.close();
    }
}

async fn send<T>(tx: &Sender<T>, msg: T) -> Result<(), String> {
    tx.send(msg).await.map_err(|_| "nobody reads this wire".to_string())
}

impl Wire for MemoryWire {
    type RequestId = RmwRequestId;

    fn raw_scans(&self) -> impl Stream<Item = Result<RawScan, String>> + '_ {
        self.raw_scans.rx.clone()
    }

    fn publish_contour(&self, msg: Contour) -> impl Future<Output = Result<(), String>> + '_ {
        send(&self.contours, msg)
    }

    fn publish_polygon(&self, msg: PolygonStamped) -> impl Future<Output = Result<(), String>> + '_ {
        send(&self.polygons, msg)
    }

    fn publish_diagnostics(&self, msg: DiagnosticArray) -> impl Future<Output = Result<(), String>> + '_ {
        send(&self.diagnostics, msg)
    }

    fn publish_calibration(&self, msg: msgs::Calibration) -> impl Future<Output = Result<(), String>> + '_ {
        send(&self.calibrations, msg)
    }

    fn calibrate_requests(&self) -> impl Stream<Item = Result<(RmwRequestId, CalibrateRequest), String>> + '_ {
        self.calibrate_requests.rx.clone()
    }

    fn calibrate_unreadable(&self) -> u64 {
        self.unreadable.load(std::sync::atomic::Ordering::Relaxed)
    }

    fn answer_calibrate(
        &self,
        id: RmwRequestId,
        response: CalibrateResponse,
    ) -> impl Future<Output = Result<(), String>> + '_ {
        send(&self.calibrate_answers, (id, response))
    }

    fn publish_calibrate_event(&self, msg: CalibrateEvent) -> impl Future<Output = Result<(), String>> + '_ {
        send(&self.calibrate_events, msg)
    }

    fn type_description_requests(
        &self,
    ) -> impl Stream<Item = Result<(RmwRequestId, GetTypeDescriptionRequest), String>> + '_ {
        self.type_description_requests.rx.clone()
    }

    fn answer_type_description(
        &self,
        id: RmwRequestId,
        response: GetTypeDescriptionResponse,
    ) -> impl Future<Output = Result<(), String>> + '_ {
        send(&self.type_description_answers, (id, response))
    }

    fn types_in_use(&self) -> Vec<String> {
        vec!["tracer_calib_msgs/msg/RawScan".into(), "tracer_calib_msgs/msg/Contour".into()]
    }

    fn set_parameters(&self, params: Vec<ros2_client::Parameter>) -> Result<(), String> {
        // All or none: every value validated before any is applied.
        for p in &params {
            parameters::validate(&self.state, &p.name, &p.value)?;
        }
        for p in &params {
            parameters::apply(&self.state, &self.calibration_changed, &self.clock, &p.name, &p.value)?;
        }
        self.parameter_events.lock().expect("events lock").push(params);
        Ok(())
    }

    fn raw_scan_publishers(&self) -> usize {
        self.raw_scan_publishers.load(std::sync::atomic::Ordering::Relaxed)
    }

    fn rosout(&self, record: &RosoutRecord) {
        self.rosout.lock().expect("rosout lock").push(format!("{record:?}"));
    }

    fn use_sim_time(&self) -> bool {
        self.use_sim_time
    }
}

/// A managed node's lifecycle services, transition events and bond, in memory.
pub(super) struct MemoryLifecycle {
    calls: Inbound<Result<(RmwRequestId, Call), String>>,
    answers: Sender<(RmwRequestId, Reply)>,
    events: Sender<TransitionEvent>,
    /// The bond's topic as the node reads it (`None`: the node keeps no bond).
    bond_in: Option<Inbound<Result<BondStatus, String>>>,
    bond_out: Sender<BondStatus>,
}

/// What the lifecycle side sent out.
pub(super) struct LifecycleOut {
    pub answers: Receiver<(RmwRequestId, Reply)>,
    pub events: Receiver<TransitionEvent>,
    pub bond: Receiver<BondStatus>,
}

impl MemoryLifecycle {
    /// The lifecycle side; with the bond's topic if `bond`.
    pub fn new(bond: bool) -> (MemoryLifecycle, LifecycleOut) {
        let (answers, answers_rx) = unbounded();
        let (events, events_rx) = unbounded();
        let (bond_out, bond_rx) = unbounded();
        let l = MemoryLifecycle { calls: Inbound::new(), answers, events, bond_in: bond.then(Inbound::new), bond_out };
        (l, LifecycleOut { answers: answers_rx, events: events_rx, bond: bond_rx })
    }

    /// A lifecycle request arrives, as client request number `seq`.
    pub fn call(&self, seq: i64, call: Call) -> RmwRequestId {
        let id = RmwRequestId { writer_gid: Gid::from([9u8; 16]), sequence_number: seq };
        self.calls.tx.try_send(Ok((id, call))).expect("unbounded");
        id
    }

    /// A status on the bond's topic (the lifecycle manager's end, or the node's own echo).
    pub fn bond_status(&self, status: BondStatus) {
        self.bond_in.as_ref().expect("a bond topic").tx.try_send(Ok(status)).expect("unbounded");
    }
}

impl LifecycleWire for MemoryLifecycle {
    type RequestId = RmwRequestId;

    fn calls(&self) -> impl Stream<Item = Result<(RmwRequestId, Call), String>> + '_ {
        self.calls.rx.clone()
    }

    fn answer(&self, id: RmwRequestId, reply: Reply) -> impl Future<Output = Result<(), String>> + '_ {
        send(&self.answers, (id, reply))
    }

    fn publish_event(&self, event: TransitionEvent) -> impl Future<Output = Result<(), String>> + '_ {
        send(&self.events, event)
    }

    fn bond_statuses(&self) -> Option<impl Stream<Item = Result<BondStatus, String>> + '_> {
        self.bond_in.as_ref().map(|b| b.rx.clone())
    }

    fn publish_bond(&self, status: BondStatus) -> impl Future<Output = Result<(), String>> + '_ {
        send(&self.bond_out, status)
    }
}
