//! One revolution as CSV: a header line `step,counts`, then one sample a line.
//!
//! ```text
//! step,counts
//! 0,24512
//! 1,24498
//! ```
//!
//! Blank lines and lines starting with `#` are skipped. Every error names the file
//! and line.

use std::fmt::Write as _;
use std::path::Path;

use super::{FileError, ParseError};

/// A revolution as the tracer reports it: steps and encoder counts.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct RawRevolution {
    pub step: Vec<u32>,
    pub counts: Vec<i32>,
}

/// Parse CSV text; `path` names the file in errors.
pub fn parse(text: &str, path: &str) -> Result<RawRevolution, ParseError> {
    let mut out = RawRevolution::default();
    let mut header_seen = false;
    for (i, raw) in text.lines().enumerate() {
        let line_no = i + 1;
        let line = raw.trim();
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        let fields: Vec<&str> = line.split(',').map(str::trim).collect();
        if !header_seen {
            if fields != ["step", "counts"] {
                return Err(ParseError(format!(
                    "{path}:{line_no}: expected the header line 'step,counts', got '{line}'"
                )));
            }
            header_seen = true;
            continue;
        }
        if fields.len() != 2 {
            return Err(ParseError(format!(
                "{path}:{line_no}: expected two values 'step,counts', got {} in '{line}'",
                fields.len()
            )));
        }
        let step = fields[0]
            .parse::<u32>()
            .map_err(|_| ParseError(format!("{path}:{line_no}: step '{}' is not a whole number >= 0", fields[0])))?;
        let counts = fields[1].parse::<i32>().map_err(|_| {
            ParseError(format!("{path}:{line_no}: counts '{}' is not a whole number (32-bit)", fields[1]))
        })?;
        out.step.push(step);
        out.counts.push(counts);
    }
    if !header_seen {
        return Err(ParseError(format!("{path}: empty file: expected the header line 'step,counts' and samples")));
    }
    Ok(out)
}

/// Read a CSV file.
pub fn read(path: &Path) -> Result<RawRevolution, FileError> {
    let shown = path.display().to_string();
    let text = std::fs::read_to_string(path).map_err(|source| FileError::Unreadable { path: shown.clone(), source })?;
    parse(&text, &shown).map_err(FileError::Malformed)
}

/// The CSV text of a revolution.
pub fn render(rev: &RawRevolution) -> String {
    let mut out = String::from("step,counts\n");
    for (s, c) in rev.step.iter().zip(&rev.counts) {
        let _ = writeln!(out, "{s},{c}");
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trip_and_errors() {
        let rev = RawRevolution { step: vec![3, 4], counts: vec![-5, 22500] };
        assert_eq!(parse(&render(&rev), "f").unwrap(), rev);
        assert_eq!(parse("# comment\nstep, counts\n\n1,2\n", "f").unwrap().step, [1]);
        assert_eq!(
            parse("steps,count\n", "f.csv").unwrap_err().to_string(),
            "f.csv:1: expected the header line 'step,counts', got 'steps,count'"
        );
        assert_eq!(
            parse("step,counts\n1,2,3\n", "f.csv").unwrap_err().to_string(),
            "f.csv:2: expected two values 'step,counts', got 3 in '1,2,3'"
        );
        assert_eq!(
            parse("step,counts\n-1,2\n", "f.csv").unwrap_err().to_string(),
            "f.csv:2: step '-1' is not a whole number >= 0"
        );
        assert_eq!(
            parse("step,counts\n1,NaN\n", "f.csv").unwrap_err().to_string(),
            "f.csv:2: counts 'NaN' is not a whole number (32-bit)"
        );
        assert_eq!(
            parse("", "f.csv").unwrap_err().to_string(),
            "f.csv: empty file: expected the header line 'step,counts' and samples"
        );
    }
}
