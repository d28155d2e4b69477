//! The node's parameters: names, types, defaults, validation, and the params file.
//!
//! The names and defaults are the contract's (`docs/CONTRACT.md`); every parameter is
//! persisted. [`Parameters`] is the typed view the node and the offline tool share;
//! [`file`](mod@file) reads and writes ROS 2 parameter files; [`value`] is the untyped value.

pub mod edit;
pub mod file;
pub mod persist;
pub mod spec;
mod tree;
pub mod value;

pub use file::{ParamsFile, ParamsFileError};
pub use value::ParamValue;

use nalgebra::DMatrix;

use crate::engine::angle::{AngleError, HarmonicOrders};
use crate::engine::calibrate::{Options as CalibrationOptions, covariance_names, layout, named_covariance_from_values};
use crate::engine::height::AxisTilt;
use crate::engine::stylus::PLAIN_BORE;
use crate::engine::{Groove, ModelKind, Mounting, PlateSpec, RingSpec};

/// The contract's parameter names.
pub mod names {
    pub const ALPHA0: &str = "calibration.alpha0";
    pub const OFFSET: &str = "calibration.offset";
    pub const DELTA_L: &str = "calibration.delta_l";
    pub const SCALE: &str = "calibration.scale";
    pub const VALID: &str = "calibration.valid";
    pub const COVARIANCE: &str = "calibration.covariance";
    pub const TIP_RADIUS: &str = "stylus.tip_radius";
    pub const PLATE_SIDE: &str = "plate.side";
    pub const CORNER_RADIUS: &str = "plate.corner_radius";
    pub const SIDE_UNCERTAINTY: &str = "plate.side_uncertainty";
    pub const RING_DIAMETER: &str = "ring.diameter";
    pub const DIAMETER_UNCERTAINTY: &str = "ring.diameter_uncertainty";
    pub const METERS_PER_COUNT: &str = "encoder.meters_per_count";
    pub const MODEL: &str = "model";
    pub const OUTPUT_FRAME_ID: &str = "output_frame_id";
    pub const RESAMPLE_POINTS: &str = "resample_points";
    pub const PARAMS_FILE: &str = "params_file";
    pub const HISTORY_FILE: &str = "history_file";
    pub const MAX_AGE_DAYS: &str = "calibration.max_age_days";
    pub const DRIFT_WARN_SIGMA: &str = "calibration.drift_warn_sigma";
    pub const USE_SIM_TIME: &str = "use_sim_time";
    pub const MANAGED: &str = "managed";
    pub const HARDWARE_ID: &str = "hardware_id";
    pub const SCAN_TIMEOUT: &str = "driver.scan_timeout";
    pub const INTROSPECTION: &str = "calibrate.introspection";
    pub const BOND_HEARTBEAT_PERIOD: &str = "bond_heartbeat_period";
    pub const LACK_OF_FIT_ALPHA: &str = "calibration.lack_of_fit_alpha";
    pub const ANGLE_HARMONICS: &str = "calibration.angle_harmonics";
    pub const ANGLE_COEFFICIENTS: &str = "calibration.angle_coefficients";
    pub const COVARIANCE_NAMES: &str = "calibration.covariance_names";
    pub const TIP_RADIUS_UNCERTAINTY: &str = "stylus.tip_radius_uncertainty";
    pub const CORNER_RADIUS_UNCERTAINTY: &str = "plate.corner_radius_uncertainty";
    pub const SEATING_UNCERTAINTY: &str = "plate.seating_uncertainty";
    pub const NOISE_LAG1: &str = "calibration.noise_lag1";
    pub const REPRODUCIBILITY: &str = "size.reproducibility";
    pub const FRAME_GROOVE_ANGLE: &str = "frame.groove_angle";
    pub const FRAME_GROOVE_ANGLE_UNCERTAINTY: &str = "frame.groove_angle_uncertainty";
    pub const RING_GROOVE_ANGLE: &str = "ring.groove_angle";
    pub const HEIGHT_METERS_PER_COUNT: &str = "encoder.height_meters_per_count";
    pub const AXIS_TILT: &str = "calibration.axis_tilt";
    pub const AXIS_TILT_COVARIANCE: &str = "calibration.axis_tilt_covariance";
    pub const HEIGHT_ZERO: &str = "calibration.height_zero";
    /// Every parameter, in the order they are written.
    pub const ALL: [&str; 42] = [
        ALPHA0,
        OFFSET,
        DELTA_L,
        SCALE,
        VALID,
        COVARIANCE,
        TIP_RADIUS,
        PLATE_SIDE,
        CORNER_RADIUS,
        SIDE_UNCERTAINTY,
        RING_DIAMETER,
        DIAMETER_UNCERTAINTY,
        METERS_PER_COUNT,
        MODEL,
        OUTPUT_FRAME_ID,
        RESAMPLE_POINTS,
        PARAMS_FILE,
        HISTORY_FILE,
        MAX_AGE_DAYS,
        DRIFT_WARN_SIGMA,
        USE_SIM_TIME,
        MANAGED,
        HARDWARE_ID,
        SCAN_TIMEOUT,
        INTROSPECTION,
        BOND_HEARTBEAT_PERIOD,
        LACK_OF_FIT_ALPHA,
        ANGLE_HARMONICS,
        ANGLE_COEFFICIENTS,
        COVARIANCE_NAMES,
        TIP_RADIUS_UNCERTAINTY,
        CORNER_RADIUS_UNCERTAINTY,
        SEATING_UNCERTAINTY,
        NOISE_LAG1,
        REPRODUCIBILITY,
        FRAME_GROOVE_ANGLE,
        FRAME_GROOVE_ANGLE_UNCERTAINTY,
        RING_GROOVE_ANGLE,
        HEIGHT_METERS_PER_COUNT,
        AXIS_TILT,
        AXIS_TILT_COVARIANCE,
        HEIGHT_ZERO,
    ];

