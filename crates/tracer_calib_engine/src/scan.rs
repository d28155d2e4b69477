//! One revolution of the tracer as the engine sees it: angle steps and encoder lengths.
//!
//! The ROS message (`RawScan`) and the CSV file carry encoder *counts*; the shell
//! multiplies by the encoder scale and builds a [`Scan`], which checks the structure
//! once, so that everything downstream can rely on it. Samples may be missing and need
//! not start at step 0; what is not allowed is a step outside the revolution, a length
//! that is not a finite number, or one step measured twice.

use std::fmt;

/// One sample: the angle step it was taken at and the encoder length, metres.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sample {
    pub step: u32,
    pub rho: f64,
}

/// A validated revolution.
#[derive(Debug, Clone, PartialEq)]
pub struct Scan {
    steps_per_rev: u32,
    samples: Vec<Sample>,
}

/// Why a scan is malformed. The messages name the offending sample.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum ScanError {
    ZeroStepsPerRevolution,
    LengthMismatch { steps: usize, lengths: usize },
    Empty,
    StepOutOfRange { index: usize, step: u32, steps_per_rev: u32 },
    NotFinite { index: usize },
    DuplicateStep { index: usize, step: u32 },
}

impl fmt::Display for ScanError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::ZeroStepsPerRevolution => write!(f, "steps_per_revolution is 0"),
            Self::LengthMismatch { steps, lengths } => {
                write!(f, "step has {steps} entries but counts has {lengths}: they must have the same length")
            }
            Self::Empty => write!(f, "the scan has no samples"),
            Self::StepOutOfRange { index, step, steps_per_rev } => write!(
                f,
                "sample {index}: step {step} is out of range (0 <= step < steps_per_revolution = {steps_per_rev})"
            ),
            Self::NotFinite { index } => write!(f, "sample {index}: the encoder length is not a finite number"),
            Self::DuplicateStep { index, step } => {
                write!(f, "sample {index}: step {step} was already measured earlier in this revolution")
            }
        }
    }
}

impl std::error::Error for ScanError {}

/// The samples of encoder counts: `rho = counts × meters_per_count`.
pub(crate) fn counts_to_samples<'a>(
    steps: &'a [u32],
    counts: &'a [i32],
    meters_per_count: f64,
) -> impl Iterator<Item = Sample> + 'a {
    steps.iter().zip(counts).map(move |(&step, &c)| Sample { step, rho: f64::from(c) * meters_per_count })
}

/// What makes `len` samples a scan: a revolution of at least one step, at least one
/// sample, every step within the revolution and seen once, every length finite.
fn check(steps_per_rev: u32, len: usize, samples: impl Iterator<Item = Sample>) -> Result<(), ScanError> {
    if steps_per_rev == 0 {
        return Err(ScanError::ZeroStepsPerRevolution);
    }
    if len == 0 {
        return Err(ScanError::Empty);
    }
    // A bitset over the steps seen; sized by the samples' steps, never by an absurd
    // steps_per_revolution.
    let mut seen = vec![0u64; len.div_ceil(64)];
    let mut seen_big = std::collections::HashSet::new();
    for (index, s) in samples.enumerate() {
        if s.step >= steps_per_rev {
            return Err(ScanError::StepOutOfRange { index, step: s.step, steps_per_rev });
        }
        if !s.rho.is_finite() {
            return Err(ScanError::NotFinite { index });
        }
        let k = s.step as usize;
        let fresh = if k < seen.len() * 64 {
            let (w, b) = (k / 64, 1u64 << (k % 64));
            let fresh = seen[w] & b == 0;
            seen[w] |= b;
            fresh
        } else {
            seen_big.insert(s.step)
        };
        if !fresh {
            return Err(ScanError::DuplicateStep { index, step: s.step });
        }
    }
    Ok(())
}

