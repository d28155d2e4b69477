//! `tracer_calib_msgs`, the node's own interface package (docs/CONTRACT.md). The structs are
//! generated (`build.rs`) from the files in `msg/` that colcon builds the package from: each
//! type's `.msg` / `.srv` file is its one declaration.

include!(concat!(env!("OUT_DIR"), "/tracer_calib_msgs.rs"));

/// The node's own interface package.
pub const PACKAGE: &str = "tracer_calib_msgs";

impl RawScan {
    /// A simulated revolution as a tracer driver publishes it: each sample's step, and its
    /// length in counts of `meters_per_count`, rounded; no heights, a default header. For
    /// the tools and tests that feed the cell scans of known shapes.
    pub fn of_simulation(
        scan_id: u32,
        target: u8,
        sim: &crate::engine::simulate::SimScan,
        meters_per_count: f64,
    ) -> RawScan {
        let samples = sim.scan.samples();
        RawScan {
            header: crate::interfaces::Header::default(),
            scan_id,
            target,
            steps_per_revolution: sim.scan.steps_per_rev(),
            step: samples.iter().map(|s| s.step).collect(),
            counts: samples.iter().map(|s| (s.rho / meters_per_count).round() as i32).collect(),
            height_counts: Vec::new(),
        }
    }
}

/// The default is a failure with no result, and `scale` 1.0, the scale of no fit.
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
            tip_radius: 0.0,
            tip_radius_stddev: 0.0,
            covariance: Vec::new(),
            covariance_names: Vec::new(),
            angle_harmonics: Vec::new(),
            angle_coefficients: Vec::new(),
            error_code: CalibrateResponse::ERROR_NONE,
        }
    }
}

/// The default is an empty, uncorrected contour (its calibration stamp zero).
impl Default for Contour {
    fn default() -> Self {
        Contour {
            header: crate::interfaces::Header::default(),
            scan_id: 0,
            target: 0,
            calibrated: false,
            points: Vec::new(),
            radii: Vec::new(),
            circumference: 0.0,
            box_width: 0.0,
            box_height: 0.0,
            effective_diameter: 0.0,
            size_u95: [0.0; 4],
            radii_u95: Vec::new(),
            calibration_stamp: crate::interfaces::Time::ZERO,
            calibration_scan_id: 0,
            circumference_3d: 0.0,
            circumference_3d_u95: 0.0,
            frame_curve: 0.0,
        }
    }
}

/// `tracer_calib_msgs/srv/Calibrate_Event`: one event of the `calibrate` service's
/// introspection, as rosidl generates a service's `_Event` message (Iron and later):
/// published on `<service>/_service_event`; the request or response present (one element)
/// when the introspection shows contents, empty when it shows metadata only. Its type
/// description and hash are rosidl's ([`super::type_hash`]).
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct CalibrateEvent {
    pub info: crate::interfaces::ServiceEventInfo,
    /// At most one.
    pub request: Vec<CalibrateRequest>,
    /// At most one.
    pub response: Vec<CalibrateResponse>,
}

impl ros2_client::Message for CalibrateEvent {}
