//! A calibrate request: the requested plate scan fitted; unless a dry run, the result
//! applied, recorded in the history and persisted in the params file. A failed fit, or one
//! that cannot be recorded, leaves the calibration in force as it was on disk.

use super::{InForce, NodeState, Now};
use crate::engine::calibrate::{Calibration, CalibrationError, Ring, calibrate_placements, named_covariance_values};
use crate::engine::correct::Corrector;
use crate::engine::geometry::Mounting;
use crate::engine::height::{AxisTilt, TiltError, fit_axis_tilt};
use crate::interfaces::{CalibrateRequest, CalibrateResponse};
use crate::params::{ParamValue, names};
use crate::records::{self, Previous, Record};
use nalgebra::Vector2;

/// What a calibrate request did.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct CalibrateOutcome {
    pub response: CalibrateResponse,
    /// The new calibration, if one was applied.
    pub applied: Option<Mounting>,
    /// The parameters the calibration set, each validated as any set of them is (the cell
    /// owns them): what the node tells its ROS parameter server, as one change. Empty
    /// unless one was applied.
    pub parameters: Vec<(&'static str, ParamValue)>,
}

impl NodeState {
    /// Handle a calibrate request: fit the requested plate scan; unless it is a dry
    /// run, apply the result and persist the parameters. A failed fit leaves the
    /// calibration in force untouched.
    pub fn on_calibrate(&mut self, req: &CalibrateRequest) -> CalibrateOutcome {
        self.on_calibrate_at(req, Now::system())
    }

