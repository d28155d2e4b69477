//! The seam between the node's loops and a middleware: what the loops read from and
//! write to, and nothing of how it travels. [`super::entities::Entities`] implements it
//! once, over either middleware ([`super::backend`]); the loops ([`super::scans`],
//! [`super::calibrate`], [`super::calibration`], [`super::diagnostics`],
//! [`super::type_description`]) are written once, against this trait. In the tests, an
//! in-memory wire (`memory.rs`) runs them in-process.
//!
//! Errors are the middleware's, as text: the loops only count and log them.

use crate::ros::logging::RosoutRecord;
use futures::Stream;

use crate::interfaces::{
    CalibrateEvent, CalibrateRequest, CalibrateResponse, Contour, DiagnosticArray, GetTypeDescriptionRequest,
    GetTypeDescriptionResponse, PolygonStamped, RawScan, tracer_calib_msgs as msgs,
};

/// A middleware's endpoints of the node.
pub(super) trait Wire {
    /// A service request's identity, to answer it with (the client's GID and the
    /// request's sequence number, which its introspection events name).
    type RequestId: std::fmt::Debug + Copy + Into<ros2_client::RmwRequestId>;

    /// The raw scans, as they arrive; an `Err` is a message that did not decode.
    fn raw_scans(&self) -> impl Stream<Item = Result<RawScan, String>> + '_;
    /// Publish a contour.
    fn publish_contour(&self, msg: Contour) -> impl Future<Output = Result<(), String>> + '_;
    /// Publish a contour's polygon.
    fn publish_polygon(&self, msg: PolygonStamped) -> impl Future<Output = Result<(), String>> + '_;
    /// Publish the node's diagnostics.
    fn publish_diagnostics(&self, msg: DiagnosticArray) -> impl Future<Output = Result<(), String>> + '_;
    /// Publish (latched) the calibration in force.
    fn publish_calibration(&self, msg: msgs::Calibration) -> impl Future<Output = Result<(), String>> + '_;

    /// The `calibrate` requests; an `Err` is one that could not be read.
    fn calibrate_requests(&self) -> impl Stream<Item = Result<(Self::RequestId, CalibrateRequest), String>> + '_;
    /// How many `calibrate` requests the middleware could not read, if it counts them.
    fn calibrate_unreadable(&self) -> u64;
    /// Answer a `calibrate` request.
    fn answer_calibrate(
        &self,
        id: Self::RequestId,
        response: CalibrateResponse,
    ) -> impl Future<Output = Result<(), String>> + '_;
    /// Publish an event of the `calibrate` service's introspection
    /// (`calibrate/_service_event`).
    fn publish_calibrate_event(&self, msg: CalibrateEvent) -> impl Future<Output = Result<(), String>> + '_;

    /// The `~/get_type_description` requests.
    fn type_description_requests(
        &self,
    ) -> impl Stream<Item = Result<(Self::RequestId, GetTypeDescriptionRequest), String>> + '_;
    /// Answer a `~/get_type_description` request.
    fn answer_type_description(
        &self,
        id: Self::RequestId,
        response: GetTypeDescriptionResponse,
    ) -> impl Future<Output = Result<(), String>> + '_;
    /// The ROS types of the node's endpoints (`pkg/msg/Name`), which it describes.
    fn types_in_use(&self) -> Vec<String>;

    /// Set several of the node's ROS parameters from within as one change, all or none
    /// (their validator and set action run as for a remote set): one
    /// `/parameter_events` message, as a remote `set_parameters_atomically` makes.
    fn set_parameters(&self, params: Vec<ros2_client::Parameter>) -> Result<(), String>;
    /// How many publishers the raw scan subscription has matched (the tracer driver).
    fn raw_scan_publishers(&self) -> usize;
    /// A record on `/rosout`, under the node's rcl logger name.
    fn rosout(&self, record: &RosoutRecord);
    /// Whether the node's clock is simulated (`use_sim_time`).
    fn use_sim_time(&self) -> bool;
}