    /// The parameters that make up the calibration in force: setting one changes it.
    pub const CALIBRATION_IN_FORCE: [&str; 13] = [
        ALPHA0,
        OFFSET,
        DELTA_L,
        SCALE,
        VALID,
        COVARIANCE,
        TIP_RADIUS,
        ANGLE_COEFFICIENTS,
        COVARIANCE_NAMES,
        NOISE_LAG1,
        AXIS_TILT,
        AXIS_TILT_COVARIANCE,
        HEIGHT_ZERO,
    ];
}

/// Largest `resample_points` accepted.
pub const MAX_RESAMPLE_POINTS: i64 = 100_000;

/// The node's parameters, typed.
#[derive(Debug, Clone, PartialEq)]
pub struct Parameters {
    /// The calibration in force (meaningful when `calibration_valid`).
    pub calibration: Mounting,
    pub calibration_valid: bool,
    /// The covariance of the calibration in force: empty (unknown), or the `n²` values of
    /// the named covariance over `covariance_names` (the five of
    /// [`crate::engine::calibrate::Covariance`], then the angle coefficients), row-major.
    pub covariance: Vec<f64>,
    /// The names of the covariance's rows ([`crate::engine::calibrate::covariance_names`]);
    /// empty: the five.
    pub covariance_names: Vec<String>,
    /// The orders of the turntable's angle error fitted by `/calibrate` and read by
    /// `angle_coefficients`.
    pub angle_harmonics: HarmonicOrders,
    /// The angle error of the calibration in force, two an order of `angle_harmonics`
    /// (`[c_h₁, s_h₁, ...]`, rad); empty: none.
    pub angle_coefficients: Vec<f64>,
    /// The stylus tip's radius in force, metres (fitted by the tip models, else known).
    pub tip_radius: f64,
    /// Standard uncertainty of a tip radius entered rather than fitted, metres.
    pub tip_radius_uncertainty: f64,
    /// Standard uncertainty of `plate.corner_radius` from its certificate, metres.
    pub corner_radius_uncertainty: f64,
    /// Standard uncertainty of the plate's seating angle against the frame holder's datum, rad.
    pub seating_uncertainty: f64,
    /// The calibration in force: the lag-1 correlation of the noise along the trace it
    /// measured on the plate (every trace's size uncertainty takes it).
    pub noise_lag1: f64,
    /// Standard uncertainty of a radius between repeated traces beyond their noise, metres.
    pub reproducibility: f64,
    pub plate: PlateSpec,
    /// Standard uncertainty of `plate.side` from its certificate, metres.
    pub plate_side_uncertainty: f64,
    /// The ring gauge's certified inner diameter, metres; 0 = none.
    pub ring_diameter: f64,
    /// Standard uncertainty of `ring.diameter` from its certificate, metres.
    pub ring_diameter_uncertainty: f64,
    /// Included angle of the ring gauge's V-groove, rad; π a plain bore.
    pub ring_groove_angle: f64,
    /// The frames' V-groove as the cell assumes it: its included angle and that angle's
    /// standard uncertainty, rad (π, 0: a plain bore, exactly).
    pub frame_groove: Groove,
    pub meters_per_count: f64,
    /// The height encoder's resolution (m per count), for scans with `height_counts`.
    pub height_meters_per_count: f64,
    /// The calibration in force: the turntable axis's tilt against the frame holder's
    /// plane and that plane's height, fitted by `/calibrate` from the flat artefacts'
    /// heights ([`crate::engine::height`]).
    pub axis_tilt: AxisTilt,
    pub model: ModelKind,
    pub output_frame_id: String,
    pub resample_points: usize,
    /// Where parameters are persisted; empty = not persisted.
    pub params_file: String,
    /// Where applied calibrations are appended; empty = nowhere. The node's default is
    /// beside `params_file` ([`crate::records::file::default_path`]).
    pub history_file: String,
    /// /diagnostics warns when the calibration in force is older; 0 = no limit.
    pub max_age_days: f64,
    /// /diagnostics warns when a calibration moved a parameter by more than this many
    /// combined standard uncertainties from the one before; 0 = never.
    pub drift_warn_sigma: f64,
    /// Significance level of the harmonic lack-of-fit test of the plate's residuals: a
    /// calibration whose residuals show structure at this level is refused; 0 = no test.
    pub lack_of_fit_alpha: f64,
    /// The node's clock follows `/clock`.
    pub use_sim_time: bool,
    /// A lifecycle (managed) node; read at start-up.
    pub managed: bool,
    /// The tracer's serial, /diagnostics' `hardware_id`; empty: `output_frame_id`.
    pub hardware_id: String,
    /// /diagnostics warns when no scan came for this long (s); 0 = never.
    pub scan_timeout: f64,
    /// What the `calibrate` service's introspection shows.
    pub introspection: Introspection,
    /// A managed node's bond with nav2's lifecycle manager: its heartbeat period (s) while
    /// active; 0 = no bond. Read at start-up (nav2_util::LifecycleNode's parameter).
    pub bond_heartbeat_period: f64,
}

/// What a service's introspection shows on `<service>/_service_event`, as rclcpp's
/// `configure_introspection` states: nothing, each request and response's metadata
/// (client, sequence number, time), or their contents too.
///
/// `off` is also `disabled` (rclcpp's demo's word): YAML, which `ros2 param set`, `-p` and
/// params files read values with, types a bare `off` as the boolean false. In a params file
/// and with `-p`, that false is taken as `off`; a running node's parameter keeps its
/// string type (`ros2 param set NODE calibrate.introspection disabled`, or `"'off'"`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Introspection {
    #[default]
    Off,
    Metadata,
    Contents,
}

