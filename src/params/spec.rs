//! Every parameter's declaration: what it means (with its unit), the range the node
//! enforces, whether it may change after start-up. One table, read both by
//! [`Parameters::set`](super::Parameters::set) (the params file, `-p`, remote sets) and by
//! the node, which declares each parameter's descriptor from it (`ros2 param describe`,
//! rqt_reconfigure): the checks and what the descriptors say cannot drift apart.
//!
//! A [`Bound`] that rcl_interfaces can express (a closed interval) becomes the descriptor's
//! `floating_point_range` or `integer_range`; the others (a positive length, one of a few
//! strings, a relation between two parameters) are stated in `additional_constraints`.

use super::names;

/// What values a parameter takes, beyond its type.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Bound {
    /// Any value of the type (a double: any finite value).
    Any,
    /// A double in `[from, to]`; `to` infinite: no upper bound (a value is finite still).
    Float { from: f64, to: f64 },
    /// An integer in `[from, to]`.
    Integer { from: i64, to: i64 },
    /// A double greater than 0 (not expressible as an rcl_interfaces range, whose bounds are
    /// inclusive).
    Positive,
}

/// One parameter's declaration.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Spec {
    pub name: &'static str,
    /// One line: the meaning, with the unit.
    pub description: &'static str,
    pub bound: Bound,
    /// What the bound cannot say (relations to other parameters, allowed strings); empty if
    /// nothing.
    pub constraints: &'static str,
    /// Read at start-up only: a remote set is refused.
    pub read_only: bool,
}

/// Why a value is not one a parameter takes ([`Spec::check_f64`], [`Spec::check_i64`]):
/// not a finite number, or outside the parameter's bound (the words name the bound and
/// the parameter's meaning).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum BoundError {
    /// A double that is not finite (NaN, infinite): no parameter takes one.
    #[error("must be a finite number, got {0}")]
    NotFinite(f64),
    /// A double outside the parameter's bound.
    #[error("must be {}, got {got} ({})", .spec.bound_text(), .spec.description)]
    OutOfBound {
        /// The parameter's declaration (its bound, its meaning).
        spec: Spec,
        /// The value given.
        got: f64,
    },
    /// An integer outside the parameter's bound.
    #[error("must be {}, got {got} ({})", .spec.bound_text(), .spec.description)]
    IntegerOutOfBound {
        /// The parameter's declaration (its bound, its meaning).
        spec: Spec,
        /// The value given.
        got: i64,
    },
}

impl Spec {
    const fn new(name: &'static str, description: &'static str) -> Spec {
        Spec { name, description, bound: Bound::Any, constraints: "", read_only: false }
    }

    const fn bound(self, bound: Bound) -> Spec {
        Spec { bound, ..self }
    }

    const fn constraints(self, constraints: &'static str) -> Spec {
        Spec { constraints, ..self }
    }

    const fn read_only(self) -> Spec {
        Spec { read_only: true, ..self }
    }

    /// Check a double against the bound: `Ok(x)`, or what is wrong.
    pub fn check_f64(&self, x: f64) -> Result<f64, BoundError> {
        if !x.is_finite() {
            return Err(BoundError::NotFinite(x));
        }
        let ok = match self.bound {
            Bound::Any | Bound::Integer { .. } => true,
            Bound::Float { from, to } => (from..=to).contains(&x),
            Bound::Positive => x > 0.0,
        };
        if ok { Ok(x) } else { Err(BoundError::OutOfBound { spec: *self, got: x }) }
    }

    /// Check an integer against the bound: `Ok(i)`, or what is wrong.
    pub fn check_i64(&self, i: i64) -> Result<i64, BoundError> {
        match self.bound {
            Bound::Integer { from, to } if !(from..=to).contains(&i) => {
                Err(BoundError::IntegerOutOfBound { spec: *self, got: i })
            }
            _ => Ok(i),
        }
    }

    /// The bound in words: `between 0.5 and 2`, `at least 0`, `positive (greater than 0)`.
    pub fn bound_text(&self) -> String {
        match self.bound {
            Bound::Any => "any value".into(),
            Bound::Float { from, to } if to == f64::INFINITY => format!("at least {from}"),
            Bound::Float { from, to } => format!("between {from} and {to}"),
            Bound::Integer { from, to } => format!("between {from} and {to}"),
            Bound::Positive => "positive (greater than 0)".into(),
        }
    }
}

