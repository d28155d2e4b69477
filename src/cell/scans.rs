//! A raw scan corrected: every sample to where the probe really touched, as a `Contour`
//! (and a `PolygonStamped` for RViz), the plate scans kept for `/calibrate`.

use super::NodeState;
use super::intake::{self, ScanRejected};
use nalgebra::Vector2;

use crate::engine::correct::{Corrector, PolarContour, default_max_gap, resample_radii};
use crate::engine::geometry::Mounting;
use crate::engine::height::Frame3d;
use crate::engine::scan::Scan;
use crate::engine::size::{self, Correction};
use crate::engine::stylus::{Groove, Traced, contact_offset, touched_surface};
use crate::interfaces::{Contour, Header, Point, Point32, Polygon, PolygonStamped, RawScan, Time};

/// Largest coordinate of a corrected point, metres: what a `Point32` of the polygon holds.
/// (Any contour of a real tracer is a few centimetres.)
pub const MAX_COORDINATE: f64 = f32::MAX as f64;
/// Equal-angle radii the size figures are taken from when `resample_points` is 0.
const SIZE_RADII: usize = 400;
/// Calibration-plate scans kept for `/calibrate`, and as many ring-gauge scans.
pub const PLATE_SCANS_KEPT: usize = 16;

/// A plate or ring-gauge scan kept for calibration.
#[derive(Debug, Clone)]
pub(super) struct KeptScan {
    pub(super) scan_id: u32,
    pub(super) scan: Scan,
    /// Its heights, metres, one a sample; empty without a height channel.
    pub(super) heights: Vec<f64>,
}

/// A corrected scan, ready to publish.
#[derive(Debug, Clone, PartialEq)]
pub struct Corrected {
    pub contour: Contour,
    /// The same points as a `PolygonStamped`, when asked for (someone listens).
    pub polygon: Option<PolygonStamped>,
}

