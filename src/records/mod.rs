//! Calibration records: the history file a lab's quality system keeps of every applied
//! calibration (docs/CONTRACT.md, "Calibration records"), and how far a calibration moved from
//! the one before.
//!
//! One JSON object a line (JSON Lines), appended and `fsync`ed for every calibration the
//! node applies:
//!
//! ```json
//! {"format":2,"time":"2026-11-23T10:12:37.123Z","node":"/tracer_calibrator","scan_id":10,"model":"full",
//!  "alpha0":0.0349,"offset":0.005,"delta_l":0.002,"scale":1.0,"stddev":[1.2e-4,5.6e-6,1.0e-6],
//!  "rms_residual":4.9e-6,"samples_used":400,"iterations":7,
//!  "previous":{"alpha0":0.0348,"offset":0.005,"delta_l":0.002,"scale":1.0}}
//! ```
//!
//! `stddev` is the standard uncertainty of `[alpha0, offset, delta_l]`, and of `scale`
//! too (a fourth entry) when the model fits it. `previous` is the calibration the record
//! replaced, or `null`.
//!
//! This module is pure (text in, records out; the drift arithmetic; UTC times);
//! [`file`](mod@file) reads and appends history files.

pub mod file;

use std::time::{SystemTime, UNIX_EPOCH};

use serde::{Deserialize, Serialize};

use crate::engine::calibrate::{InvalidCovariance, named_covariance_from_values};
use crate::engine::geometry::Mounting;

/// One applied calibration, as a line of the history file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Record {
    /// The record format ([`HISTORY_FORMAT`]): absent (1) in records written before it
    /// existed; a newer one than this node's is skipped with the reason.
    #[serde(default = "format_1")]
    pub format: u32,
    /// When it was applied: UTC, ISO 8601 (`2026-11-23T10:12:37.123Z`).
    pub time: String,
    /// The node's fully qualified name.
    pub node: String,
    /// The plate scan it was fitted to.
    pub scan_id: u32,
    /// `full`, `paper` or `full_scale`.
    pub model: String,
    /// Radians.
    pub alpha0: f64,
    /// Metres (d).
    pub offset: f64,
    /// Metres (dL).
    pub delta_l: f64,
    /// Encoder scale k.
    pub scale: f64,
    /// Standard uncertainty of `[alpha0, offset, delta_l(, scale)]`.
    pub stddev: Vec<f64>,
    /// Metres.
    pub rms_residual: f64,
    pub samples_used: u32,
    pub iterations: u32,
    /// The tip radius in force, metres (0 unless modelled). Absent (0) in records written
    /// before it existed.
    #[serde(default)]
    pub tip_radius: f64,
    /// The covariance over `covariance_names` (`[alpha0, offset, delta_l, scale,
    /// tip_radius]`, 25 values, without angle harmonics), row-major. Absent (empty) in
    /// records written before it existed.
    #[serde(default)]
    pub covariance: Vec<f64>,
    /// The names of the covariance's rows, when the calibration fitted angle harmonics
    /// (format 3); else absent: the five.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub covariance_names: Vec<String>,
    /// The orders of the turntable's angle error fitted (format 3); absent: none.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub angle_harmonics: Vec<i64>,
    /// The angle error, `[c_h₁, s_h₁, ...]` radians (format 3); absent: none.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub angle_coefficients: Vec<f64>,
    /// The plate scans after `scan_id`, when several placements were fitted; absent: one.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub plate_scan_ids: Vec<u32>,
    /// The lag-1 correlation of the noise along the plate's trace the calibration
    /// measured (`calibration.noise_lag1`); absent: 0, white.
    #[serde(default, skip_serializing_if = "is_zero")]
    pub noise_lag1: f64,
    /// The turntable axis's tilt fitted with the calibration from the artefacts' heights
    /// (`calibration.axis_tilt`, `[τ_x, τ_y]` rad); absent: none fitted (no heights).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub axis_tilt: Vec<f64>,
    /// Its covariance, 2×2 row-major, rad² (`calibration.axis_tilt_covariance`).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub axis_tilt_covariance: Vec<f64>,
    /// The holder's plane's height where the axis meets it, m (`calibration.height_zero`).
    #[serde(default, skip_serializing_if = "is_zero")]
    pub height_zero: f64,
    /// The calibration this one replaced; `None` (`null`) if there was none.
    pub previous: Option<Previous>,
    /// The node's ROS time when it was applied (simulated time under `use_sim_time`;
    /// else the system time, as `time`). Absent in records written before it existed.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub ros_time: Option<RosTime>,
}