impl Introspection {
    pub fn as_str(self) -> &'static str {
        match self {
            Introspection::Off => "off",
            Introspection::Metadata => "metadata",
            Introspection::Contents => "contents",
        }
    }
}

/// A word that is none of the [`Introspection`] states (its `FromStr`): the word given.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("'{0}' is not one of: off (or disabled), metadata, contents")]
pub struct UnknownIntrospection(pub String);

impl std::str::FromStr for Introspection {
    type Err = UnknownIntrospection;
    fn from_str(s: &str) -> Result<Self, UnknownIntrospection> {
        match s {
            "off" | "disabled" => Ok(Introspection::Off),
            "metadata" => Ok(Introspection::Metadata),
            "contents" => Ok(Introspection::Contents),
            other => Err(UnknownIntrospection(other.to_string())),
        }
    }
}

impl Default for Parameters {
    fn default() -> Self {
        Parameters {
            calibration: Mounting::IDEAL,
            calibration_valid: false,
            covariance: Vec::new(),
            covariance_names: Vec::new(),
            angle_harmonics: HarmonicOrders::NONE,
            angle_coefficients: Vec::new(),
            tip_radius: 0.0,
            tip_radius_uncertainty: 0.0,
            corner_radius_uncertainty: 0.0,
            seating_uncertainty: 0.0,
            noise_lag1: 0.0,
            reproducibility: 0.0,
            plate: PlateSpec::default(),
            plate_side_uncertainty: 0.0,
            ring_diameter: 0.0,
            ring_diameter_uncertainty: 0.0,
            ring_groove_angle: PLAIN_BORE,
            frame_groove: Groove::default(),
            meters_per_count: 1.0e-6,
            height_meters_per_count: 1.0e-6,
            axis_tilt: AxisTilt::NONE,
            model: ModelKind::Full,
            output_frame_id: "tracer_axis".into(),
            resample_points: 400,
            params_file: String::new(),
            history_file: String::new(),
            max_age_days: 0.0,
            drift_warn_sigma: 10.0,
            lack_of_fit_alpha: 0.001,
            use_sim_time: false,
            managed: false,
            hardware_id: String::new(),
            scan_timeout: 0.0,
            introspection: Introspection::Off,
            bond_heartbeat_period: 0.1,
        }
    }
}

/// Why a parameter was not set ([`Parameters::set`]).
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum ParamError {
    /// No parameter of this node has that name.
    #[error("'{0}' is not a parameter of this node")]
    Unknown(String),
    /// A value of another type than the parameter's.
    #[error("expected {expected}, got {got}")]
    WrongType {
        /// The parameter's type, in words (`a double`).
        expected: String,
        /// The value given, with its type (`integer '3'`).
        got: String,
    },
    /// A value of the right type that the parameter does not take (out of its range, not
    /// one of its values, inconsistent with another parameter): why.
    #[error("{0}")]
    Invalid(String),
}

impl Parameters {
    /// Every parameter as a name and a value, in [`names::ALL`] order.
    pub fn to_list(&self) -> Vec<(String, ParamValue)> {
        names::ALL.iter().map(|n| (n.to_string(), self.get(n).expect("every name has a value"))).collect()
    }

    /// The value of one parameter.
    pub fn get(&self, name: &str) -> Option<ParamValue> {
        use ParamValue::*;
        Some(match name {
            names::ALPHA0 => Double(self.calibration.alpha0),
            names::OFFSET => Double(self.calibration.offset),
            names::DELTA_L => Double(self.calibration.delta_l),
            names::SCALE => Double(self.calibration.scale),
            names::VALID => Bool(self.calibration_valid),
            names::COVARIANCE => DoubleArray(self.covariance.clone()),
            names::TIP_RADIUS => Double(self.tip_radius),
            names::PLATE_SIDE => Double(self.plate.side),
            names::CORNER_RADIUS => Double(self.plate.corner_radius),
            names::SIDE_UNCERTAINTY => Double(self.plate_side_uncertainty),
            names::RING_DIAMETER => Double(self.ring_diameter),
            names::DIAMETER_UNCERTAINTY => Double(self.ring_diameter_uncertainty),
            names::METERS_PER_COUNT => Double(self.meters_per_count),
            names::MODEL => String(self.model.as_str().into()),
            names::OUTPUT_FRAME_ID => String(self.output_frame_id.clone()),
            names::RESAMPLE_POINTS => Integer(self.resample_points as i64),
            names::PARAMS_FILE => String(self.params_file.clone()),
            names::HISTORY_FILE => String(self.history_file.clone()),
            names::MAX_AGE_DAYS => Double(self.max_age_days),
            names::DRIFT_WARN_SIGMA => Double(self.drift_warn_sigma),
            names::LACK_OF_FIT_ALPHA => Double(self.lack_of_fit_alpha),
            names::USE_SIM_TIME => Bool(self.use_sim_time),
            names::MANAGED => Bool(self.managed),
            names::HARDWARE_ID => String(self.hardware_id.clone()),
            names::SCAN_TIMEOUT => Double(self.scan_timeout),
            names::INTROSPECTION => String(self.introspection.as_str().into()),
            names::BOND_HEARTBEAT_PERIOD => Double(self.bond_heartbeat_period),
            names::ANGLE_HARMONICS => IntegerArray(self.angle_harmonics.to_vec()),
            names::ANGLE_COEFFICIENTS => DoubleArray(self.angle_coefficients.clone()),
            names::COVARIANCE_NAMES => StringArray(self.covariance_names.clone()),
            names::TIP_RADIUS_UNCERTAINTY => Double(self.tip_radius_uncertainty),
            names::CORNER_RADIUS_UNCERTAINTY => Double(self.corner_radius_uncertainty),
            names::SEATING_UNCERTAINTY => Double(self.seating_uncertainty),
            names::NOISE_LAG1 => Double(self.noise_lag1),
            names::REPRODUCIBILITY => Double(self.reproducibility),
            names::FRAME_GROOVE_ANGLE => Double(self.frame_groove.angle),
            names::FRAME_GROOVE_ANGLE_UNCERTAINTY => Double(self.frame_groove.uncertainty),
            names::RING_GROOVE_ANGLE => Double(self.ring_groove_angle),
            names::HEIGHT_METERS_PER_COUNT => Double(self.height_meters_per_count),
            names::AXIS_TILT => DoubleArray(self.axis_tilt.angles.to_vec()),
            names::AXIS_TILT_COVARIANCE => DoubleArray(self.axis_tilt.covariance.to_vec()),
            names::HEIGHT_ZERO => Double(self.axis_tilt.height_zero),
            _ => return None,
        })
    }

