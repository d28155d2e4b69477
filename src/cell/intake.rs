//! The checks of a raw scan, and the one conversion of a `RawScan` into an engine [`Scan`]:
//! the node and the offline tools (`calibrate --bag`, `correct`) take scans through here,
//! so a scan the node refuses is refused offline too, with the same words.

use crate::engine::scan::Scan;
use crate::interfaces::RawScan;

/// Largest scan accepted, in samples: far above any tracer (400-1000 steps a turn),
/// far below what would hurt the node.
pub const MAX_SAMPLES: usize = 1 << 16;
/// Largest `steps_per_revolution` accepted.
pub const MAX_STEPS_PER_REV: u32 = 1 << 20;

/// The checks of a raw scan that need no pass over its samples: the target, and sizes
/// within the limits.
pub fn check_limits(msg: &RawScan) -> Result<(), String> {
    if msg.target > RawScan::TARGET_RING_GAUGE {
        return Err(format!("target {} is not one of TARGET_UNKNOWN..TARGET_RING_GAUGE (0..4)", msg.target));
    }
    if msg.steps_per_revolution > MAX_STEPS_PER_REV {
        return Err(format!(
            "steps_per_revolution {} is larger than the limit of {MAX_STEPS_PER_REV}",
            msg.steps_per_revolution
        ));
    }
    if msg.step.len() > MAX_SAMPLES || msg.counts.len() > MAX_SAMPLES {
        return Err(format!(
            "the scan has {} samples, more than the limit of {MAX_SAMPLES}",
            msg.step.len().max(msg.counts.len())
        ));
    }
    if msg.step.len() < 3 {
        return Err(format!("the scan has {} samples, at least 3 are needed for a contour", msg.step.len()));
    }
    Ok(())
}

/// Check a raw scan's samples, with encoder counts of `meters_per_count` metres; the error
/// says what is wrong.
pub fn check(msg: &RawScan, meters_per_count: f64) -> Result<(), String> {
    check_limits(msg)?;
    Scan::check_counts(msg.steps_per_revolution, &msg.step, &msg.counts, meters_per_count).map_err(|e| e.to_string())
}

/// Check a raw scan and turn it into an engine scan; the error says what is wrong.
pub fn to_scan(msg: &RawScan, meters_per_count: f64) -> Result<Scan, String> {
    check_limits(msg)?;
    Scan::from_counts(msg.steps_per_revolution, &msg.step, &msg.counts, meters_per_count).map_err(|e| e.to_string())
}