/// The newest history record format this node writes: 1, records without `format`; 2,
/// with it; 3, a calibration with an angle error (an older node skips it, as it could not
/// apply the angle). A record without one is written as 2.
pub const HISTORY_FORMAT: u32 = 3;

/// The format of a record with (or without) an angle error.
pub fn format_for(angle_coefficients: &[f64]) -> u32 {
    if angle_coefficients.is_empty() { 2 } else { 3 }
}

fn is_zero(x: &f64) -> bool {
    *x == 0.0
}

fn format_1() -> u32 {
    1
}

/// A ROS time (`builtin_interfaces/Time`): seconds and nanoseconds.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct RosTime {
    pub sec: i32,
    pub nanosec: u32,
}

impl RosTime {
    /// From nanoseconds since the clock's epoch.
    pub fn from_nanos(nanos: i64) -> RosTime {
        RosTime { sec: nanos.div_euclid(1_000_000_000) as i32, nanosec: nanos.rem_euclid(1_000_000_000) as u32 }
    }

    /// Nanoseconds since the clock's epoch.
    pub fn to_nanos(self) -> i64 {
        i64::from(self.sec) * 1_000_000_000 + i64::from(self.nanosec)
    }
}

/// The calibration a record replaced.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Previous {
    pub alpha0: f64,
    pub offset: f64,
    pub delta_l: f64,
    pub scale: f64,
}

impl From<Mounting> for Previous {
    fn from(m: Mounting) -> Self {
        Previous { alpha0: m.alpha0, offset: m.offset, delta_l: m.delta_l, scale: m.scale }
    }
}

impl Previous {
    pub fn mounting(&self) -> Mounting {
        Mounting { alpha0: self.alpha0, offset: self.offset, delta_l: self.delta_l, scale: self.scale }
    }
}

impl Record {
    /// The calibration the record holds.
    pub fn mounting(&self) -> Mounting {
        Mounting { alpha0: self.alpha0, offset: self.offset, delta_l: self.delta_l, scale: self.scale }
    }

    /// When it was applied, if `time` is a UTC time this module reads.
    pub fn applied_at(&self) -> Option<SystemTime> {
        parse_utc(&self.time)
    }

    /// The record as one line of JSON (no newline).
    pub fn to_line(&self) -> String {
        serde_json::to_string(self).expect("a record always serializes")
    }

    /// A record with a non-finite number, a stddev of the wrong length, a covariance that
    /// is none or a time that is no UTC time is not one the node writes.
    fn check(&self) -> Result<(), RecordError> {
        if self.format > HISTORY_FORMAT {
            return Err(RecordError::Newer(self.format));
        }
        let numbers = [self.alpha0, self.offset, self.delta_l, self.scale, self.rms_residual, self.tip_radius];
        if !numbers.iter().chain(&self.stddev).all(|v| v.is_finite()) {
            return Err(RecordError::NotFinite);
        }
        if !(self.stddev.is_empty() || (3..=4).contains(&self.stddev.len())) {
            return Err(RecordError::StddevLength(self.stddev.len()));
        }
        if !self.covariance.is_empty() {
            named_covariance_from_values(&self.covariance)?;
        }
        if !self.angle_coefficients.iter().all(|v| v.is_finite()) {
            return Err(RecordError::NotFinite);
        }
        if self.applied_at().is_none() {
            return Err(RecordError::Time(self.time.clone()));
        }
        Ok(())
    }
}