    /// [`NodeState::on_calibrate`] at `now`: the record's `time` is its system time, its
    /// `ros_time` (and the `calibration` message's stamp) its ROS time.
    pub fn on_calibrate_at(&mut self, req: &CalibrateRequest, now: Now) -> CalibrateOutcome {
        let fail = |this: &mut Self, error_code: u16, message: String| {
            this.stats.calibrations_failed += 1;
            this.stats.last_fit_message = message.clone();
            this.stats.last_fit_error = error_code;
            CalibrateOutcome {
                response: CalibrateResponse { success: false, message, error_code, ..Default::default() },
                ..CalibrateOutcome::default()
            }
        };
        // The plate scans: those of plate_scan_ids, each a placement; else scan_id's.
        let wanted = if req.plate_scan_ids.is_empty() { vec![req.scan_id] } else { req.plate_scan_ids.clone() };
        let mut plates = Vec::with_capacity(wanted.len());
        for &id in &wanted {
            let plate = if id == 0 { self.plates.back() } else { self.plates.iter().find(|p| p.scan_id == id) };
            let Some(plate) = plate else {
                let have: Vec<String> = self.plates.iter().map(|p| p.scan_id.to_string()).collect();
                let message = if have.is_empty() {
                    "no calibration-plate scan received yet (publish a RawScan with target TARGET_CALIBRATION_PLATE)"
                        .to_string()
                } else {
                    format!("no calibration-plate scan with scan_id {id} (kept: {})", have.join(", "))
                };
                return fail(self, CalibrateResponse::ERROR_NO_PLATE_SCAN, message);
            };
            if plates.iter().any(|p: &&super::scans::KeptScan| p.scan_id == plate.scan_id) {
                return fail(
                    self,
                    CalibrateResponse::ERROR_BAD_REQUEST,
                    format!("plate_scan_ids names scan {} twice: each scan is one placement", plate.scan_id),
                );
            }
            plates.push(plate);
        }
        let scan_id = plates[0].scan_id;
        let more_ids: Vec<u32> = plates[1..].iter().map(|p| p.scan_id).collect();
        // The tip models fit the tip's radius from a ring-gauge scan too.
        let model = self.params.model;
        let ring = if model.fits_tip() {
            let Some(spec) = self.params.ring() else {
                return fail(
                    self,
                    CalibrateResponse::ERROR_NO_RING_SCAN,
                    format!(
                        "model {model} needs the ring gauge's diameter: set ring.diameter (m, its certificate's value)"
                    ),
                );
            };
            let id = req.ring_scan_id;
            let kept = if id == 0 { self.rings.back() } else { self.rings.iter().find(|r| r.scan_id == id) };
            let Some(kept) = kept else {
                let have: Vec<String> = self.rings.iter().map(|r| r.scan_id.to_string()).collect();
                let message = if have.is_empty() {
                    format!(
                        "model {model} needs a ring-gauge scan and none was received yet (publish a RawScan with target TARGET_RING_GAUGE)"
                    )
                } else {
                    format!("no ring-gauge scan with scan_id {id} (kept: {})", have.join(", "))
                };
                return fail(self, CalibrateResponse::ERROR_NO_RING_SCAN, message);
            };
            Some((kept.scan_id, Ring { scan: &kept.scan, spec }, kept))
        } else {
            None
        };
        let scans: Vec<&crate::engine::scan::Scan> = plates.iter().map(|p| &p.scan).collect();
        let fitted = calibrate_placements(
            &scans,
            ring.as_ref().map(|(_, r, _)| *r),
            &self.params.plate,
            &self.params.calibration_options(),
        );
        let plate_ids: Vec<String> = plates.iter().map(|p| p.scan_id.to_string()).collect();
        let scans = match (&ring, plate_ids.len()) {
            (Some((ring_id, _, _)), _) => format!("scans {} and {ring_id} (ring gauge)", plate_ids.join(", ")),
            (None, 1) => format!("scan {scan_id}"),
            (None, _) => format!("scans {}", plate_ids.join(", ")),
        };
        let cal = match fitted {
            Ok(cal) => cal,
            Err(e) => return fail(self, error_code(&e), format!("calibration failed on {scans}: {e}")),
        };
        self.stats.last_fit_rms = Some(cal.rms_residual);
        let mut response = response_for(&cal, format!("{scans}: {}", cal.summary()));
        // The axis's tilt, from the heights of the artefacts that have them.
        let with_heights: Vec<&super::scans::KeptScan> =
            plates.iter().copied().chain(ring.as_ref().map(|(_, _, k)| *k)).filter(|k| !k.heights.is_empty()).collect();
        let tilt = (!with_heights.is_empty()).then(|| fit_tilt(&with_heights, &cal));
        match &tilt {
            Some(Ok(t)) => response.message = format!("{}; {}", response.message, describe_tilt(t)),
            Some(Err(e)) => {
                response.message =
                    format!("{}; the axis's tilt not fitted, the one in force kept: {e}", response.message)
            }
            None => {}
        }
        let mut stddev = cal.stddev.to_vec();
        if cal.model.fits_scale() {
            stddev.push(cal.scale_stddev);
        }
        let previous = self.params.calibration_in_force();
        let drift = previous.and_then(|prev| {
            let prev_sd = (self.in_force.stddev.len() >= 3).then_some(self.in_force.stddev.as_slice());
            records::drift(&cal.mounting, &stddev, &prev, prev_sd)
        });
        if let Some(d) = &drift {
            response.message = format!("{}; moved since the previous calibration: {}", response.message, d.describe());
            if d.exceeds(self.params.drift_warn_sigma) {
                response.message = format!(
                    "{} — more than calibration.drift_warn_sigma = {}: check the tracer",
                    response.message, self.params.drift_warn_sigma
                );
            }
        }
        if req.dry_run {
            response.message = format!("dry run, not applied: {}", response.message);
            self.stats.last_fit_message = response.message.clone();
            self.stats.last_fit_error = response.error_code;
            return CalibrateOutcome { response, ..CalibrateOutcome::default() };
        }
        // The covariance's names where they say more than the five: with an angle error.
        let names_in_force =
            if response.angle_coefficients.is_empty() { Vec::new() } else { response.covariance_names.clone() };
        let fitted_tilt = tilt.as_ref().and_then(|t| t.as_ref().ok());
        // The parameters it sets, together through the rules any set of them goes through:
        // a value they refuse fails the calibration, and the one in force stays.
        let parameters = calibration_parameters(&cal, &response, &names_in_force, fitted_tilt);
        let mut next = self.params.clone();
        if let Err(e) = next.set_all(parameters.iter().map(|(name, value)| (*name, value))) {
            let message = format!("calibration failed on {scans}: the parameters refuse what the fit gives: {e}");
            return fail(self, CalibrateResponse::ERROR_NO_FIT, message);
        }
        let record = Record {
            format: records::format_for(&response.angle_coefficients),
            time: records::format_utc(now.wall),
            node: self.fqn.clone(),
            scan_id,
            model: cal.model.as_str().to_string(),
            alpha0: cal.mounting.alpha0,
            offset: cal.mounting.offset,
            delta_l: cal.mounting.delta_l,
            scale: cal.mounting.scale,
            stddev: stddev.clone(),
            rms_residual: cal.rms_residual,
            samples_used: cal.samples_used as u32,
            iterations: cal.iterations as u32,
            tip_radius: cal.tip_radius,
            covariance: response.covariance.clone(),
            covariance_names: names_in_force.clone(),
            angle_harmonics: response.angle_harmonics.iter().map(|&h| i64::from(h)).collect(),
            angle_coefficients: response.angle_coefficients.clone(),
            plate_scan_ids: more_ids,
            noise_lag1: cal.noise_lag1,
            axis_tilt: fitted_tilt.map(|t| t.angles.to_vec()).unwrap_or_default(),
            axis_tilt_covariance: fitted_tilt.map(|t| t.covariance.to_vec()).unwrap_or_default(),
            height_zero: fitted_tilt.map_or(0.0, |t| t.height_zero),
            previous: previous.map(Previous::from),
            ros_time: Some(records::RosTime::from_nanos(now.ros.to_nanos())),
        };
        self.params = next;
        // The time the record gives, to the millisecond: what a restart reads back.
        self.in_force = InForce {
            applied_at: record.applied_at().unwrap_or(now.wall),
            ros_time: now.ros,
            model: record.model.clone(),
            scan_id,
            stddev,
            rms_residual: cal.rms_residual,
            samples_used: record.samples_used,
            source: "calibrate",
        };
        self.drift = drift;
        self.stats.calibrations_applied += 1;
        // The record first: a calibration the history cannot show is not persisted
        // either (a restart goes back to the last recorded one).
        if let Err(e) = self.append_history(&record).and_then(|()| self.persist()) {
            response.success = false;
            response.error_code = CalibrateResponse::ERROR_NOT_PERSISTED;
            response.message = format!("calibration applied in memory but not persisted: {e}; {}", response.message);
        }
        self.stats.last_fit_message = response.message.clone();
        self.stats.last_fit_error = response.error_code;
        CalibrateOutcome { response, applied: Some(cal.mounting), parameters }
    }
}