/// Every parameter of the node, in [`names::ALL`] order.
pub const SPECS: [Spec; 42] = [
    Spec::new(names::ALPHA0, "calibration in force: start angle error alpha0 of the rail (rad)")
        .bound(Bound::Float { from: -std::f64::consts::PI, to: std::f64::consts::PI }),
    Spec::new(names::OFFSET, "calibration in force: offset d of the rail from the turning axis (m)"),
    Spec::new(names::DELTA_L, "calibration in force: encoder zero error dL (m)"),
    Spec::new(names::SCALE, "calibration in force: encoder scale k; true length = counts x encoder.meters_per_count x k")
        .bound(Bound::Float { from: 0.5, to: 2.0 }),
    Spec::new(names::VALID, "true once a calibration is in force (applied by /calibrate or set here); false: scans are corrected with an ideal mounting"),
    Spec::new(names::COVARIANCE, "calibration in force: its covariance, n x n values row-major over calibration.covariance_names ([alpha0 (rad), offset (m), delta_l (m), scale, tip_radius (m)], then the angle coefficients (rad)), zero rows for what the model did not fit; set by /calibrate; empty = unknown")
        .constraints("empty, or n x n finite values of a symmetric matrix with no negative variance, n the number of calibration.covariance_names (5 when empty)"),
    Spec::new(names::TIP_RADIUS, "radius of the probe's contact tip (m): contours are of the surface the tip touched; fitted by the models full_tip and full_scale_tip, else known")
        .bound(Bound::Float { from: 0.0, to: 0.005 }),
    Spec::new(names::PLATE_SIDE, "side of the square calibration plate (m)")
        .bound(Bound::Positive)
        .constraints("positive (greater than 0) and more than twice plate.corner_radius"),
    Spec::new(names::CORNER_RADIUS, "corner radius of the calibration plate (m)")
        .constraints("at least 0 and less than half of plate.side"),
    Spec::new(names::SIDE_UNCERTAINTY, "standard uncertainty of plate.side from the plate's calibration certificate (m): a type B part of the calibration's covariance")
        .bound(Bound::Float { from: 0.0, to: f64::INFINITY }),
    Spec::new(names::RING_DIAMETER, "certified inner diameter of the ring gauge (m), traced from inside for the models full_tip and full_scale_tip; 0 = none")
        .bound(Bound::Float { from: 0.0, to: f64::INFINITY }),
    Spec::new(names::DIAMETER_UNCERTAINTY, "standard uncertainty of ring.diameter from the ring gauge's calibration certificate (m): a type B part of the covariance of full_tip and full_scale_tip")
        .bound(Bound::Float { from: 0.0, to: f64::INFINITY }),
    Spec::new(names::METERS_PER_COUNT, "encoder resolution (m per count)").bound(Bound::Positive),
    Spec::new(names::MODEL, "fitting model: full, paper (the seed paper's reduced model), full_scale (full + encoder scale), full_tip (full + tip radius, from a plate and a ring-gauge scan) or full_scale_tip")
        .constraints("one of: full, paper, full_scale, full_tip, full_scale_tip"),
    Spec::new(names::OUTPUT_FRAME_ID, "frame_id of the published contours and polygons"),
    Spec::new(names::RESAMPLE_POINTS, "size of Contour.radii (equal angle steps); 0 = no resampling")
        .bound(Bound::Integer { from: 0, to: super::MAX_RESAMPLE_POINTS }),
    Spec::new(names::PARAMS_FILE, "ROS 2 params file the node persists its parameters to after each change; empty = not persisted"),
    Spec::new(names::HISTORY_FILE, "JSON-lines file each applied calibration is appended to; empty = none"),
    Spec::new(names::MAX_AGE_DAYS, "/diagnostics warns when the calibration in force is older than this (days); 0 = no limit")
        .bound(Bound::Float { from: 0.0, to: f64::INFINITY }),
    Spec::new(names::DRIFT_WARN_SIGMA, "/diagnostics warns when a calibration moved a parameter by more than this many combined standard uncertainties; 0 = never")
        .bound(Bound::Float { from: 0.0, to: f64::INFINITY }),
    Spec::new(names::USE_SIM_TIME, "the node's clock follows /clock (rosgraph_msgs/msg/Clock) instead of the system clock"),
    Spec::new(names::MANAGED, "true: a lifecycle (managed) node that starts unconfigured; read at start-up")
        .read_only(),
    Spec::new(names::HARDWARE_ID, "the tracer's serial: /diagnostics' hardware_id; empty = output_frame_id"),
    Spec::new(names::SCAN_TIMEOUT, "/diagnostics warns when no raw scan came for this long (s); 0 = never (a tracer idles between jobs)")
        .bound(Bound::Float { from: 0.0, to: f64::INFINITY }),
    Spec::new(names::INTROSPECTION, "service introspection of calibrate, as rclcpp's configure_introspection: off, metadata (each request and response's client, sequence number and time on calibrate/_service_event) or contents (with the request and response: what `ros2 service echo` shows)")
        .constraints("one of: off (or disabled), metadata, contents"),
    Spec::new(names::BOND_HEARTBEAT_PERIOD, "a managed node's bond with nav2's lifecycle manager (bond/msg/Status on bond, id: the node's name), kept while active: its heartbeat period (s); 0 = no bond; read at start-up")
        .bound(Bound::Float { from: 0.0, to: f64::INFINITY })
        .read_only(),
    Spec::new(names::LACK_OF_FIT_ALPHA, "significance level of the harmonic lack-of-fit test: a calibration whose plate residuals show structure at this level (harmonics 1-12 a turn against the scan's own noise) is refused, naming the harmonics; 0 = no test")
        .bound(Bound::Float { from: 0.0, to: 0.5 }),
    Spec::new(names::ANGLE_HARMONICS, "orders of the turntable's angle error fitted by /calibrate with the model (times a turn: 1 a disc or gear eccentricity, 2 an elliptic disc); orders 4, 8, 12 need a second plate scan turned 22.5 degrees (plate_scan_ids); empty = the angle encoder taken as exact")
        .constraints("each from 1 to 63, once; calibration.angle_coefficients holds two an order, or none"),
    Spec::new(names::ANGLE_COEFFICIENTS, "calibration in force: the turntable's angle error, [c_h1, s_h1, c_h2, s_h2, ...] (rad) over calibration.angle_harmonics, the rail at alpha0 + phi + sum(c_h cos h phi + s_h sin h phi); set by /calibrate; empty = none")
        .constraints("empty, or two finite values of at most 0.1 rad an order of calibration.angle_harmonics"),
    Spec::new(names::COVARIANCE_NAMES, "calibration in force: the names of calibration.covariance's rows: alpha0, offset, delta_l, scale, tip_radius, then angle_c1, angle_s1, ... for each angle harmonic in force; set by /calibrate; empty = the five")
        .constraints("empty, or the five and the names of the angle coefficients in force, in that order (with no coefficients in force, the five and any)"),
    Spec::new(names::TIP_RADIUS_UNCERTAINTY, "standard uncertainty of stylus.tip_radius where it is entered rather than fitted (m, u = U/k from the stylus' certificate): a type B part of the covariance of full, full_scale and their angle fits, with its own row; 0 = what the calibration in force states of it")
        .bound(Bound::Float { from: 0.0, to: f64::INFINITY }),
    Spec::new(names::CORNER_RADIUS_UNCERTAINTY, "standard uncertainty of plate.corner_radius from the plate's calibration certificate (m, u = U/k): a type B part of the calibration's covariance")
        .bound(Bound::Float { from: 0.0, to: f64::INFINITY }),
    Spec::new(names::SEATING_UNCERTAINTY, "standard uncertainty of the plate's seating angle against the frame holder's datum (rad): added to alpha0's variance, so into every frame's A and B")
        .bound(Bound::Float { from: 0.0, to: f64::INFINITY }),
    Spec::new(names::NOISE_LAG1, "calibration in force: the lag-1 correlation of the encoder noise along the trace, as the plate's residuals showed it (0 = white); every trace's size uncertainty takes it; set by /calibrate")
        .bound(Bound::Float { from: -0.95, to: 0.95 }),
    Spec::new(names::REPRODUCIBILITY, "standard uncertainty of a radius between repeated traces of one shape beyond their noise (m, from repeated traces: re-seating, clamping), added to every contour's size and radius uncertainty; 0 = none")
        .bound(Bound::Float { from: 0.0, to: f64::INFINITY }),
    Spec::new(names::FRAME_GROOVE_ANGLE, "included angle of the V-groove of the frames the tracer traces (rad; 100-120 degrees is 1.745-2.094): the ball touches both flanks, its centre stylus.tip_radius / sin(angle/2) from the groove's bottom, and a frame's contour and sizes are of that bottom, where the lens's bevel sits; pi = a plain bore")
        .bound(Bound::Float { from: 0.5, to: std::f64::consts::PI }),
    Spec::new(names::FRAME_GROOVE_ANGLE_UNCERTAINTY, "standard uncertainty of frame.groove_angle (rad): the frames' groove angle varies by maker; it moves the groove's bottom against the ball's centre, into every frame's size and radius uncertainty")
        .bound(Bound::Float { from: 0.0, to: f64::INFINITY }),
    Spec::new(names::RING_GROOVE_ANGLE, "included angle of the ring gauge's V-groove (rad), ring.diameter that of its bottom: the ball's centre sits stylus.tip_radius / sin(angle/2) from it; pi = a plain bore")
        .bound(Bound::Float { from: 0.5, to: std::f64::consts::PI }),
    Spec::new(names::HEIGHT_METERS_PER_COUNT, "the height encoder's resolution (m per count), for the scans that carry RawScan.height_counts")
        .bound(Bound::Positive),
    Spec::new(names::AXIS_TILT, "calibration in force: the turntable axis's tilt against the frame holder's plane, [tau_x, tau_y] (rad), a flat artefact's height h = height_zero + x tan(tau_x) + y tan(tau_y); fitted by /calibrate from the plate's and ring's heights; removed from every contour's heights; empty = none")
        .constraints("empty, or two finite values"),
    Spec::new(names::AXIS_TILT_COVARIANCE, "calibration in force: the covariance of calibration.axis_tilt, 2 x 2 row-major (rad^2); into every frame's 3-D length uncertainty; empty = unknown (zero)")
        .constraints("empty, or four finite values of a symmetric matrix with no negative variance"),
    Spec::new(names::HEIGHT_ZERO, "calibration in force: the frame holder's plane's height where the axis meets it (m), as the plate's heights showed it; a contour's z is the height above that plane"),
];