/// Why a line of a history file is not a record ([`History::parse`] says it, with the
/// file and line, and skips the line).
#[derive(Debug, thiserror::Error)]
pub enum RecordError {
    /// Not JSON, or JSON with a field missing or of the wrong type.
    #[error("{0}")]
    Json(#[from] serde_json::Error),
    #[error("record format {0}, written by a newer tracer_calib: this one reads formats up to {HISTORY_FORMAT}")]
    Newer(u32),
    #[error("a number is not finite")]
    NotFinite,
    #[error("stddev has {0} entries, expected 3 or 4")]
    StddevLength(usize),
    #[error("covariance: {0}")]
    Covariance(#[from] InvalidCovariance),
    #[error("time '{0}' is not a UTC time (YYYY-MM-DDTHH:MM:SS[.fff]Z)")]
    Time(String),
}

/// Are two calibrations the same (within what a round trip through JSON or YAML text
/// can change: a few units in the last place)?
pub fn same_calibration(a: &Mounting, b: &Mounting) -> bool {
    let close = |x: f64, y: f64| (x - y).abs() <= 1e-12 * x.abs().max(y.abs()) + 1e-300;
    close(a.alpha0, b.alpha0) && close(a.offset, b.offset) && close(a.delta_l, b.delta_l) && close(a.scale, b.scale)
}

/// A history file's records, and the lines skipped (with why).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct History {
    pub records: Vec<Record>,
    /// `FILE:LINE: why`, one for each line that is not a record (a line torn by a
    /// crash mid-write).
    pub skipped: Vec<String>,
}

impl History {
    /// Parse the text of a history file (`path` names it in the messages). A line that
    /// is not a complete record is skipped with a message: a crash mid-write leaves at
    /// most a torn last line, and the next append starts on a fresh line, so a torn line
    /// may also sit between two good ones.
    pub fn parse(text: &str, path: &str) -> History {
        let mut h = History::default();
        let complete = text.ends_with('\n');
        let lines: Vec<&str> = text.lines().collect();
        for (i, line) in lines.iter().enumerate() {
            if line.trim().is_empty() {
                continue;
            }
            let last = i + 1 == lines.len();
            let record = serde_json::from_str::<Record>(line).map_err(RecordError::from);
            match record.and_then(|r| r.check().map(|()| r)) {
                Ok(r) => h.records.push(r),
                Err(e) => {
                    let what = if last && !complete { "a torn last line (no newline)" } else { "not a record" };
                    h.skipped.push(format!("{path}:{}: skipped {what}: {e}", i + 1));
                }
            }
        }
        h
    }

    /// The last record, and the one before it.
    pub fn last_two(&self) -> (Option<&Record>, Option<&Record>) {
        let n = self.records.len();
        (self.records.last(), n.checked_sub(2).map(|i| &self.records[i]))
    }
}

// ---------------------------------------------------------------------------------------
// Drift

/// The parameters a drift is measured on, in the order of `stddev`.
pub const DRIFT_NAMES: [&str; 3] = ["alpha0", "d", "dL"];

/// How far a calibration moved from the one before, parameter by parameter.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Drift {
    /// New minus previous, of `[alpha0, offset, delta_l]` (radians, metres). `alpha0`'s
    /// difference is taken to the nearest quarter turn (a square plate cannot tell them apart).
    pub delta: [f64; 3],
    /// `|delta|` over the combined standard uncertainty `sqrt(σ_new² + σ_prev²)`.
    pub sigmas: [f64; 3],
    /// Whether the previous calibration's uncertainties were known (else `σ_prev = 0`).
    pub previous_uncertainty_known: bool,
}

impl Drift {
    /// The largest move, in σ, and the index of its parameter.
    pub fn worst(&self) -> (usize, f64) {
        let mut w = (0, self.sigmas[0]);
        for (i, &s) in self.sigmas.iter().enumerate().skip(1) {
            if s > w.1 {
                w = (i, s);
            }
        }
        w
    }

    /// `alpha0 +0.0123° (1.2σ), d -0.0040 mm (0.8σ), dL +0.0002 mm (0.3σ)`.
    pub fn describe(&self) -> String {
        let [a, d, l] = self.delta;
        let [sa, sd, sl] = self.sigmas;
        format!(
            "alpha0 {:+.4}° ({sa:.1}σ), d {:+.4} mm ({sd:.1}σ), dL {:+.4} mm ({sl:.1}σ){}",
            a.to_degrees(),
            d * 1e3,
            l * 1e3,
            if self.previous_uncertainty_known {
                ""
            } else {
                " (σ of the new calibration alone: the previous one's is unknown)"
            }
        )
    }

