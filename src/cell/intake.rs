//! The checks of a raw scan, and the one conversion of a `RawScan` into an engine [`Scan`]:
//! the node and the offline tools (`calibrate --bag`, `correct`) take scans through here,
//! so a scan the node refuses is refused offline too, with the same words.

use crate::engine::scan::{Scan, ScanError};
use crate::interfaces::RawScan;

/// Why a raw scan was refused (counted as rejected; the words are the log's and
/// /diagnostics' `last_rejection`).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ScanRejected {
    /// `target` is none of the message's `TARGET_*` constants.
    #[error("target {0} is not one of TARGET_UNKNOWN..TARGET_RING_GAUGE (0..4)")]
    UnknownTarget(u8),
    /// `steps_per_revolution` above [`MAX_STEPS_PER_REV`].
    #[error("steps_per_revolution {0} is larger than the limit of {MAX_STEPS_PER_REV}")]
    TooManySteps(u32),
    /// More samples than [`MAX_SAMPLES`].
    #[error("the scan has {0} samples, more than the limit of {MAX_SAMPLES}")]
    TooLarge(usize),
    /// Fewer than 3 samples.
    #[error("the scan has {0} samples, at least 3 are needed for a contour")]
    TooSmall(usize),
    /// The samples themselves (a step out of range, a count not finite, ...).
    #[error(transparent)]
    Samples(#[from] ScanError),
    /// `height_counts` neither empty (no height channel) nor one a sample.
    #[error(
        "step has {samples} entries but height_counts has {heights} (one a sample, or none without a height channel)"
    )]
    HeightCounts {
        /// Entries of `step`.
        samples: usize,
        /// Entries of `height_counts`.
        heights: usize,
    },
    /// A corrected point beyond what a contour can hold (extreme parameters).
    #[error(
        "sample {index}: the corrected point ({x}, {y}) m is out of range (check encoder.meters_per_count and the calibration)"
    )]
    OutOfRange {
        /// The sample's index.
        index: usize,
        /// The corrected point, m.
        x: f64,
        /// The corrected point, m.
        y: f64,
    },
}

/// Largest scan accepted, in samples: far above any tracer (400-1000 steps a turn),
/// far below what would hurt the node.
pub const MAX_SAMPLES: usize = 1 << 16;
/// Largest `steps_per_revolution` accepted.
pub const MAX_STEPS_PER_REV: u32 = 1 << 20;

/// The checks of a raw scan that need no pass over its samples: the target, and sizes
/// within the limits.
pub fn check_limits(msg: &RawScan) -> Result<(), ScanRejected> {
    if msg.target > RawScan::TARGET_RING_GAUGE {
        return Err(ScanRejected::UnknownTarget(msg.target));
    }
    if msg.steps_per_revolution > MAX_STEPS_PER_REV {
        return Err(ScanRejected::TooManySteps(msg.steps_per_revolution));
    }
    if msg.step.len() > MAX_SAMPLES || msg.counts.len() > MAX_SAMPLES {
        return Err(ScanRejected::TooLarge(msg.step.len().max(msg.counts.len())));
    }
    if msg.step.len() < 3 {
        return Err(ScanRejected::TooSmall(msg.step.len()));
    }
    if !msg.height_counts.is_empty() && msg.height_counts.len() != msg.step.len() {
        return Err(ScanRejected::HeightCounts { samples: msg.step.len(), heights: msg.height_counts.len() });
    }
    Ok(())
}

/// Check a raw scan's samples, with encoder counts of `meters_per_count` metres; the error
/// says what is wrong.
pub fn check(msg: &RawScan, meters_per_count: f64) -> Result<(), ScanRejected> {
    check_limits(msg)?;
    Ok(Scan::check_counts(msg.steps_per_revolution, &msg.step, &msg.counts, meters_per_count)?)
}

/// The heights of a checked scan, metres (`height_counts` × `height_meters_per_count`);
/// empty without a height channel.
pub fn heights(msg: &RawScan, height_meters_per_count: f64) -> Vec<f64> {
    msg.height_counts.iter().map(|&c| f64::from(c) * height_meters_per_count).collect()
}

/// Check a raw scan and turn it into an engine scan; the error says what is wrong.
pub fn to_scan(msg: &RawScan, meters_per_count: f64) -> Result<Scan, ScanRejected> {
    check_limits(msg)?;
    Ok(Scan::from_counts(msg.steps_per_revolution, &msg.step, &msg.counts, meters_per_count)?)
}
