//! `tracer_calib_msgs`, the node's own interface package (CONTRACT.md). The definition texts
//! are the files in `msg/` that colcon builds the package from, read at compile time.

use super::{Definition, Header, InterfaceName, Point, RosService, ros_message};

/// The node's own interface package.
pub const PACKAGE: &str = "tracer_calib_msgs";

/// `msg/srv/Calibrate.srv`.
const CALIBRATE_SRV: &str = include_str!("../../msg/srv/Calibrate.srv");

ros_message! {
    /// `tracer_calib_msgs/msg/RawScan`: one revolution of the tracer, as its encoders report it.
    #[derive(Debug, Clone, Default, PartialEq)]
    pub struct RawScan(
        tracer_calib_msgs/msg/RawScan,
        Definition::Msg(include_str!("../../msg/msg/RawScan.msg"))
    ) {
        /// `stamp`: start of the revolution; `frame_id`: the tracer's frame.
        pub header: Header,
        /// Set by the tracer, increases by one per revolution.
        pub scan_id: u32,
        /// What was traced: one of the `TARGET_*` constants.
        pub target: u8,
        /// Angle steps in one turn (400 -> 0.9 degrees per step).
        pub steps_per_revolution: u32,
        /// Angle step of each sample, `0 <= step < steps_per_revolution`.
        pub step: Vec<u32>,
        /// Probe encoder reading of each sample; same length as `step`.
        pub counts: Vec<i32>,
    }
}

impl RawScan {
    /// `target`: unknown.
    pub const TARGET_UNKNOWN: u8 = 0;
    /// `target`: the calibration plate.
    pub const TARGET_CALIBRATION_PLATE: u8 = 1;
    /// `target`: a spectacle frame.
    pub const TARGET_FRAME: u8 = 2;
    /// `target`: a lens.
    pub const TARGET_LENS: u8 = 3;
}

ros_message! {
    /// `tracer_calib_msgs/msg/Contour`: a corrected contour in the frame of the rotation axis.
    #[derive(Debug, Clone, Default, PartialEq)]
    pub struct Contour(
        tracer_calib_msgs/msg/Contour,
        Definition::Msg(include_str!("../../msg/msg/Contour.msg"))
    ) {
        /// `stamp` copied from the raw scan; `frame_id`: parameter `output_frame_id`.
        pub header: Header,
        /// Copied from the raw scan.
        pub scan_id: u32,
        /// Copied from the raw scan.
        pub target: u8,
        /// False: no calibration applied yet, points are uncorrected.
        pub calibrated: bool,
        /// One per raw sample, in sample order, metres, `z = 0`.
        pub points: Vec<Point>,
        /// Contour resampled at equal angles about the rotation axis: `radii[k]` at angle
        /// `2*pi*k/radii.len()`, metres; empty if the scan does not go all the way round.
        pub radii: Vec<f64>,
    }
}

ros_message! {
    /// `tracer_calib_msgs/msg/Calibration`: the calibration in force, published latched on
    /// `calibration` so that every contour can be traced to the calibration that made it.
    #[derive(Debug, Clone, Default, PartialEq)]
    pub struct Calibration(
        tracer_calib_msgs/msg/Calibration,
        Definition::Msg(include_str!("../../msg/msg/Calibration.msg"))
    ) {
        /// Stamp: when this calibration was applied; frame_id: `output_frame_id`.
        pub header: Header,
        /// False: no calibration yet (parameters at their defaults).
        pub valid: bool,
        /// `full`, `paper` or `full_scale`.
        pub model: String,
        /// The plate scan it was fitted to; 0 if set by parameters.
        pub scan_id: u32,
        /// Radians.
        pub alpha0: f64,
        /// Metres (d).
        pub offset: f64,
        /// Metres (dL).
        pub delta_l: f64,
        /// Encoder scale k; 1.0 unless fitted.
        pub scale: f64,
        /// Standard uncertainty of `[alpha0, offset, delta_l(, scale)]`; empty if unknown.
        pub stddev: Vec<f64>,
        /// Metres; 0 if unknown.
        pub rms_residual: f64,
        /// Samples that entered the fit; 0 if unknown.
        pub samples_used: u32,
    }
}

ros_message! {
    /// The request of `tracer_calib_msgs/srv/Calibrate`.
    #[derive(Debug, Clone, Default, PartialEq, Eq)]
    pub struct CalibrateRequest(tracer_calib_msgs/srv/Calibrate_Request, Definition::Request(CALIBRATE_SRV)) {
        /// Which calibration-plate scan to use; 0 = the most recent one received.
        pub scan_id: u32,
        /// True: report the fit, but do not apply or persist it.
        pub dry_run: bool,
    }
}

ros_message! {
    /// The response of `tracer_calib_msgs/srv/Calibrate`.
    ///
    /// Its serde field names and order are also those of the offline tool's `--json` output.
    /// The default is a failure with no result (and `scale` 1.0, the scale of no fit).
    #[derive(Debug, Clone, PartialEq)]
    pub struct CalibrateResponse(tracer_calib_msgs/srv/Calibrate_Response, Definition::Response(CALIBRATE_SRV)) {
        /// Whether the fit succeeded (and, unless `dry_run`, was applied).
        pub success: bool,
        /// A one-line summary, or why it failed.
        pub message: String,
        /// Rail angle at step 0, radians, in (-pi/4, pi/4].
        pub alpha0: f64,
        /// Rail offset d from the rotation axis, metres.
        pub offset: f64,
        /// Encoder zero offset along the rail, metres.
        pub delta_l: f64,
        /// Standard uncertainty of `[alpha0, offset, delta_l]`, same units.
        pub stddev: Vec<f64>,
        /// Metres.
        pub rms_residual: f64,
        /// LM iterations used.
        pub iterations: u32,
        /// Samples that entered the fit.
        pub samples_used: u32,
        /// Encoder scale k (true length = counts × meters_per_count × k); 1.0 unless the
        /// model fits it.
        pub scale: f64,
        /// Standard uncertainty of `scale`; 0.0 unless the model fits it.
        pub scale_stddev: f64,
    }
}

impl Default for CalibrateResponse {
    fn default() -> Self {
        CalibrateResponse {
            success: false,
            message: String::new(),
            alpha0: 0.0,
            offset: 0.0,
            delta_l: 0.0,
            stddev: Vec::new(),
            rms_residual: 0.0,
            iterations: 0,
            samples_used: 0,
            scale: 1.0,
            scale_stddev: 0.0,
        }
    }
}

/// The `tracer_calib_msgs/srv/Calibrate` service type: give [`RosService::type_name`] to
/// ros2-client; the DDS topics then carry `tracer_calib_msgs::srv::dds_::Calibrate_Request_`
/// and `..._Response_`.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Calibrate;

impl RosService for Calibrate {
    type Request = CalibrateRequest;
    type Response = CalibrateResponse;
    const NAME: InterfaceName = InterfaceName::srv(PACKAGE, "Calibrate");
}