    /// Did any parameter move by more than `limit` σ? (`limit` 0: never.)
    pub fn exceeds(&self, limit: f64) -> bool {
        limit > 0.0 && self.worst().1 > limit
    }
}

/// How far calibration `new` (standard uncertainties `new_sd`) moved from `prev`
/// (`prev_sd`, if known). `None` when the new uncertainties are not known or a combined
/// uncertainty is zero.
pub fn drift(new: &Mounting, new_sd: &[f64], prev: &Mounting, prev_sd: Option<&[f64]>) -> Option<Drift> {
    if new_sd.len() < 3 {
        return None;
    }
    let prev_sd = prev_sd.filter(|s| s.len() >= 3);
    let quarter = std::f64::consts::FRAC_PI_2;
    let da = new.alpha0 - prev.alpha0;
    let da = da - quarter * (da / quarter).round();
    let delta = [da, new.offset - prev.offset, new.delta_l - prev.delta_l];
    let mut sigmas = [0.0; 3];
    for i in 0..3 {
        let p = prev_sd.map_or(0.0, |s| s[i]);
        let u = new_sd[i].hypot(p);
        if !(u > 0.0 && u.is_finite() && delta[i].is_finite()) {
            return None;
        }
        sigmas[i] = delta[i].abs() / u;
    }
    Some(Drift { delta, sigmas, previous_uncertainty_known: prev_sd.is_some() })
}

/// The drift of history record `i` from the calibration it replaced: the record's
/// `previous`, with the uncertainties of the record before it when that record is the
/// calibration replaced.
pub fn record_drift(records: &[Record], i: usize) -> Option<Drift> {
    let r = records.get(i)?;
    let prev = r.previous?;
    let prev_sd = i
        .checked_sub(1)
        .map(|j| &records[j])
        .filter(|before| same_calibration(&before.mounting(), &prev.mounting()))
        .map(|before| before.stddev.as_slice());
    drift(&r.mounting(), &r.stddev, &prev.mounting(), prev_sd)
}

// ---------------------------------------------------------------------------------------
// UTC times (RFC 3339), by `humantime`

/// `2026-11-23T10:12:37.123Z` (UTC, milliseconds); a time before 1970 as 1970's first.
pub fn format_utc(t: SystemTime) -> String {
    humantime::format_rfc3339_millis(t.max(UNIX_EPOCH)).to_string()
}

/// Read a UTC time as [`format_utc`] writes it; also without fractional seconds, with
/// any number of fractional digits, with a space for `T`, and with `+00:00` for `Z`
/// (one of the two is required: a time without its zone is not read as UTC).
pub fn parse_utc(s: &str) -> Option<SystemTime> {
    let s = s.trim();
    if !(s.ends_with('Z') || s.ends_with("+00:00")) {
        return None;
    }
    humantime::parse_rfc3339_weak(s).ok()
}