/// The parameters a calibration sets, by name: the mounting, its covariance (and the rows'
/// names), the tip radius, the angle error, the noise's lag-1 correlation, and the axis's
/// tilt when it was fitted.
fn calibration_parameters(
    cal: &Calibration,
    response: &CalibrateResponse,
    covariance_names: &[String],
    tilt: Option<&AxisTilt>,
) -> Vec<(&'static str, ParamValue)> {
    use ParamValue::{Bool, Double, DoubleArray, StringArray};
    let m = cal.mounting;
    let mut p = vec![
        (names::ALPHA0, Double(m.alpha0)),
        (names::OFFSET, Double(m.offset)),
        (names::DELTA_L, Double(m.delta_l)),
        (names::SCALE, Double(m.scale)),
        (names::VALID, Bool(true)),
        (names::COVARIANCE, DoubleArray(response.covariance.clone())),
        (names::TIP_RADIUS, Double(cal.tip_radius)),
        (names::ANGLE_COEFFICIENTS, DoubleArray(response.angle_coefficients.clone())),
        (names::COVARIANCE_NAMES, StringArray(covariance_names.to_vec())),
        (names::NOISE_LAG1, Double(cal.noise_lag1)),
    ];
    if let Some(t) = tilt {
        p.extend([
            (names::AXIS_TILT, DoubleArray(t.angles.to_vec())),
            (names::AXIS_TILT_COVARIANCE, DoubleArray(t.covariance.to_vec())),
            (names::HEIGHT_ZERO, Double(t.height_zero)),
        ]);
    }
    p
}

/// The axis's tilt against the holder's plane from flat artefacts' heights, each at its
/// ball's centre as the new calibration `cal` corrects its scan ([`crate::engine::height`]).
fn fit_tilt(artefacts: &[&super::scans::KeptScan], cal: &Calibration) -> Result<AxisTilt, TiltError> {
    let centres: Vec<Vec<Vector2<f64>>> = artefacts
        .iter()
        .map(|k| Corrector::with_angle(cal.mounting, &cal.angle, k.scan.steps_per_rev()).correct(&k.scan))
        .collect();
    let pairs: Vec<(&[Vector2<f64>], &[f64])> =
        centres.iter().zip(artefacts).map(|(c, k)| (c.as_slice(), k.heights.as_slice())).collect();
    fit_axis_tilt(&pairs)
}