impl NodeState {
    /// Handle one raw scan: check it, keep it if it is of the plate, correct it, and
    /// build the `PolygonStamped` too if `with_polygon`. An error is a rejected scan
    /// (counted).
    ///
    /// A lens scan is corrected straight from the message's arrays: each point goes into
    /// the `Contour` and into the polar form the radii are resampled from as it comes
    /// (no engine `Scan`, no array of points: less memory to bring into cache for every
    /// scan).
    pub fn on_raw_scan(&mut self, msg: &RawScan, with_polygon: bool) -> Result<Corrected, ScanRejected> {
        self.stats.scans_received += 1;
        // A plate or ring-gauge scan is kept as an engine scan (for /calibrate); any other
        // is only checked. Either way its samples are checked once.
        let kept = matches!(msg.target, RawScan::TARGET_CALIBRATION_PLATE | RawScan::TARGET_RING_GAUGE);
        let checked = if kept {
            intake::to_scan(msg, self.params.meters_per_count).map(Some)
        } else {
            intake::check(msg, self.params.meters_per_count).map(|()| None)
        };
        // The heights, metres (empty without a height channel): kept with a plate or ring
        // scan, and each point's z below.
        let raw_heights = intake::heights(msg, self.params.height_meters_per_count);
        if let Some(scan) = checked.map_err(|e| self.reject(msg, e))? {
            let keep = if msg.target == RawScan::TARGET_RING_GAUGE { &mut self.rings } else { &mut self.plates };
            keep.retain(|p| p.scan_id != msg.scan_id);
            if keep.len() == PLATE_SCANS_KEPT {
                keep.pop_front();
            }
            keep.push_back(KeptScan { scan_id: msg.scan_id, scan, heights: raw_heights.clone() });
        }
        let calibration = self.params.calibration_in_force();
        let mounting = calibration.unwrap_or(Mounting::IDEAL);
        let angle = self.params.angle_in_force();
        let steps_per_rev = msg.steps_per_revolution;
        let corrector = match &self.corrector {
            Some(c) if *c.mounting() == mounting && *c.angle() == angle && c.steps_per_rev() == steps_per_rev => c,
            _ => self.corrector.insert(Corrector::with_angle(mounting, &angle, steps_per_rev)),
        };
        let n = msg.step.len();
        let mut points = Vec::with_capacity(n);
        let mut polar = (self.params.resample_points > 0).then(|| PolarContour::with_capacity(n));
        // Extreme but accepted parameters (encoder.meters_per_count, calibration.offset,
        // calibration.delta_l up to 1e308) can put points beyond what a float32 polygon or
        // a radius (sqrt(x² + y²)) can hold: refuse the scan rather than publish inf/NaN.
        // (A plate scan is kept above all the same: it is what a recalibration needs.)
        let mut out_of_range = None;
        let mut emit = |p: Vector2<f64>| {
            if out_of_range.is_none() && !(p.x.abs() <= MAX_COORDINATE && p.y.abs() <= MAX_COORDINATE) {
                out_of_range = Some((points.len(), p));
            }
            points.push(Point { x: p.x, y: p.y, z: 0.0 });
            if let Some(polar) = polar.as_mut() {
                polar.push(p);
            }
        };
        let tip = self.params.tip_radius;
        // What the tip traced from inside sits in a groove: a frame's as the cell assumes
        // it, the ring gauge's as certified (engine::stylus).
        let (traced, groove) = match msg.target {
            RawScan::TARGET_FRAME => (Traced::Inside, self.params.frame_groove),
            RawScan::TARGET_RING_GAUGE => (Traced::Inside, Groove::new(self.params.ring_groove_angle, 0.0)),
            _ => (Traced::Outside, Groove::default()),
        };
        let offset = match traced {
            Traced::Inside => contact_offset(tip, groove.angle),
            Traced::Outside => tip,
        };
        // With a height channel, each point's height above the holder's plane, the axis's
        // tilt taken at the ball's centre (engine::height).
        let tilt = self.params.axis_tilt_in_force();
        let above = |centres: &mut dyn Iterator<Item = Vector2<f64>>| -> Vec<f64> {
            centres.zip(&raw_heights).map(|(c, h)| tilt.height_above(&c, *h)).collect()
        };
        let heights = if tip == 0.0 {
            corrector.correct_counts(&msg.step, &msg.counts, self.params.meters_per_count, emit);
            above(&mut points.iter().map(|p| Vector2::new(p.x, p.y)))
        } else {
            // The tip's centre first, then the surface it touched (engine::stylus).
            let mut path = Vec::with_capacity(n);
            corrector.correct_counts(&msg.step, &msg.counts, self.params.meters_per_count, |p| path.push(p));
            let heights = above(&mut path.iter().copied());
            let closed = goes_round(&msg.step, steps_per_rev);
            touched_surface(&mut path, offset, traced, closed);
            path.into_iter().for_each(&mut emit);
            heights
        };
        points.iter_mut().zip(&heights).for_each(|(p, z)| p.z = *z);
        if let Some((index, p)) = out_of_range {
            return Err(self.reject(msg, ScanRejected::OutOfRange { index, x: p.x, y: p.y }));
        }
        let max_gap = default_max_gap(steps_per_rev);
        let (radii, radii_gain) =
            polar.and_then(|polar| polar.resample_with_gain(self.params.resample_points, max_gap)).unwrap_or_default();
        // The size figures, when the contour goes all the way round (engine::size), with the
        // calibration's whole covariance when it is known.
        let surface: Vec<Vector2<f64>> = points.iter().map(|p| Vector2::new(p.x, p.y)).collect();
        let resampled = if radii.is_empty() { resample_radii(&surface, SIZE_RADII, max_gap) } else { None };
        let sized = if radii.is_empty() { resampled.as_deref() } else { Some(radii.as_slice()) };
        let covariance = self.params.covariance_in_force();
        let correction = Correction {
            mounting,
            tip_radius: tip,
            traced,
            groove,
            angle_orders: angle.orders(),
            noise: self.params.trace_noise(),
        };
        let report = sized.and_then(|r| size::uncertainty(&surface, r, &radii_gain, &correction, covariance.as_ref()));
        let header = Header { stamp: msg.header.stamp, frame_id: self.params.output_frame_id.clone() };
        let polygon = with_polygon.then(|| PolygonStamped {
            header: header.clone(),
            polygon: Polygon {
                points: points.iter().map(|p| Point32 { x: p.x as f32, y: p.y as f32, z: p.z as f32 }).collect(),
            },
        });
        // The third dimension, when the scan has heights and the contour goes round.
        let frame = report
            .as_ref()
            .filter(|_| !heights.is_empty())
            .and_then(|r| Frame3d::of(&r.sizes, &surface, &heights, self.params.height_meters_per_count));
        let (figures, size_u95, radii_u95) = match report {
            Some(r) => (r.sizes.figures(), r.u95, if radii.is_empty() { Vec::new() } else { r.radii_u95 }),
            None => ([0.0; 4], [0.0; 4], Vec::new()),
        };
        let (circumference_3d, circumference_3d_u95, frame_curve) = match &frame {
            Some(f) => (
                f.circumference,
                f.circumference_u95(figures[0], size_u95[0], &tilt.slope_covariance()),
                f.frame_curve(),
            ),
            None => (figures[0], size_u95[0], 0.0),
        };
        let contour = Contour {
            header,
            scan_id: msg.scan_id,
            target: msg.target,
            calibrated: calibration.is_some(),
            points,
            radii,
            circumference: figures[0],
            box_width: figures[1],
            box_height: figures[2],
            effective_diameter: figures[3],
            size_u95,
            radii_u95,
            calibration_stamp: if calibration.is_some() { self.in_force.ros_time } else { Time::ZERO },
            calibration_scan_id: if calibration.is_some() { self.in_force.scan_id } else { 0 },
            circumference_3d,
            circumference_3d_u95,
            frame_curve,
        };
        self.stats.contours_published += 1;
        Ok(Corrected { contour, polygon })
    }
}

/// Are the first and last samples of a scan neighbours round the turn (within the
/// largest gap a scan that goes all the way round may have)?
fn goes_round(steps: &[u32], steps_per_rev: u32) -> bool {
    let (Some(&first), Some(&last)) = (steps.first(), steps.last()) else { return false };
    let n = steps_per_rev.max(1);
    let gap = (u64::from(first) + u64::from(n) - u64::from(last)) % u64::from(n);
    steps.len() > 2 && gap as f64 * std::f64::consts::TAU / f64::from(n) <= default_max_gap(n)
}