#[cfg(test)]
impl Record {
    /// A full-model calibration record, for tests to vary.
    pub(crate) fn example() -> Record {
        Record {
            format: 2,
            time: "2026-11-23T10:12:37.123Z".into(),
            node: "/tracer_calibrator".into(),
            scan_id: 10,
            model: "full".into(),
            alpha0: 0.03,
            offset: 0.005,
            delta_l: 0.002,
            scale: 1.0,
            stddev: vec![1e-4, 5e-6, 1e-6],
            rms_residual: 5e-6,
            samples_used: 400,
            iterations: 7,
            tip_radius: 0.0,
            covariance: Vec::new(),
            covariance_names: Vec::new(),
            angle_harmonics: Vec::new(),
            angle_coefficients: Vec::new(),
            plate_scan_ids: Vec::new(),
            noise_lag1: 0.0,
            axis_tilt: Vec::new(),
            axis_tilt_covariance: Vec::new(),
            height_zero: 0.0,
            previous: None,
            ros_time: None,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::time::Duration;

    fn record(time: &str, alpha0: f64, previous: Option<Previous>) -> Record {
        Record { time: time.into(), alpha0, previous, ..Record::example() }
    }

    #[test]
    fn utc_times_round_trip() {
        let t = UNIX_EPOCH + Duration::new(1_795_428_757, 123_456_789);
        assert_eq!(format_utc(t), "2026-11-23T10:12:37.123Z");
        assert_eq!(parse_utc("2026-11-23T10:12:37.123Z"), Some(UNIX_EPOCH + Duration::new(1_795_428_757, 123_000_000)));
        assert_eq!(parse_utc("2026-11-23T10:12:37Z"), Some(UNIX_EPOCH + Duration::new(1_795_428_757, 0)));
        assert_eq!(
            parse_utc("2026-11-23 10:12:37.5+00:00"),
            Some(UNIX_EPOCH + Duration::new(1_795_428_757, 500_000_000))
        );
        assert_eq!(format_utc(UNIX_EPOCH), "1970-01-01T00:00:00.000Z");
        assert_eq!(parse_utc("2024-02-29T00:00:00Z").map(format_utc).as_deref(), Some("2024-02-29T00:00:00.000Z"));
        for bad in [
            "",
            "2026-11-23T10:12:37",
            "2026-02-30T00:00:00Z",
            "2026-11-23T25:00:00Z",
            "x-1-1T0:0:0Z",
            "2026-11-23T10:12:37.1e3Z",
        ] {
            assert_eq!(parse_utc(bad), None, "{bad}");
        }
        // Every day of four centuries round-trips.
        for day in (0..146_097 * 4).step_by(7) {
            let t = UNIX_EPOCH + Duration::from_secs(day * 86_400 + 3_599);
            assert_eq!(parse_utc(&format_utc(t)), Some(t));
        }
    }

    #[test]
    fn an_older_record_reads_and_a_newer_one_is_skipped_with_the_reason() {
        let mut line = serde_json::to_value(Record::example()).unwrap();
        assert_eq!(line["format"], 2, "written with the format");
        line.as_object_mut().unwrap().remove("format");
        let old = line.to_string();
        line["format"] = 4.into();
        let newer = line.to_string();
        let h = History::parse(&format!("{old}\n{newer}\n"), "h.jsonl");
        assert_eq!(h.records.len(), 1);
        assert_eq!(h.records[0].format, 1, "a record without a format is format 1");
        assert_eq!(h.skipped.len(), 1);
        assert!(
            h.skipped[0].starts_with("h.jsonl:2: ")
                && h.skipped[0]
                    .contains("record format 4, written by a newer tracer_calib: this one reads formats up to 3"),
            "{}",
            h.skipped[0]
        );
    }

    #[test]
    fn records_round_trip_as_lines_of_the_contracts_fields() {
        let r = record(
            "2026-11-23T10:12:37.123Z",
            0.0349,
            Some(Previous { alpha0: 0.03, offset: 0.005, delta_l: 0.002, scale: 1.0 }),
        );
        let line = r.to_line();
        assert!(!line.contains('\n'));
        let v: serde_json::Value = serde_json::from_str(&line).unwrap();
        let keys: Vec<&str> = v.as_object().unwrap().keys().map(String::as_str).collect();
        assert_eq!(
            keys,
            [
                "format",
                "time",
                "node",
                "scan_id",
                "model",
                "alpha0",
                "offset",
                "delta_l",
                "scale",
                "stddev",
                "rms_residual",
                "samples_used",
                "iterations",
                "tip_radius",
                "covariance",
                "previous"
            ]
        );
        let first = record("2026-11-22T10:00:00.000Z", 0.03, None);
        assert!(first.to_line().ends_with("\"previous\":null}"));
        let h = History::parse(&format!("{}\n{line}\n", first.to_line()), "h.jsonl");
        assert_eq!(h.records, [first, r]);
        assert!(h.skipped.is_empty());
    }

    #[test]
    fn records_before_the_covariance_read_and_a_bad_covariance_is_skipped() {
        let mut v: serde_json::Value = serde_json::from_str(&Record::example().to_line()).unwrap();
        let o = v.as_object_mut().unwrap();
        o.remove("tip_radius");
        o.remove("covariance");
        let old = v.to_string();
        let mut bad = Record::example();
        bad.covariance = vec![1e-12; 24];
        let h = History::parse(&format!("{old}\n{}\n", bad.to_line()), "h.jsonl");
        assert_eq!(h.records, [Record::example()]);
        assert_eq!(h.skipped.len(), 1);
        assert!(h.skipped[0].contains("covariance: expected n×n finite values"), "{}", h.skipped[0]);
    }

    #[test]
    fn torn_lines_are_skipped_with_their_line() {
        let a = record("2026-11-22T10:00:00.000Z", 0.03, None).to_line();
        let b = record("2026-11-23T10:00:00.000Z", 0.031, None).to_line();
        // A torn last line.
        let h = History::parse(&format!("{a}\n{}", &b[..b.len() / 2]), "h.jsonl");
        assert_eq!(h.records.len(), 1);
        assert_eq!(h.skipped.len(), 1);
        assert!(h.skipped[0].starts_with("h.jsonl:2: skipped a torn last line (no newline)"), "{}", h.skipped[0]);
        // A torn line the next append started after.
        let h = History::parse(&format!("{a}\n{}\n{b}\n", &b[..30]), "h.jsonl");
        assert_eq!(h.records.len(), 2);
        assert!(h.skipped[0].starts_with("h.jsonl:2: skipped not a record"), "{}", h.skipped[0]);
        // Wrong content is not a record either.
        let bad_time = a.replace("2026-11-22T10:00:00.000Z", "yesterday");
        let h = History::parse(&format!("{bad_time}\n\n{{}}\n"), "h.jsonl");
        assert!(h.records.is_empty());
        assert_eq!(h.skipped.len(), 2);
        assert!(h.skipped[0].contains("yesterday"), "{}", h.skipped[0]);
        assert!(h.skipped[1].starts_with("h.jsonl:3:"), "{}", h.skipped[1]);
    }

    #[test]
    fn drift_in_combined_standard_uncertainties() {
        let prev = Mounting::new(0.03, 0.005, 0.002);
        let new = Mounting::new(0.03 + 5e-4, 0.005 - 3e-5, 0.002);
        let sd = [1e-4, 1e-5, 1e-6];
        let d = drift(&new, &sd, &prev, Some(&sd)).unwrap();
        let u = 2f64.sqrt();
        assert!((d.sigmas[0] - 5.0 / u).abs() < 1e-9, "{d:?}");
        assert!((d.sigmas[1] - 3.0 / u).abs() < 1e-9, "{d:?}");
        assert_eq!(d.sigmas[2], 0.0);
        assert_eq!(d.worst().0, 0);
        assert!(d.exceeds(3.0) && !d.exceeds(4.0) && !d.exceeds(0.0));
        assert!(
            d.describe().starts_with("alpha0 +0.0286° (3.5σ), d -0.0300 mm (2.1σ), dL +0.0000 mm (0.0σ)"),
            "{}",
            d.describe()
        );
        // Unknown previous uncertainties: the new ones alone.
        let d = drift(&new, &sd, &prev, None).unwrap();
        assert!((d.sigmas[0] - 5.0).abs() < 1e-9 && !d.previous_uncertainty_known);
        // A quarter turn apart is no move.
        let turned = Mounting::new(0.03 - std::f64::consts::FRAC_PI_2, 0.005, 0.002);
        assert!(drift(&turned, &sd, &prev, Some(&sd)).unwrap().sigmas[0] < 1e-9);
        assert!(drift(&new, &[], &prev, None).is_none());
        assert!(drift(&new, &[0.0, 0.0, 0.0], &prev, None).is_none());
    }

    #[test]
    fn record_drift_takes_the_uncertainties_of_the_record_replaced() {
        let a = record("2026-11-22T10:00:00.000Z", 0.03, None);
        let b = record("2026-11-23T10:00:00.000Z", 0.031, Some(Previous::from(a.mounting())));
        let c =
            record("2026-11-24T10:00:00.000Z", 0.031, Some(Previous { alpha0: 0.02, ..Previous::from(b.mounting()) }));
        let rs = [a, b, c];
        assert!(record_drift(&rs, 0).is_none());
        let d = record_drift(&rs, 1).unwrap();
        assert!(d.previous_uncertainty_known && (d.sigmas[0] - 1e-3 / (1e-4 * 2f64.sqrt())).abs() < 1e-6, "{d:?}");
        // The record before is not the calibration replaced (set by hand in between).
        let d = record_drift(&rs, 2).unwrap();
        assert!(!d.previous_uncertainty_known && (d.sigmas[0] - 110.0).abs() < 1e-6, "{d:?}");
    }
}