    /// Is `name` one of this node's parameters?
    pub fn is_known(name: &str) -> bool {
        names::ALL.contains(&name)
    }

    /// Set one parameter, checking its type and its declaration's bound
    /// ([`spec::SPECS`]) and that the calibration in force still reads
    /// ([`Self::check_calibration`]); the error says what is wrong. Unknown names are an
    /// error here; the caller decides whether to ignore them.
    pub fn set(&mut self, name: &str, value: &ParamValue) -> Result<(), ParamError> {
        let mut next = self.clone();
        next.set_unchecked(name, value)?;
        next.check_calibration()?;
        *self = next;
        Ok(())
    }

    /// Set several parameters in turn, then check that the calibration in force reads: a
    /// file or a command line may change the angle's orders and coefficients together.
    pub fn set_all<'a>(
        &mut self,
        values: impl IntoIterator<Item = (&'a str, &'a ParamValue)>,
    ) -> Result<(), ParamError> {
        let mut next = self.clone();
        for (name, value) in values {
            next.set_unchecked(name, value).map_err(|e| match e {
                ParamError::Unknown(_) => e,
                e => ParamError::Invalid(format!("{name}: {e}")),
            })?;
        }
        next.check_calibration()?;
        *self = next;
        Ok(())
    }

    /// That the parameters of the calibration in force read together: the angle's
    /// coefficients two an order of `calibration.angle_harmonics` (or none), the
    /// covariance's names those of the five and those coefficients (or none), and its
    /// values `n²` over them.
    pub fn check_calibration(&self) -> Result<(), ParamError> {
        let orders = self.angle_harmonics;
        if !self.angle_coefficients.is_empty() {
            AngleError::new(orders, self.angle_coefficients.clone()).map_err(|e| {
                ParamError::Invalid(format!(
                    "{} and {} do not read together: {e} (set both at once, or set {} to [] first and calibrate again)",
                    names::ANGLE_HARMONICS,
                    names::ANGLE_COEFFICIENTS,
                    names::ANGLE_COEFFICIENTS
                ))
            })?;
        }
        let n = if self.covariance_names.is_empty() { 5 } else { self.covariance_names.len() };
        if !self.covariance_names.is_empty() {
            // With no coefficients in force the angle's names may stay (the rows are then
            // not read), so that clearing the coefficients alone is a set that reads.
            let five = covariance_names(HarmonicOrders::NONE);
            let want = covariance_names(orders);
            let names_ok = if self.angle_coefficients.is_empty() {
                self.covariance_names.len() >= 5 && self.covariance_names[..5] == five[..]
            } else {
                self.covariance_names == want
            };
            if !names_ok {
                return Err(ParamError::Invalid(format!(
                    "{} must be [{}] (the five, then the angle coefficients in force), got [{}]",
                    names::COVARIANCE_NAMES,
                    want.join(", "),
                    self.covariance_names.join(", ")
                )));
            }
        }
        if !self.covariance.is_empty() && self.covariance.len() != n * n {
            return Err(ParamError::Invalid(format!(
                "{} holds {} values where {} names ask for {}",
                names::COVARIANCE,
                self.covariance.len(),
                n,
                n * n
            )));
        }
        Ok(())
    }

    /// Set one parameter without [`Self::check_calibration`]: one of several set together,
    /// checked after the last ([`Self::set_all`]).
    pub fn set_unchecked(&mut self, name: &str, value: &ParamValue) -> Result<(), ParamError> {
        let spec = spec::spec(name).ok_or_else(|| ParamError::Unknown(name.to_string()))?;
        let mut next = self.clone();
        let wrong = |expected: &str, v: &ParamValue| ParamError::WrongType {
            expected: expected.to_string(),
            got: format!("{} '{}'", v.type_name(), v),
        };
        let double = |v: &ParamValue| {
            v.as_f64()
                .ok_or_else(|| wrong("a double", v))
                .and_then(|x| spec.check_f64(x).map_err(|e| ParamError::Invalid(e.to_string())))
        };
        let integer = |v: &ParamValue| match v {
            ParamValue::Integer(i) => spec.check_i64(*i).map_err(|e| ParamError::Invalid(e.to_string())),
            v => Err(wrong("an integer", v)),
        };
        let boolean = |v: &ParamValue| match v {
            ParamValue::Bool(b) => Ok(*b),
            v => Err(wrong("a bool", v)),
        };
        let string = |v: &ParamValue| match v {
            ParamValue::String(s) => Ok(s.clone()),
            v => Err(wrong("a string", v)),
        };
        // A string naming one of a few values: a wrong type is told with what they are.
        let one_of = |v: &ParamValue| string(v).map_err(|_| wrong(&format!("a string ({})", spec.constraints), v));
        // `[]` (what `ros2 param dump` writes for it) has no element type: any empty list
        // is the empty covariance; whole numbers are doubles, as for a double parameter.
        let covariance = |v: &ParamValue| {
            let c: Vec<f64> = match v {
                v if v.is_empty_array() => return Ok(Vec::new()),
                ParamValue::IntegerArray(c) => c.iter().map(|&i| i as f64).collect(),
                ParamValue::DoubleArray(c) => c.clone(),
                v => return Err(wrong("a double array", v)),
            };
            named_covariance_from_values(&c).map(|_| c).map_err(|e| ParamError::Invalid(e.to_string()))
        };
        let integers = |v: &ParamValue| match v {
            v if v.is_empty_array() => Ok(Vec::new()),
            ParamValue::IntegerArray(c) => Ok(c.clone()),
            v => Err(wrong("an integer array", v)),
        };
        let doubles = |v: &ParamValue| match v {
            v if v.is_empty_array() => Ok(Vec::new()),
            ParamValue::IntegerArray(c) => Ok(c.iter().map(|&i| i as f64).collect()),
            ParamValue::DoubleArray(c) if c.iter().all(|x| x.is_finite()) => Ok(c.clone()),
            ParamValue::DoubleArray(_) => Err(ParamError::Invalid("every value must be a finite number".into())),
            v => Err(wrong("a double array", v)),
        };
        let strings = |v: &ParamValue| match v {
            v if v.is_empty_array() => Ok(Vec::new()),
            ParamValue::StringArray(c) => Ok(c.clone()),
            v => Err(wrong("a string array", v)),
        };
        // Empty (none: zeros) or exactly `N` values.
        fn fixed<const N: usize>(v: Vec<f64>, what: &str) -> Result<[f64; N], ParamError> {
            if v.is_empty() {
                return Ok([0.0; N]);
            }
            v.try_into().map_err(|v: Vec<f64>| {
                ParamError::Invalid(format!("expected {what} (or none), got {} values", v.len()))
            })
        }
        match name {
            names::ALPHA0 => next.calibration.alpha0 = double(value)?,
            names::OFFSET => next.calibration.offset = double(value)?,
            names::DELTA_L => next.calibration.delta_l = double(value)?,
            names::SCALE => next.calibration.scale = double(value)?,
            names::VALID => next.calibration_valid = boolean(value)?,
            names::COVARIANCE => next.covariance = covariance(value)?,
            names::TIP_RADIUS => next.tip_radius = double(value)?,
            names::PLATE_SIDE => next.plate.side = double(value)?,
            names::CORNER_RADIUS => next.plate.corner_radius = double(value)?,
            names::SIDE_UNCERTAINTY => next.plate_side_uncertainty = double(value)?,
            names::RING_DIAMETER => next.ring_diameter = double(value)?,
            names::DIAMETER_UNCERTAINTY => next.ring_diameter_uncertainty = double(value)?,
            names::METERS_PER_COUNT => next.meters_per_count = double(value)?,
            names::MODEL => {
                next.model = one_of(value)?.parse::<ModelKind>().map_err(|e| ParamError::Invalid(e.to_string()))?
            }
            names::OUTPUT_FRAME_ID => next.output_frame_id = string(value)?,
            names::RESAMPLE_POINTS => next.resample_points = integer(value)? as usize,
            names::PARAMS_FILE => next.params_file = string(value)?,
            names::HISTORY_FILE => next.history_file = string(value)?,
            names::MAX_AGE_DAYS => next.max_age_days = double(value)?,
            names::DRIFT_WARN_SIGMA => next.drift_warn_sigma = double(value)?,
            names::LACK_OF_FIT_ALPHA => next.lack_of_fit_alpha = double(value)?,
            names::USE_SIM_TIME => next.use_sim_time = boolean(value)?,
            names::MANAGED => next.managed = boolean(value)?,
            names::HARDWARE_ID => next.hardware_id = string(value)?,
            names::SCAN_TIMEOUT => next.scan_timeout = double(value)?,
            names::INTROSPECTION if *value == ParamValue::Bool(false) => next.introspection = Introspection::Off,
            names::INTROSPECTION => {
                next.introspection =
                    one_of(value)?.parse::<Introspection>().map_err(|e| ParamError::Invalid(e.to_string()))?
            }
            names::BOND_HEARTBEAT_PERIOD => next.bond_heartbeat_period = double(value)?,
            names::TIP_RADIUS_UNCERTAINTY => next.tip_radius_uncertainty = double(value)?,
            names::CORNER_RADIUS_UNCERTAINTY => next.corner_radius_uncertainty = double(value)?,
            names::SEATING_UNCERTAINTY => next.seating_uncertainty = double(value)?,
            names::NOISE_LAG1 => next.noise_lag1 = double(value)?,
            names::REPRODUCIBILITY => next.reproducibility = double(value)?,
            names::FRAME_GROOVE_ANGLE => next.frame_groove.angle = double(value)?,
            names::FRAME_GROOVE_ANGLE_UNCERTAINTY => next.frame_groove.uncertainty = double(value)?,
            names::RING_GROOVE_ANGLE => next.ring_groove_angle = double(value)?,
            names::HEIGHT_METERS_PER_COUNT => next.height_meters_per_count = double(value)?,
            names::AXIS_TILT => next.axis_tilt.angles = fixed(doubles(value)?, "two angles, [tau_x, tau_y]")?,
            names::AXIS_TILT_COVARIANCE => {
                let c: [f64; 4] = fixed(doubles(value)?, "four values, the angles' 2 x 2 covariance row-major")?;
                // Symmetric to 1e-9 of the variances' scale, and taken symmetric: an earlier node
                // wrote covariances whose off-diagonal entries differed in the last bits (and
                // then refused its own file at the next start).
                let asymmetric = (c[1] - c[2]).abs() > 1e-9 * (c[0] * c[3]).sqrt();
                let off = 0.5 * (c[1] + c[2]);
                if c[0] < 0.0 || c[3] < 0.0 || asymmetric || off * off > c[0] * c[3] * (1.0 + 1e-9) {
                    return Err(ParamError::Invalid(
                        "not a covariance: symmetric, no negative variance, |correlation| <= 1".into(),
                    ));
                }
                next.axis_tilt.covariance = [c[0], off, off, c[3]]
            }
            names::HEIGHT_ZERO => next.axis_tilt.height_zero = double(value)?,
            names::ANGLE_HARMONICS => {
                next.angle_harmonics =
                    HarmonicOrders::new(&integers(value)?).map_err(|e| ParamError::Invalid(e.to_string()))?
            }
            names::ANGLE_COEFFICIENTS => next.angle_coefficients = doubles(value)?,
            names::COVARIANCE_NAMES => next.covariance_names = strings(value)?,
            _ => unreachable!("every declared name is handled"),
        }
        if matches!(name, names::PLATE_SIDE | names::CORNER_RADIUS) {
            next.plate.validate().map_err(|e| ParamError::Invalid(e.to_string()))?;
        }
        *self = next;
        Ok(())
    }

    /// Apply the entries of a params file that match node `fqn`, in file order.
    /// Unknown names are returned (they may be meant for other nodes, like
    /// `use_sim_time`); a known name with a bad value is an error naming file, line
    /// and key, and leaves `self` unchanged.
    pub fn apply_file(&mut self, file: &ParamsFile, fqn: &str, path: &str) -> Result<Vec<String>, ParamsFileError> {
        let mut next = self.clone();
        let mut unknown = Vec::new();
        for e in file.entries_for(fqn) {
            if !Self::is_known(&e.name) {
                unknown.push(e.name.clone());
                continue;
            }
            next.set_unchecked(&e.name, &e.value)
                .map_err(|m| ParamsFileError::new(path, Some(e.line), Some(&e.name), m.to_string()))?;
        }
        next.check_calibration().map_err(|m| ParamsFileError::new(path, None, None, m.to_string()))?;
        *self = next;
        Ok(unknown)
    }

    /// The calibration in force, if there is one.
    pub fn calibration_in_force(&self) -> Option<Mounting> {
        self.calibration_valid.then_some(self.calibration)
    }

    /// The turntable's angle error in force ([`crate::engine::angle`]): none without a
    /// calibration in force or coefficients.
    pub fn angle_in_force(&self) -> AngleError {
        if !self.calibration_valid || self.angle_coefficients.is_empty() {
            return AngleError::NONE;
        }
        AngleError::new(self.angle_harmonics, self.angle_coefficients.clone()).unwrap_or(AngleError::NONE)
    }

    /// The axis's tilt in force ([`crate::engine::height`]): none without a calibration
    /// in force.
    pub fn axis_tilt_in_force(&self) -> AxisTilt {
        if self.calibration_valid { self.axis_tilt } else { AxisTilt::NONE }
    }

    /// The named covariance of the calibration in force, when it is known.
    pub fn covariance_in_force(&self) -> Option<DMatrix<f64>> {
        self.calibration_valid.then(|| named_covariance_from_values(&self.covariance).ok()).flatten()
    }

    /// How a calibration is fitted with these parameters: the model, and the encoder
    /// scale and tip radius in force (for the models that do not fit them).
    pub fn calibration_options(&self) -> CalibrationOptions {
        CalibrationOptions {
            model: self.model,
            scale: self.calibration.scale,
            tip_radius: self.tip_radius,
            plate_side_uncertainty: self.plate_side_uncertainty,
            ring_diameter_uncertainty: self.ring_diameter_uncertainty,
            corner_radius_uncertainty: self.corner_radius_uncertainty,
            tip_radius_uncertainty: self.carried(self.tip_radius_uncertainty, layout::TIP_RADIUS),
            scale_uncertainty: self.carried(0.0, layout::SCALE),
            seating_uncertainty: self.seating_uncertainty,
            lack_of_fit_alpha: self.lack_of_fit_alpha,
            angle_harmonics: self.angle_harmonics,
            ..CalibrationOptions::default()
        }
    }

    /// The standard uncertainty of an input a model may take as known (the tip radius,
    /// the scale: its row of the covariance): `given` when it is set, else what the
    /// calibration in force states of it (an earlier fit of it, carried), else 0.
    fn carried(&self, given: f64, row: usize) -> f64 {
        if given > 0.0 {
            return given;
        }
        self.covariance_in_force().filter(|c| c.nrows() > row).map_or(0.0, |c| c[(row, row)].max(0.0).sqrt())
    }

    /// How the noise of every trace is taken (`engine::size::TraceNoise`): the
    /// calibration's correlation, the encoder count's length, `size.reproducibility`.
    pub fn trace_noise(&self) -> crate::engine::size::TraceNoise {
        let scale = if self.calibration_valid { self.calibration.scale } else { 1.0 };
        crate::engine::size::TraceNoise {
            lag1: if self.calibration_valid { self.noise_lag1 } else { 0.0 },
            quantum: self.meters_per_count * scale,
            reproducibility: self.reproducibility,
        }
    }

    /// The ring gauge, if `ring.diameter` names one.
    pub fn ring(&self) -> Option<RingSpec> {
        (self.ring_diameter > 0.0).then_some(RingSpec::grooved(self.ring_diameter, self.ring_groove_angle))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_angle_orders_and_coefficients_are_set_together() {
        use ParamValue::*;
        let mut p = Parameters { calibration_valid: true, ..Parameters::default() };
        p.set("calibration.angle_harmonics", &IntegerArray(vec![1, 2])).unwrap();
        p.set("calibration.angle_coefficients", &DoubleArray(vec![1e-3, 0.0, 0.0, 2e-4])).unwrap();
        assert_eq!(p.angle_in_force().coefficients(), [1e-3, 0.0, 0.0, 2e-4]);
        // Orders alone would misread the coefficients in force: refused, saying how.
        let e = p.clone().set("calibration.angle_harmonics", &IntegerArray(vec![1, 2, 4])).unwrap_err();
        assert!(e.to_string().contains("set both at once"), "{e}");
        let e = p.clone().set("calibration.angle_harmonics", &IntegerArray(vec![0])).unwrap_err();
        assert!(e.to_string().contains("from 1 to 63"), "{e}");
        // Together (a file, a command line), they read.
        let (orders, coefficients) = (IntegerArray(vec![1, 2, 4]), DoubleArray(vec![0.0; 6]));
        p.set_all([("calibration.angle_harmonics", &orders), ("calibration.angle_coefficients", &coefficients)])
            .unwrap();
        assert_eq!(p.angle_in_force().orders().to_vec(), [1, 2, 4]);
        // The covariance's names follow the coefficients in force; its size, the names.
        let names = covariance_names(p.angle_harmonics);
        p.set("calibration.covariance_names", &StringArray(names.clone())).unwrap();
        assert!(p.clone().set("calibration.covariance", &DoubleArray(vec![0.0; 25])).is_err());
        p.set("calibration.covariance", &DoubleArray(vec![0.0; 121])).unwrap();
        let e = p.clone().set("calibration.covariance_names", &StringArray(names[..5].to_vec())).unwrap_err();
        assert!(e.to_string().contains("angle_c1"), "{e}");
        // Dropping the angle error one set at a time reads at every step: the coefficients,
        // then the orders (the covariance's rows of the angle are then not read).
        p.set("calibration.angle_coefficients", &DoubleArray(Vec::new())).unwrap();
        assert!(p.angle_in_force().coefficients().is_empty());
        p.set("calibration.angle_harmonics", &IntegerArray(Vec::new())).unwrap();
        assert!(p.covariance_in_force().is_some_and(|c| c.nrows() == 11));
    }

    /// A tilt covariance whose off-diagonal entries differ in their last bits (as an
    /// earlier node wrote them into its params file after a calibration with heights, then
    /// refused the file at its next start) is taken, made symmetric; one that is not a
    /// covariance is refused.
    #[test]
    fn a_tilt_covariance_asymmetric_in_its_last_bits_is_taken_symmetric() {
        let mut p = Parameters::default();
        let written =
            vec![1.26014155241632e-10, 3.3870327367540585e-14, 3.3870327367540617e-14, 1.2599283303907513e-10];
        p.set("calibration.axis_tilt_covariance", &ParamValue::DoubleArray(written)).unwrap();
        let c = p.axis_tilt.covariance;
        assert_eq!(c[1].to_bits(), c[2].to_bits());
        assert!((c[1] - 3.38703273675406e-14).abs() < 1e-27, "{c:?}");
        for bad in [[1e-10, 1e-12, 2e-12, 1e-10], [1e-10, 2e-10, 2e-10, 1e-10], [-1e-10, 0.0, 0.0, 1e-10]] {
            let e = p.set("calibration.axis_tilt_covariance", &ParamValue::DoubleArray(bad.to_vec())).unwrap_err();
            assert!(e.to_string().contains("not a covariance"), "{bad:?}: {e}");
        }
        assert_eq!(p.axis_tilt.covariance, c, "a refused value leaves the one in force");
    }

    #[test]
    fn defaults_are_the_contracts() {
        let p = Parameters::default();
        let list = p.to_list();
        assert_eq!(list.len(), 42);
        assert_eq!(p.get("calibration.axis_tilt"), Some(ParamValue::DoubleArray(vec![0.0; 2])));
        assert_eq!(p.get("calibration.axis_tilt_covariance"), Some(ParamValue::DoubleArray(vec![0.0; 4])));
        assert_eq!(p.get("encoder.height_meters_per_count"), Some(ParamValue::Double(1e-6)));
        assert_eq!(p.get("calibration.angle_harmonics"), Some(ParamValue::IntegerArray(Vec::new())));
        assert_eq!(p.get("calibration.angle_coefficients"), Some(ParamValue::DoubleArray(Vec::new())));
        assert_eq!(p.get("calibration.covariance_names"), Some(ParamValue::StringArray(Vec::new())));
        assert_eq!(p.get("calibration.lack_of_fit_alpha"), Some(ParamValue::Double(0.001)));
        assert_eq!(p.get("calibrate.introspection"), Some(ParamValue::String("off".into())));
        assert_eq!(p.get("bond_heartbeat_period"), Some(ParamValue::Double(0.1)));
        assert_eq!(p.get("calibration.covariance"), Some(ParamValue::DoubleArray(Vec::new())));
        assert_eq!(p.get("use_sim_time"), Some(ParamValue::Bool(false)));
        assert_eq!(p.get("managed"), Some(ParamValue::Bool(false)));
        assert_eq!(p.get("history_file"), Some(ParamValue::String(String::new())));
        assert_eq!(p.get("calibration.max_age_days"), Some(ParamValue::Double(0.0)));
        assert_eq!(p.get("calibration.drift_warn_sigma"), Some(ParamValue::Double(10.0)));
        assert_eq!(p.get("calibration.scale"), Some(ParamValue::Double(1.0)));
        assert_eq!(p.get("plate.side"), Some(ParamValue::Double(0.045)));
        assert_eq!(p.get("plate.corner_radius"), Some(ParamValue::Double(0.003)));
        assert_eq!(p.get("encoder.meters_per_count"), Some(ParamValue::Double(1e-6)));
        assert_eq!(p.get("model"), Some(ParamValue::String("full".into())));
        assert_eq!(p.get("output_frame_id"), Some(ParamValue::String("tracer_axis".into())));
        assert_eq!(p.get("resample_points"), Some(ParamValue::Integer(400)));
        assert_eq!(p.get("calibration.valid"), Some(ParamValue::Bool(false)));
    }

    #[test]
    fn introspection_takes_rclcpps_states_and_yamls_off() {
        let mut p = Parameters::default();
        for (value, state) in [
            (ParamValue::String("contents".into()), Introspection::Contents),
            (ParamValue::String("metadata".into()), Introspection::Metadata),
            (ParamValue::String("disabled".into()), Introspection::Off),
            (ParamValue::String("contents".into()), Introspection::Contents),
            // `-p calibrate.introspection:=off`: rcl's YAML typing makes it false.
            (ParamValue::Bool(false), Introspection::Off),
        ] {
            p.set(names::INTROSPECTION, &value).unwrap();
            assert_eq!(p.introspection, state, "{value:?}");
        }
        let e = p.set(names::INTROSPECTION, &ParamValue::String("loud".into())).unwrap_err();
        assert_eq!(e.to_string(), "'loud' is not one of: off (or disabled), metadata, contents");
        assert!(p.set(names::INTROSPECTION, &ParamValue::Bool(true)).is_err());
        assert_eq!(p.introspection, Introspection::Off);
    }

    #[test]
    fn validation_names_the_problem() {
        let mut p = Parameters::default();
        assert_eq!(
            p.set("plate.side", &ParamValue::Double(-0.045)).unwrap_err().to_string(),
            "must be positive (greater than 0), got -0.045 (side of the square calibration plate (m))"
        );
        assert_eq!(
            p.set("model", &ParamValue::String("magic".into())).unwrap_err().to_string(),
            "unknown model 'magic': expected 'full', 'paper', 'full_scale', 'full_tip' or 'full_scale_tip'"
        );
        // The kinds of refusal, told apart.
        assert_eq!(p.set("nope", &ParamValue::Bool(true)), Err(ParamError::Unknown("nope".into())));
        assert_eq!(
            p.set("calibration.valid", &ParamValue::Integer(1)),
            Err(ParamError::WrongType { expected: "a bool".into(), got: "integer '1'".into() })
        );
        assert!(matches!(p.set("calibration.scale", &ParamValue::Double(0.0)), Err(ParamError::Invalid(_))));
        assert!(p.set("resample_points", &ParamValue::Integer(-1)).unwrap_err().to_string().contains("between 0"));
        assert!(p.set("plate.corner_radius", &ParamValue::Double(0.03)).is_err());
        assert!(
            p.set("calibration.valid", &ParamValue::Integer(1)).unwrap_err().to_string().contains("expected a bool")
        );
        assert!(
            p.set("calibration.scale", &ParamValue::Double(0.0)).unwrap_err().to_string().contains("between 0.5 and 2")
        );
        assert!(
            p.set("calibration.max_age_days", &ParamValue::Double(-1.0))
                .unwrap_err()
                .to_string()
                .contains("at least 0")
        );
        assert!(
            p.set("calibration.drift_warn_sigma", &ParamValue::Double(f64::NAN))
                .unwrap_err()
                .to_string()
                .contains("finite")
        );
        assert!(p.set("history_file", &ParamValue::Integer(3)).unwrap_err().to_string().contains("expected a string"));
        let cov = |v: Vec<f64>| p.clone().set("calibration.covariance", &ParamValue::DoubleArray(v));
        assert!(cov(vec![1e-12; 24]).unwrap_err().to_string().contains("expected n×n finite values"));
        let mut asymmetric = vec![0.0; 25];
        (asymmetric[0], asymmetric[1], asymmetric[6]) = (1e-8, 1e-9, 1e-8);
        assert!(cov(asymmetric).unwrap_err().to_string().contains("symmetric"));
        let mut negative = vec![0.0; 25];
        negative[6] = -1e-12;
        assert!(cov(negative).is_err());
        assert!(cov(Vec::new()).is_ok() && cov(vec![1e-12; 25]).is_ok());
        let mut q = p.clone();
        q.set("calibration.covariance", &ParamValue::DoubleArray(vec![1e-12; 25])).unwrap();
        q.set("calibration.covariance", &ParamValue::StringArray(Vec::new())).unwrap();
        assert!(q.covariance.is_empty(), "`[]` in a file is the empty covariance");
        q.set("calibration.covariance", &ParamValue::IntegerArray(vec![0; 25])).unwrap();
        assert_eq!(q.covariance, vec![0.0; 25]);
        assert_eq!(p, Parameters::default(), "failed sets change nothing");
        p.set("plate.side", &ParamValue::Integer(1)).unwrap();
        assert_eq!(p.plate.side, 1.0);
    }

    #[test]
    fn a_file_with_a_wrong_type_is_refused_with_its_line() {
        let text = "tracer_calibrator:\n  ros__parameters:\n    plate.side: 0.05\n    resample_points: lots\n";
        let f = file::parse(text, "cell.yaml").unwrap();
        let mut p = Parameters::default();
        let e = p.apply_file(&f, "/tracer_calibrator", "cell.yaml").unwrap_err();
        assert_eq!(e.to_string(), "cell.yaml:4: resample_points: expected an integer, got string 'lots'");
        assert_eq!(p, Parameters::default());
        let ok =
            "tracer_calibrator:\n  ros__parameters:\n    plate.side: 0.05\n    use_sim_time: true\n    tags: [a]\n";
        let unknown = p.apply_file(&file::parse(ok, "c").unwrap(), "/tracer_calibrator", "c").unwrap();
        assert_eq!(unknown, ["tags"]);
        assert_eq!((p.plate.side, p.use_sim_time), (0.05, true));
    }
}