impl Scan {
    /// Build a scan from parallel arrays of steps and encoder lengths (metres).
    pub fn new(steps_per_rev: u32, steps: &[u32], rho: &[f64]) -> Result<Self, ScanError> {
        if steps_per_rev == 0 {
            return Err(ScanError::ZeroStepsPerRevolution);
        }
        if steps.len() != rho.len() {
            return Err(ScanError::LengthMismatch { steps: steps.len(), lengths: rho.len() });
        }
        Self::from_samples(steps_per_rev, steps.iter().zip(rho).map(|(&step, &rho)| Sample { step, rho }).collect())
    }

    /// The same samples with every length multiplied by `k` (an encoder scale): what the
    /// tracer measured in true lengths. An error if a length is then not finite.
    pub fn scaled(&self, k: f64) -> Result<Self, ScanError> {
        let samples = self.samples.iter().map(|s| Sample { step: s.step, rho: s.rho * k }).collect();
        Self::from_samples(self.steps_per_rev, samples)
    }

    /// Build a scan from encoder counts, `rho = counts × meters_per_count`, as the
    /// tracer reports them (`RawScan`, CSV files).
    pub fn from_counts(
        steps_per_rev: u32,
        steps: &[u32],
        counts: &[i32],
        meters_per_count: f64,
    ) -> Result<Self, ScanError> {
        Self::check_counts(steps_per_rev, steps, counts, meters_per_count)?;
        let samples = counts_to_samples(steps, counts, meters_per_count).collect();
        Ok(Scan { steps_per_rev, samples })
    }

    /// Check encoder counts as [`Self::from_counts`] does, without building the scan:
    /// for a caller that corrects the samples straight from the arrays
    /// ([`crate::Corrector::correct_counts`]).
    pub fn check_counts(
        steps_per_rev: u32,
        steps: &[u32],
        counts: &[i32],
        meters_per_count: f64,
    ) -> Result<(), ScanError> {
        if steps.len() != counts.len() {
            return Err(ScanError::LengthMismatch { steps: steps.len(), lengths: counts.len() });
        }
        check(steps_per_rev, steps.len(), counts_to_samples(steps, counts, meters_per_count))
    }

    /// Build a scan from samples.
    pub fn from_samples(steps_per_rev: u32, samples: Vec<Sample>) -> Result<Self, ScanError> {
        check(steps_per_rev, samples.len(), samples.iter().copied())?;
        Ok(Scan { steps_per_rev, samples })
    }

    pub fn steps_per_rev(&self) -> u32 {
        self.steps_per_rev
    }

    pub fn samples(&self) -> &[Sample] {
        &self.samples
    }

    pub fn len(&self) -> usize {
        self.samples.len()
    }

    pub fn is_empty(&self) -> bool {
        self.samples.is_empty()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn structure_is_checked_with_named_samples() {
        assert_eq!(Scan::new(0, &[0], &[1.0]), Err(ScanError::ZeroStepsPerRevolution));
        assert_eq!(Scan::new(400, &[0, 1], &[1.0]), Err(ScanError::LengthMismatch { steps: 2, lengths: 1 }));
        assert_eq!(Scan::new(400, &[], &[]), Err(ScanError::Empty));
        let e = Scan::new(400, &[0, 400], &[1.0, 1.0]).unwrap_err();
        assert_eq!(e.to_string(), "sample 1: step 400 is out of range (0 <= step < steps_per_revolution = 400)");
        assert_eq!(Scan::new(400, &[3, 4], &[1.0, f64::NAN]), Err(ScanError::NotFinite { index: 1 }));
        assert_eq!(Scan::new(400, &[3, 4, 3], &[1.0; 3]), Err(ScanError::DuplicateStep { index: 2, step: 3 }));
        assert_eq!(
            Scan::new(u32::MAX, &[4_000_000_000, 4_000_000_000], &[1.0; 2]),
            Err(ScanError::DuplicateStep { index: 1, step: 4_000_000_000 })
        );
        // Gaps and a start away from step 0 are fine.
        let s = Scan::new(400, &[390, 399, 0, 5], &[1.0; 4]).unwrap();
        assert_eq!(s.len(), 4);
    }
}