/// `axis tilt 0.10 ± 0.01 mrad, -0.05 ± 0.01 mrad` (standard uncertainties).
fn describe_tilt(t: &AxisTilt) -> String {
    let u = |i: usize| t.covariance[3 * i].max(0.0).sqrt() * 1e3;
    format!(
        "axis tilt {:.4} ± {:.4} mrad, {:.4} ± {:.4} mrad, holder at {:.1} µm",
        t.angles[0] * 1e3,
        u(0),
        t.angles[1] * 1e3,
        u(1),
        t.height_zero * 1e6
    )
}

/// The Calibrate response of a successful fit (the node's, and the offline tool's JSON):
/// `scale` and `scale_stddev` are the fitted ones, or 1 and 0 for a model that does not
/// fit the scale; `tip_radius` the one in force after the fit (fitted by the tip models,
/// else the known one) with its uncertainty (0 unless fitted); `covariance` the whole
/// covariance over `covariance_names` (the contract's five, then the angle coefficients).
pub fn response_for(cal: &Calibration, message: String) -> CalibrateResponse {
    let (scale, scale_stddev) =
        if cal.model.fits_scale() { (cal.mounting.scale, cal.scale_stddev) } else { (1.0, 0.0) };
    CalibrateResponse {
        success: true,
        message,
        alpha0: cal.mounting.alpha0,
        offset: cal.mounting.offset,
        delta_l: cal.mounting.delta_l,
        stddev: cal.stddev.to_vec(),
        rms_residual: cal.rms_residual,
        iterations: cal.iterations as u32,
        samples_used: cal.samples_used as u32,
        scale,
        scale_stddev,
        tip_radius: cal.tip_radius,
        tip_radius_stddev: cal.tip_radius_stddev,
        covariance: named_covariance_values(&cal.named_covariance),
        covariance_names: cal.covariance_names(),
        angle_harmonics: cal.angle.orders().iter().map(|h| h as i32).collect(),
        angle_coefficients: cal.angle.coefficients().to_vec(),
        error_code: CalibrateResponse::ERROR_NONE,
    }
}

/// The name of a Calibrate response's `error_code` (`ERROR_NONE`, ...), as the `.srv`
/// declares it; `ERROR_<n>` for a code it does not.
pub fn error_name(code: u16) -> std::borrow::Cow<'static, str> {
    const NAMES: [&str; 14] = [
        "ERROR_NONE",
        "ERROR_NO_PLATE_SCAN",
        "ERROR_NO_RING_SCAN",
        "ERROR_BAD_REQUEST",
        "ERROR_NOT_ACTIVE",
        "ERROR_INVALID_SETUP",
        "ERROR_SCAN_UNUSABLE",
        "ERROR_NO_FIT",
        "ERROR_RESIDUALS",
        "ERROR_LACK_OF_FIT",
        "ERROR_PLACEMENTS",
        "ERROR_SCALE_OFF",
        "ERROR_RING_MISMATCH",
        "ERROR_NOT_PERSISTED",
    ];
    match NAMES.get(code as usize) {
        Some(name) => (*name).into(),
        None => format!("ERROR_{code}").into(),
    }
}

/// The Calibrate response's `error_code` of a fit that failed (the table in
/// docs/troubleshooting.md says what each means and what to do).
pub fn error_code(e: &CalibrationError) -> u16 {
    use CalibrationError as E;
    match e {
        E::InvalidPlate(_) | E::Model(_) | E::InvalidScale(_) | E::InvalidTipRadius(_) => {
            CalibrateResponse::ERROR_INVALID_SETUP
        }
        E::TooFewSamples { .. } | E::TooManyOutliers { .. } => CalibrateResponse::ERROR_SCAN_UNUSABLE,
        E::NoStart | E::NotConverged { .. } | E::Singular => CalibrateResponse::ERROR_NO_FIT,
        E::ResidualTooLarge { .. } | E::SystematicResidual { .. } => CalibrateResponse::ERROR_RESIDUALS,
        E::Structure { .. } => CalibrateResponse::ERROR_LACK_OF_FIT,
        E::HarmonicInseparable { .. } => CalibrateResponse::ERROR_PLACEMENTS,
        E::TooManyPlacements(_) => CalibrateResponse::ERROR_BAD_REQUEST,
        E::ScaleOff { .. } => CalibrateResponse::ERROR_SCALE_OFF,
        E::Ring(_) => CalibrateResponse::ERROR_NO_RING_SCAN,
        E::RingMismatch { .. } | E::RingGroove { .. } | E::TipRadiusImplausible { .. } => {
            CalibrateResponse::ERROR_RING_MISMATCH
        }
    }
}