/// The declaration of `name`, if it is one of the node's parameters.
pub fn spec(name: &str) -> Option<&'static Spec> {
    SPECS.iter().find(|s| s.name == name)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn one_declaration_per_parameter_in_order() {
        let names: Vec<_> = SPECS.iter().map(|s| s.name).collect();
        assert_eq!(names, names::ALL);
        assert!(SPECS.iter().all(|s| !s.description.is_empty()));
    }

    #[test]
    fn bounds_say_what_is_wrong() {
        let scale = spec(names::SCALE).unwrap();
        assert_eq!(scale.check_f64(1.5), Ok(1.5));
        let e = scale.check_f64(2.5).unwrap_err();
        assert_eq!(e, BoundError::OutOfBound { spec: *scale, got: 2.5 });
        assert!(e.to_string().starts_with("must be between 0.5 and 2, got 2.5 (calibration in force"), "{e}");
        let age = spec(names::MAX_AGE_DAYS).unwrap();
        let e = age.check_f64(f64::INFINITY).unwrap_err();
        assert_eq!(e, BoundError::NotFinite(f64::INFINITY), "no upper bound, yet finite");
        assert_eq!(e.to_string(), "must be a finite number, got inf");
        assert!(age.check_f64(-1.0).unwrap_err().to_string().starts_with("must be at least 0"));
        assert!(matches!(age.check_f64(f64::NAN), Err(BoundError::NotFinite(x)) if x.is_nan()));
        let e = spec(names::METERS_PER_COUNT).unwrap().check_f64(0.0).unwrap_err();
        assert!(
            matches!(e, BoundError::OutOfBound { got: 0.0, .. }) && e.to_string().contains("greater than 0"),
            "{e}"
        );
        let e = spec(names::RESAMPLE_POINTS).unwrap().check_i64(-1).unwrap_err();
        assert!(matches!(e, BoundError::IntegerOutOfBound { got: -1, .. }), "{e:?}");
        assert_eq!(
            e.to_string(),
            "must be between 0 and 100000, got -1 (size of Contour.radii (equal angle steps); 0 = no resampling)"
        );
    }
}
