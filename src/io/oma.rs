//! Trace records of the VCA Data Communication Standard ("OMA files"), as edgers read them.
//!
//! An OMA file is a list of records `LABEL=VALUE`, one a line, CRLF line ends. A trace is
//! a `TRCFMT` record followed by its `R=` records:
//!
//! ```text
//! JOB=4711
//! TRCFMT=1;400;E;R;F
//! R=2350;2351;2353;2356;2360;2365;2371;2378;2386;2395
//! R=...
//! TRCFMT=1;400;E;L;F
//! R=...
//! ```
//!
//! - `TRCFMT=format;N;E|U;eye;type`: format 1 = ASCII (the only one read or written here;
//!   2, 3 and 4 are differential and binary encodings, not read yet: a warning); `N`
//!   points; `E` = equiangular, `U` = not (then `A=` records give each point's angle);
//!   eye `R`, `L` or `B` (both); trace type ([`TraceType`]).
//! - `R=`: the radii, whole numbers in 1/100 mm, `;`-separated, 10 a line here (a reader
//!   takes any number a line).
//! - `A=`: for a `U` trace, the angle of each point, whole numbers in 1/100 degree.
//! - `ZFMT=format;N;E|U;eye;type` after a trace, then its `Z=` records: the height of each
//!   of the trace's points (a tracer with a height channel), whole numbers in 1/100 mm,
//!   signed; `N`, `E|U` and the eye those of the trace before it of that eye
//!   ([`Trace::heights`]).
//! - Every dataset opens with its own `...FMT` record (`TRCFMT`, `ZFMT`, a job's lens
//!   thickness `STHKFMT`, ...), and the data records after it (`R=`, `A=`, `Z=`) are its:
//!   a dataset that is not a trace is kept as it is, its `R=` never taken for radii. A trace
//!   in a format not read (2-4, or a maker's own) is a warning naming its line
//!   ([`OmaFile::warnings`]), its records kept; the rest of the file is read.
//! - Every other record (`JOB`, `FCRV`, `CIRC`, ...) is kept as it is, not interpreted,
//!   except `JOB`, which [`OmaFile::job`] carries; chiral ones (`HBOX=right;left`) are read
//!   per eye with [`OmaFile::chiral`].
//!
//! # Angle convention (ours; state it to whoever reads the file)
//!
//! The standard's text was not at hand to confirm its angle origin and direction, so this
//! module uses **our output frame's convention**, the same as `Contour.radii`: point `i` of an
//! equiangular trace of `N` points lies at angle `i·2π/N`, measured **counter-clockwise from
//! the +x axis** of the output frame (`tracer_axis`: origin on the rotation axis, x to the
//! right and y up when looking at the traced shape the way the tracer's frame is drawn, z
//! towards the viewer). `A=` angles and [`Trace::angles`] follow the same convention. The
//! usual reading of the standard (point 0 on the horizontal axis at 0°, counter-clockwise)
//! matches this if our +x axis is the horizontal axis the edger expects; no mirroring for
//! left/right eyes is done here: the caller chooses the eye label and the shape. Labs'
//! files agree as far as they can show it: in each of seven public files holding both
//! eyes (docs/cli.md, *on files as labs' systems wrote them*; 360 and 1000 points, two
//! systems) the left trace is the right one mirrored about the 90°-270° line point for
//! point, `L_i = R_((N/2 - i) mod N)` to the 1/100 mm: one angle frame for both eyes, angles
//! running the same way for both. Which side of a right lens lies at 0° (nasal or
//! temporal) they do not show.
//!
//! Units: radii in metres in code (SI, like the rest of the crate), 1/100 mm in the file;
//! writing rounds to the nearest 1/100 mm.
//!
//! Errors are one line naming the line number (reading) or the trace (writing).

use std::fmt;
use std::fmt::Write as _;
use std::path::Path;

use super::{FileError, ParseError};

/// The only trace format read and written: ASCII absolute radii.
pub const FORMAT_ASCII: u32 = 1;

/// Values per `R=`/`A=` line when writing.
const PER_LINE: usize = 10;
/// Metres per file unit of radius (1/100 mm).
const METRES_PER_UNIT: f64 = 1e-5;
/// Degrees per file unit of angle (1/100 degree).
const DEGREES_PER_UNIT: f64 = 0.01;
/// The largest radius written, metres: anything larger is not a spectacle shape.
const MAX_RADIUS: f64 = 10.0;
/// Points preallocated for a trace at most, whatever its `TRCFMT` declares.
const MAX_PREALLOCATED_POINTS: usize = 10_000;

/// Which eye a trace is for (the fourth `TRCFMT` field).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Eye {
    /// `R`
    Right,
    /// `L`
    Left,
    /// `B`: one trace for both eyes.
    Both,
}

impl Eye {
    /// The letter in the file.
    pub fn code(self) -> &'static str {
        match self {
            Eye::Right => "R",
            Eye::Left => "L",
            Eye::Both => "B",
        }
    }

    /// The eye of a letter (case-insensitive), if it is one.
    pub fn from_code(code: &str) -> Option<Self> {
        match code.to_ascii_uppercase().as_str() {
            "R" => Some(Eye::Right),
            "L" => Some(Eye::Left),
            "B" => Some(Eye::Both),
            _ => None,
        }
    }
}

impl fmt::Display for Eye {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.code())
    }
}

/// What was traced (the fifth `TRCFMT` field).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum TraceType {
    /// `F`: the frame's groove (or bevel).
    Frame,
    /// `P`: a pattern.
    Pattern,
    /// `L`: a lens.
    Lens,
    /// `D`: the demo lens that came in the frame.
    DemoLens,
}

impl TraceType {
    /// The letter in the file.
    pub fn code(self) -> &'static str {
        match self {
            TraceType::Frame => "F",
            TraceType::Pattern => "P",
            TraceType::Lens => "L",
            TraceType::DemoLens => "D",
        }
    }

    /// The trace type of a letter (case-insensitive), if it is one.
    pub fn from_code(code: &str) -> Option<Self> {
        match code.to_ascii_uppercase().as_str() {
            "F" => Some(TraceType::Frame),
            "P" => Some(TraceType::Pattern),
            "L" => Some(TraceType::Lens),
            "D" => Some(TraceType::DemoLens),
            _ => None,
        }
    }
}

impl fmt::Display for TraceType {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.code())
    }
}

/// One eye's trace (format 1, ASCII).
#[derive(Debug, Clone, PartialEq)]
pub struct Trace {
    /// Which eye (`R`, `L`, `B`).
    pub eye: Eye,
    /// What was traced (`F`, `P`, `L`, `D`).
    pub trace_type: TraceType,
    /// Radii about the rotation axis, metres, in point order.
    pub radii: Vec<f64>,
    /// `None`: equiangular (`E`), point `i` at `i·2π/N`. `Some`: not equiangular (`U`), the
    /// angle of each point, radians, counter-clockwise from +x; same length as `radii`.
    pub angles: Option<Vec<f64>>,
    /// The height of each point (`ZFMT`/`Z=`), metres; same length as `radii`. `None`:
    /// no heights.
    pub heights: Option<Vec<f64>>,
}

impl Trace {
    /// An equiangular trace: `radii[i]` (metres) at angle `i·2π/N`, like `Contour.radii`.
    pub fn equiangular(eye: Eye, trace_type: TraceType, radii: Vec<f64>) -> Self {
        Trace { eye, trace_type, radii, angles: None, heights: None }
    }

    /// `N`, the number of points.
    pub fn n(&self) -> usize {
        self.radii.len()
    }

    /// Whether the points are at equal angles (`E`), with no `A=` records.
    pub fn is_equiangular(&self) -> bool {
        self.angles.is_none()
    }

    /// The format written and read: always [`FORMAT_ASCII`].
    pub fn format(&self) -> u32 {
        FORMAT_ASCII
    }

    /// The angle of point `i`, radians, counter-clockwise from +x.
    pub fn angle(&self, i: usize) -> f64 {
        match &self.angles {
            Some(a) => a[i],
            None => std::f64::consts::TAU * i as f64 / self.radii.len() as f64,
        }
    }
}

/// The traces of an OMA file, and its other records.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct OmaFile {
    /// The `JOB` record, if any; written first.
    pub job: Option<String>,
    /// The traces, in file order (one a `TRCFMT` block).
    pub traces: Vec<Trace>,
    /// Every other record, `(label, value)` in file order, not interpreted (e.g. `DO`,
    /// `HBOX`, another dataset's `STHKFMT` and its `R=` records, a trace in a format not
    /// read). Written after `JOB` and before the traces.
    pub other: Vec<(String, String)>,
    /// What was not read, one line each naming its line (a trace in a format not read): the
    /// rest of the file is.
    pub warnings: Vec<String>,
}

impl OmaFile {
    /// The first trace for `eye`, if any.
    pub fn trace(&self, eye: Eye) -> Option<&Trace> {
        self.traces.iter().find(|t| t.eye == eye)
    }

    /// The value of a chiral record (`LABEL=right;left`, e.g. `HBOX=52.00;52.10`) for
    /// `eye`: its first field for `R`, its second for `L`, for `B` the first that is not
    /// empty; `None` if the file has no such record or the field is empty. A value with no
    /// `;` at all is both eyes' (`CIRC=150.85` beside a right and a left trace of one frame,
    /// as a frame library writes it); `50.03;` is the right eye's alone.
    pub fn chiral(&self, label: &str, eye: Eye) -> Option<&str> {
        let (_, value) = self.other.iter().find(|(l, _)| l.eq_ignore_ascii_case(label))?;
        if !value.contains(';') {
            let both = value.trim();
            return (!both.is_empty()).then_some(both);
        }
        let mut fields = value.split(';').map(str::trim);
        let (right, left) = (fields.next().unwrap_or(""), fields.next().unwrap_or(""));
        let field = match eye {
            Eye::Right => right,
            Eye::Left => left,
            Eye::Both => {
                if right.is_empty() {
                    left
                } else {
                    right
                }
            }
        };
        (!field.is_empty()).then_some(field)
    }
}

/// Whether a record's label opens a dataset of its own (the standard's `...FMT` records:
/// `TRCFMT`, `ZFMT`, `STHKFMT`, ...): the data records after it (`R=`, `A=`, `Z=`) are its.
fn opens_dataset(label: &str) -> bool {
    label.len() > 3 && label.ends_with("FMT")
}

/// The data records of a dataset.
fn is_data(label: &str) -> bool {
    matches!(label, "R" | "A" | "Z" | "ZA")
}

/// A trace being read: its `TRCFMT` line and what has come so far.
struct Pending {
    line_no: usize,
    n: usize,
    trace: Trace,
    /// Angles in the file's units, for a `U` trace.
    angles: Vec<f64>,
}

impl Pending {
    /// Check the counts and hand over the trace.
    fn finish(self, path: &str) -> Result<Trace, ParseError> {
        let Pending { line_no, n, mut trace, angles } = self;
        if trace.radii.len() != n {
            return Err(ParseError(format!(
                "{path}:{line_no}: TRCFMT declares {n} points, the R= records that follow give {} radii",
                trace.radii.len()
            )));
        }
        if trace.angles.is_some() {
            if angles.len() != n {
                return Err(ParseError(format!(
                    "{path}:{line_no}: TRCFMT declares {n} points (not equiangular, U), the A= records that follow give {} angles",
                    angles.len()
                )));
            }
            trace.angles = Some(angles.iter().map(|a| (a * DEGREES_PER_UNIT).to_radians()).collect());
        }
        Ok(trace)
    }
}

/// Parse the `;`-separated whole numbers of an `R=` or `A=` record.
fn parse_values(value: &str, what: &str, unit: &str, path: &str, line_no: usize) -> Result<Vec<i64>, ParseError> {
    let mut out = Vec::new();
    let fields: Vec<&str> = value.split(';').map(str::trim).collect();
    for (k, field) in fields.iter().enumerate() {
        if field.is_empty() {
            if k + 1 == fields.len() && k > 0 {
                break; // a trailing ';'
            }
            return Err(ParseError(format!("{path}:{line_no}: empty {what} value (field {})", k + 1)));
        }
        let v = field
            .parse::<i64>()
            .map_err(|_| ParseError(format!("{path}:{line_no}: {what} '{field}' is not a whole number ({unit})")))?;
        out.push(v);
    }
    Ok(out)
}

/// What a trace format other than 1 is, for a message.
fn format_kind(format: u32) -> &'static str {
    match format {
        2 => " (ASCII differential)",
        3 | 4 => " (binary)",
        _ => " (not the standard's: a maker's own)",
    }
}

/// The format number of a `TRCFMT`/`ZFMT` value, if its first field is one.
fn format_of(value: &str) -> Option<u32> {
    value.split(';').next()?.trim().parse().ok()
}

/// Parse a `TRCFMT` value into a pending trace.
fn parse_trcfmt(value: &str, path: &str, line_no: usize) -> Result<Pending, ParseError> {
    let fields: Vec<&str> = value.split(';').map(str::trim).collect();
    if fields.len() < 5 {
        return Err(ParseError(format!(
            "{path}:{line_no}: TRCFMT needs 5 fields 'format;N;E|U;R|L|B;type', got {} in '{value}'",
            fields.len()
        )));
    }
    let format = fields[0]
        .parse::<u32>()
        .map_err(|_| ParseError(format!("{path}:{line_no}: TRCFMT format '{}' is not a number", fields[0])))?;
    // Another format never comes here: `parse` keeps its dataset aside with a warning.
    debug_assert_eq!(format, FORMAT_ASCII);
    let n = fields[1].parse::<usize>().map_err(|_| {
        ParseError(format!("{path}:{line_no}: TRCFMT point count '{}' is not a whole number", fields[1]))
    })?;
    if n == 0 {
        return Err(ParseError(format!("{path}:{line_no}: TRCFMT point count is 0")));
    }
    let equiangular = match fields[2].to_ascii_uppercase().as_str() {
        "E" => true,
        "U" => false,
        other => {
            return Err(ParseError(format!(
                "{path}:{line_no}: TRCFMT third field '{other}' is neither E (equiangular) nor U (angles given)"
            )));
        }
    };
    let eye = Eye::from_code(fields[3])
        .ok_or_else(|| ParseError(format!("{path}:{line_no}: TRCFMT eye '{}' is not R, L or B", fields[3])))?;
    let trace_type = TraceType::from_code(fields[4]).ok_or_else(|| {
        ParseError(format!(
            "{path}:{line_no}: TRCFMT trace type '{}' is not F (frame), P (pattern), L (lens) or D (demo lens)",
            fields[4]
        ))
    })?;
    Ok(Pending {
        line_no,
        n,
        trace: Trace {
            eye,
            trace_type,
            // `n` comes from the file: preallocate for real traces only, so that an absurd
            // count is the "declares N points" error at the end of the trace, not an abort.
            radii: Vec::with_capacity(n.min(MAX_PREALLOCATED_POINTS)),
            angles: if equiangular { None } else { Some(Vec::new()) },
            heights: None,
        },
        angles: Vec::new(),
    })
}

/// Parse OMA text; `path` names the file in errors. Lines may end in CRLF or LF; blank
/// lines are skipped. A file without `TRCFMT` records gives no traces (not an error).
pub fn parse(text: &str, path: &str) -> Result<OmaFile, ParseError> {
    let mut out = OmaFile::default();
    let mut pending: Option<Pending> = None;
    // A `ZFMT` block being read: the trace it belongs to, its line, its heights.
    let mut heights: Option<(usize, usize, Vec<f64>)> = None;
    let finish_heights = |out: &mut OmaFile, h: Option<(usize, usize, Vec<f64>)>| -> Result<(), ParseError> {
        if let Some((index, line_no, z)) = h {
            let n = out.traces[index].n();
            if z.len() != n {
                return Err(ParseError(format!(
                    "{path}:{line_no}: ZFMT declares {n} points, the Z= records that follow give {}",
                    z.len()
                )));
            }
            out.traces[index].heights = Some(z);
        }
        Ok(())
    };
    // A dataset not read (another `...FMT`, or a trace in a format not read): its records
    // are kept as they are.
    let mut foreign = false;
    // The eyes of traces not read.
    let mut not_read: Vec<Eye> = Vec::new();
    for (i, raw) in text.split('\n').enumerate() {
        let line_no = i + 1;
        let line = raw.trim_matches(|c: char| c.is_whitespace() || c == '\0');
        if line.is_empty() {
            continue;
        }
        let Some((label, value)) = line.split_once('=') else {
            let shown: String = line.chars().take(40).collect();
            return Err(ParseError(format!("{path}:{line_no}: expected a record LABEL=VALUE, got '{shown}'")));
        };
        let label = label.trim().to_ascii_uppercase();
        let value = value.trim();
        let skip = |what: &str| format!("{path}:{line_no}: {label}={value}: {what}; its records kept as they are");
        if opens_dataset(&label) {
            if let Some(p) = pending.take() {
                out.traces.push(p.finish(path)?);
            }
            finish_heights(&mut out, heights.take())?;
            let format = format_of(value);
            foreign = match label.as_str() {
                "TRCFMT" | "ZFMT" if format.is_some_and(|f| f != FORMAT_ASCII) => {
                    let f = format.unwrap_or_default();
                    out.warnings.push(skip(&format!("format {f}{} not read (only format 1)", format_kind(f))));
                    if label == "TRCFMT" {
                        not_read.extend(value.split(';').nth(3).and_then(Eye::from_code));
                    }
                    true
                }
                "ZFMT" => {
                    // The heights of a trace not read are not either; of no trace at all, an error.
                    let eye = value.split(';').nth(3).and_then(Eye::from_code);
                    let orphan = eye.is_some_and(|e| !out.traces.iter().any(|t| t.eye == e) && not_read.contains(&e));
                    if orphan {
                        out.warnings.push(skip("heights of a trace not read"));
                    }
                    orphan
                }
                "TRCFMT" => false,
                _ => true,
            };
        }
        if foreign && (opens_dataset(&label) || is_data(&label)) {
            out.other.push((label, value.to_string()));
            continue;
        }
        match label.as_str() {
            "TRCFMT" => {
                pending = Some(parse_trcfmt(value, path, line_no)?);
            }
            "ZFMT" => {
                let z = parse_trcfmt(value, path, line_no)?;
                let Some(index) = out.traces.iter().rposition(|t| t.eye == z.trace.eye) else {
                    return Err(ParseError(format!(
                        "{path}:{line_no}: ZFMT for eye {} before any trace of that eye",
                        z.trace.eye
                    )));
                };
                let t = &out.traces[index];
                if z.n != t.n() || z.trace.angles.is_some() != t.angles.is_some() {
                    return Err(ParseError(format!(
                        "{path}:{line_no}: ZFMT '{value}' does not match the {} trace of {} points before it",
                        if t.angles.is_some() { "U" } else { "E" },
                        t.n()
                    )));
                }
                heights = Some((index, line_no, Vec::with_capacity(z.n.min(MAX_PREALLOCATED_POINTS))));
            }
            "Z" => {
                let Some((index, zline, z)) = heights.as_mut() else {
                    return Err(ParseError(format!("{path}:{line_no}: Z= record before any ZFMT record")));
                };
                let n = out.traces[*index].n();
                for v in parse_values(value, "height", "1/100 mm", path, line_no)? {
                    if z.len() == n {
                        return Err(ParseError(format!(
                            "{path}:{line_no}: more heights than the {n} declared by ZFMT on line {zline}"
                        )));
                    }
                    z.push(v as f64 * METRES_PER_UNIT);
                }
            }
            "R" => {
                let Some(p) = pending.as_mut() else {
                    return Err(ParseError(format!("{path}:{line_no}: R= record before any TRCFMT record")));
                };
                for v in parse_values(value, "radius", "1/100 mm", path, line_no)? {
                    if v < 0 {
                        return Err(ParseError(format!("{path}:{line_no}: radius {v} is negative")));
                    }
                    if p.trace.radii.len() == p.n {
                        return Err(ParseError(format!(
                            "{path}:{line_no}: more radii than the {} declared by TRCFMT on line {}",
                            p.n, p.line_no
                        )));
                    }
                    p.trace.radii.push(v as f64 * METRES_PER_UNIT);
                }
            }
            "A" => {
                let Some(p) = pending.as_mut() else {
                    return Err(ParseError(format!("{path}:{line_no}: A= record before any TRCFMT record")));
                };
                if p.trace.angles.is_none() {
                    return Err(ParseError(format!(
                        "{path}:{line_no}: A= record in an equiangular (E) trace (TRCFMT on line {})",
                        p.line_no
                    )));
                }
                for v in parse_values(value, "angle", "1/100 degree", path, line_no)? {
                    if p.angles.len() == p.n {
                        return Err(ParseError(format!(
                            "{path}:{line_no}: more angles than the {} declared by TRCFMT on line {}",
                            p.n, p.line_no
                        )));
                    }
                    p.angles.push(v as f64);
                }
            }
            "JOB" if out.job.is_none() => out.job = Some(value.to_string()),
            _ => out.other.push((label, value.to_string())),
        }
    }
    if let Some(p) = pending.take() {
        out.traces.push(p.finish(path)?);
    }
    finish_heights(&mut out, heights.take())?;
    Ok(out)
}

/// Read an OMA file.
pub fn read(path: &Path) -> Result<OmaFile, FileError> {
    let shown = path.display().to_string();
    let bytes = std::fs::read(path).map_err(|source| FileError::Unreadable { path: shown.clone(), source })?;
    // OMA files are ASCII; be lenient with stray bytes rather than refuse the file.
    parse(&String::from_utf8_lossy(&bytes), &shown).map_err(FileError::Malformed)
}

/// Append `values` as `LABEL=v;v;...` lines, 10 a line, CRLF.
fn push_values(out: &mut String, label: &str, values: &[i64]) {
    for chunk in values.chunks(PER_LINE) {
        out.push_str(label);
        out.push('=');
        for (k, v) in chunk.iter().enumerate() {
            if k > 0 {
                out.push(';');
            }
            let _ = write!(out, "{v}");
        }
        out.push_str("\r\n");
    }
}

/// Check that a record value can be written on one line.
fn check_value(what: &str, value: &str) -> Result<(), RenderError> {
    if value.chars().any(|c| c.is_control()) {
        return Err(RenderError(format!(
            "{what} '{}' contains a line break or control character",
            value.escape_debug()
        )));
    }
    Ok(())
}

/// The text of an OMA file (CRLF line ends): `JOB` if given, the other records, then one
/// `TRCFMT` block a trace. Radii are rounded to 1/100 mm, angles to 1/100 degree (and
/// brought into [0°, 360°)).
pub fn render(file: &OmaFile) -> Result<String, RenderError> {
    let mut out = String::new();
    if let Some(job) = &file.job {
        check_value("JOB", job)?;
        let _ = write!(out, "JOB={job}\r\n");
    }
    for (label, value) in &file.other {
        if label.is_empty() || label.contains('=') || label.chars().any(|c| c.is_control() || c.is_whitespace()) {
            return Err(RenderError(format!("record label '{}' is not a plain label", label.escape_debug())));
        }
        check_value(label, value)?;
        let _ = write!(out, "{label}={value}\r\n");
    }
    for (t, trace) in file.traces.iter().enumerate() {
        let name = format!("trace {} ({} eye)", t + 1, trace.eye);
        let n = trace.radii.len();
        if n == 0 {
            return Err(RenderError(format!("{name}: no radii")));
        }
        let mut radii = Vec::with_capacity(n);
        for (k, &r) in trace.radii.iter().enumerate() {
            if !r.is_finite() || !(0.0..MAX_RADIUS).contains(&r) {
                return Err(RenderError(format!("{name}: radius {k} is {r} m, not a length in [0, {MAX_RADIUS}) m")));
            }
            radii.push((r / METRES_PER_UNIT).round() as i64);
        }
        let angles = match &trace.angles {
            None => None,
            Some(a) if a.len() != n => {
                return Err(RenderError(format!("{name}: {} angles for {n} radii", a.len())));
            }
            Some(a) => {
                let full = (360.0 / DEGREES_PER_UNIT) as i64;
                let mut units = Vec::with_capacity(n);
                for (k, &angle) in a.iter().enumerate() {
                    if !angle.is_finite() {
                        return Err(RenderError(format!("{name}: angle {k} is {angle}")));
                    }
                    units.push(((angle.to_degrees() / DEGREES_PER_UNIT).round() as i64).rem_euclid(full));
                }
                Some(units)
            }
        };
        let _ = write!(
            out,
            "TRCFMT={FORMAT_ASCII};{n};{};{};{}\r\n",
            if angles.is_some() { "U" } else { "E" },
            trace.eye,
            trace.trace_type
        );
        push_values(&mut out, "R", &radii);
        if let Some(units) = &angles {
            push_values(&mut out, "A", units);
        }
        if let Some(z) = &trace.heights {
            if z.len() != n {
                return Err(RenderError(format!("{name}: {} heights for {n} radii", z.len())));
            }
            let mut units = Vec::with_capacity(n);
            for (k, &h) in z.iter().enumerate() {
                if !h.is_finite() || h.abs() >= MAX_RADIUS {
                    return Err(RenderError(format!(
                        "{name}: height {k} is {h} m, not a length within {MAX_RADIUS} m"
                    )));
                }
                units.push((h / METRES_PER_UNIT).round() as i64);
            }
            let _ = write!(
                out,
                "ZFMT={FORMAT_ASCII};{n};{};{};{}\r\n",
                if angles.is_some() { "U" } else { "E" },
                trace.eye,
                trace.trace_type
            );
            push_values(&mut out, "Z", &units);
        }
    }
    Ok(out)
}

/// Why an OMA file was not rendered ([`render`]): a value the format cannot hold, in
/// words naming the trace or the record.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("{0}")]
pub struct RenderError(pub String);

/// Why an OMA file was not written ([`write()`]).
#[derive(Debug, thiserror::Error)]
pub enum WriteError {
    /// What was to be written is not an OMA file; nothing was written.
    #[error("{path}: {source}")]
    Unrenderable {
        /// The file, as given.
        path: String,
        /// What the format cannot hold.
        #[source]
        source: RenderError,
    },
    /// The file could not be written (no such directory, no permission, a full disk, ...).
    #[error("{path}: cannot write: {source}")]
    Unwritable {
        /// The file, as given.
        path: String,
        /// The system's reason.
        #[source]
        source: std::io::Error,
    },
}

/// Write an OMA file.
pub fn write(path: &Path, file: &OmaFile) -> Result<(), WriteError> {
    let shown = path.display().to_string();
    let text = render(file).map_err(|source| WriteError::Unrenderable { path: shown.clone(), source })?;
    std::fs::write(path, text).map_err(|source| WriteError::Unwritable { path: shown, source })
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::TAU;

    /// A rounded-rectangle-like lens shape, metres.
    fn shape(n: usize, scale: f64) -> Vec<f64> {
        (0..n)
            .map(|k| {
                let a = TAU * k as f64 / n as f64;
                scale * (0.025 + 0.004 * (2.0 * a).cos() + 0.0007 * (4.0 * a).cos() + 0.0003 * a.sin())
            })
            .collect()
    }

    #[test]
    fn round_trip_two_eyes() {
        let file = OmaFile {
            job: Some("4711".into()),
            traces: vec![
                Trace::equiangular(Eye::Right, TraceType::Frame, shape(400, 1.0)),
                Trace::equiangular(Eye::Left, TraceType::Lens, shape(400, 1.01)),
            ],
            other: vec![],
            warnings: Vec::new(),
        };
        let text = render(&file).unwrap();
        // CRLF everywhere, no bare LF.
        assert_eq!(text.matches('\n').count(), text.matches("\r\n").count());
        assert!(text.starts_with("JOB=4711\r\nTRCFMT=1;400;E;R;F\r\nR="));
        assert!(text.contains("\r\nTRCFMT=1;400;E;L;L\r\n"));
        // 40 R= lines of 10 values each per eye.
        let r_lines: Vec<&str> = text.lines().filter(|l| l.starts_with("R=")).collect();
        assert_eq!(r_lines.len(), 80);
        assert!(r_lines.iter().all(|l| l[2..].split(';').count() == 10));

        let back = parse(&text, "t.oma").unwrap();
        assert_eq!(back.job.as_deref(), Some("4711"));
        assert_eq!(back.traces.len(), 2);
        for (a, b) in file.traces.iter().zip(&back.traces) {
            assert_eq!((a.eye, a.trace_type, a.n()), (b.eye, b.trace_type, b.n()));
            assert!(b.is_equiangular());
            assert_eq!(b.format(), 1);
            for (ra, rb) in a.radii.iter().zip(&b.radii) {
                assert!((ra - rb).abs() <= 0.5e-5 + 1e-12, "{ra} vs {rb}");
            }
        }
        assert_eq!(back.trace(Eye::Left).unwrap().trace_type, TraceType::Lens);
        assert!(back.trace(Eye::Both).is_none());
        // Written again, the same text.
        assert_eq!(render(&back).unwrap(), text);
    }

    #[test]
    fn round_trip_partial_line_and_non_equiangular() {
        let radii = shape(13, 1.0);
        let angles: Vec<f64> = (0..13).map(|k| (k as f64 * 27.0 + 0.5).to_radians()).collect();
        let file = OmaFile {
            job: None,
            traces: vec![Trace {
                eye: Eye::Both,
                trace_type: TraceType::Pattern,
                radii,
                angles: Some(angles.clone()),
                heights: None,
            }],
            other: vec![("DO".into(), "B".into())],
            warnings: Vec::new(),
        };
        let text = render(&file).unwrap();
        assert!(text.starts_with("DO=B\r\nTRCFMT=1;13;U;B;P\r\nR="));
        assert_eq!(text.lines().filter(|l| l.starts_with("R=")).count(), 2);
        assert!(text.contains("\r\nA=50;2750;5450;"));
        let back = parse(&text, "t.oma").unwrap();
        let t = &back.traces[0];
        assert!(!t.is_equiangular());
        assert_eq!(back.other, vec![("DO".to_string(), "B".to_string())]);
        for (k, a) in angles.iter().enumerate() {
            assert!((t.angle(k) - a).abs() < 1e-9);
        }
    }

    #[test]
    fn angles_are_ours() {
        let t = Trace::equiangular(Eye::Right, TraceType::Frame, vec![0.02; 4]);
        assert_eq!(t.angle(0), 0.0);
        assert!((t.angle(1) - TAU / 4.0).abs() < 1e-15);
        // Negative angles are written in [0, 360).
        let file = OmaFile {
            traces: vec![Trace {
                eye: Eye::Right,
                trace_type: TraceType::Frame,
                radii: vec![0.02, 0.02],
                angles: Some(vec![-0.5f64.to_radians(), 359.996f64.to_radians()]),
                heights: None,
            }],
            ..Default::default()
        };
        assert!(render(&file).unwrap().contains("A=35950;0\r\n"));
    }

    #[test]
    fn heights_round_trip_as_z_records() {
        let mut t = Trace::equiangular(Eye::Right, TraceType::Frame, vec![0.025, 0.02, 0.025, 0.02]);
        t.heights = Some(vec![0.00213, -0.0001, 0.002134, 0.0]);
        let file = OmaFile { traces: vec![t], ..Default::default() };
        let text = render(&file).unwrap();
        assert!(text.contains("ZFMT=1;4;E;R;F\r\nZ=213;-10;213;0\r\n"), "{text}");
        let back = parse(&text, "x").unwrap();
        let z = back.traces[0].heights.as_ref().unwrap();
        assert!(z.iter().zip([0.00213, -0.0001, 0.00213, 0.0]).all(|(a, b)| (a - b).abs() < 1e-12), "{z:?}");
        // Heights that do not fit their trace: named.
        let e = parse("TRCFMT=1;3;E;R;F\r\nR=1;2;3\r\nZFMT=1;4;E;R;F\r\n", "f").unwrap_err().to_string();
        assert!(e.contains("f:3: ZFMT '1;4;E;R;F' does not match the E trace of 3 points"), "{e}");
        let e = parse("TRCFMT=1;3;E;R;F\r\nR=1;2;3\r\nZFMT=1;3;E;L;F\r\n", "f").unwrap_err().to_string();
        assert!(e.contains("f:3: ZFMT for eye L before any trace of that eye"), "{e}");
        let e = parse("TRCFMT=1;3;E;R;F\r\nR=1;2;3\r\nZFMT=1;3;E;R;F\r\nZ=1;2\r\n", "f").unwrap_err().to_string();
        assert!(e.contains("f:3: ZFMT declares 3 points, the Z= records that follow give 2"), "{e}");
        let e = parse("TRCFMT=1;3;E;R;F\r\nR=1;2;3\r\nZFMT=1;3;E;R;F\r\nZ=1;2;3;4\r\n", "f").unwrap_err().to_string();
        assert!(e.contains("f:4: more heights than the 3 declared by ZFMT on line 3"), "{e}");
        let e = parse("Z=1\r\n", "f").unwrap_err().to_string();
        assert!(e.contains("f:1: Z= record before any ZFMT record"), "{e}");
    }

    #[test]
    fn hand_made_fixture() {
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/hand_made.oma");
        let bytes = std::fs::read(&path).unwrap();
        // The fixture really is CRLF.
        assert!(bytes.windows(2).filter(|w| w == b"\r\n").count() >= 10);
        assert!(!bytes.windows(2).any(|w| w[1] == b'\n' && w[0] != b'\r'));
        let file = read(&path).unwrap();
        assert_eq!(file.job.as_deref(), Some("HAND-0001"));
        assert_eq!(file.other, vec![("DO".to_string(), "B".to_string())]);
        assert_eq!(file.traces.len(), 2);
        let r = file.trace(Eye::Right).unwrap();
        let l = file.trace(Eye::Left).unwrap();
        assert_eq!((r.trace_type, r.n(), r.is_equiangular()), (TraceType::Frame, 40, true));
        assert_eq!((l.trace_type, l.n(), l.is_equiangular()), (TraceType::Frame, 40, true));
        assert!((r.radii[0] - 0.02650).abs() < 1e-12);
        assert!((r.radii[10] - 0.01812).abs() < 1e-12);
        assert!((r.radii[39] - 0.02623).abs() < 1e-12);
        assert!((l.radii[0] - 0.02640).abs() < 1e-12);
        // Left is the right mirrored about the vertical axis: l(i) = r(20 - i).
        for i in 0..40 {
            let j = (60 - i) % 40;
            assert!((l.radii[i] - r.radii[j]).abs() < 1e-12, "point {i}");
        }
    }

    #[test]
    fn hand_made_literal_lf_and_padding() {
        // LF line ends, spaces around fields, a trailing ';', sag records to skip.
        let text = "REQ=FIL\nJOB=\"12\"\nTRCFMT= 1;10 ;E; R;F\nR=2500;2400;2300;2200;2100;2000;2100;2200;2300;2400;\n\
                    ZFMT=1;10;E;R;F\nZ=0;0;0;0;0;0;0;0;0;0\nTRCFMT=1;10;E;L;F\nR=2500;2400;2300;2200;2100\nR=2000;2100;2200;2300;2400\n";
        let file = parse(text, "x").unwrap();
        assert_eq!(file.job.as_deref(), Some("\"12\""));
        assert_eq!(file.traces.len(), 2);
        assert_eq!(file.traces[0].radii, file.traces[1].radii);
        assert!((file.traces[0].radii[5] - 0.02).abs() < 1e-12);
        assert_eq!(file.other.len(), 1);
        assert_eq!(file.other[0], ("REQ".to_string(), "FIL".to_string()));
        // The sag records are the right trace's heights.
        assert_eq!(file.traces[0].heights, Some(vec![0.0; 10]));
        assert_eq!(file.traces[1].heights, None);
        // No trace at all is not an error.
        assert!(parse("JOB=1\r\n", "x").unwrap().traces.is_empty());
    }

    fn err(text: &str) -> String {
        let e = parse(text, "f.oma").unwrap_err().to_string();
        assert!(!e.contains('\n'), "one line: {e}");
        e
    }

    #[test]
    fn read_errors() {
        let f = parse("JOB=1\r\nTRCFMT=4;512;E;R;F\r\nR=]\x09\x00\r\n", "f.oma").unwrap();
        assert!(f.traces.is_empty());
        assert_eq!(f.warnings.len(), 1);
        assert!(
            f.warnings[0].starts_with("f.oma:2: TRCFMT=4;512;E;R;F: format 4 (binary) not read"),
            "{:?}",
            f.warnings
        );
        let e = err("TRCFMT=1;3;E;R;F\r\nR=1;2\r\nTRCFMT=1;3;E;L;F\r\nR=1;2;3\r\n");
        assert!(e.starts_with("f.oma:1: TRCFMT declares 3 points, the R= records that follow give 2"), "{e}");
        let e = err("TRCFMT=1;3;E;R;F\r\nR=1;2\r\nR=3;4\r\n");
        assert!(e.starts_with("f.oma:3: more radii than the 3 declared by TRCFMT on line 1"), "{e}");
        let e = err("TRCFMT=1;3;E;R;F\r\nR=1;2.5;3\r\n");
        assert!(e.starts_with("f.oma:2: radius '2.5' is not a whole number"), "{e}");
        let e = err("TRCFMT=1;3;E;R;F\r\nR=1;;3\r\n");
        assert!(e.starts_with("f.oma:2: empty radius value"), "{e}");
        let e = err("TRCFMT=1;3;E;R;F\r\nR=1;-2;3\r\n");
        assert!(e.starts_with("f.oma:2: radius -2 is negative"), "{e}");
        let e = err("TRCFMT=1;0;E;R;F\r\n");
        assert!(e.starts_with("f.oma:1: TRCFMT point count is 0"), "{e}");
        let e = err("TRCFMT=1;x;E;R;F\r\n");
        assert!(e.starts_with("f.oma:1: TRCFMT point count 'x'"), "{e}");
        let e = err("TRCFMT=1;3;E;R\r\n");
        assert!(e.starts_with("f.oma:1: TRCFMT needs 5 fields"), "{e}");
        let e = err("TRCFMT=1;3;X;R;F\r\n");
        assert!(e.contains(":1: TRCFMT third field 'X'"), "{e}");
        let e = err("TRCFMT=1;3;E;Q;F\r\n");
        assert!(e.contains(":1: TRCFMT eye 'Q'"), "{e}");
        let e = err("TRCFMT=1;3;E;R;Z\r\n");
        assert!(e.contains(":1: TRCFMT trace type 'Z'"), "{e}");
        let e = err("JOB=1\r\nR=1;2;3\r\n");
        assert!(e.starts_with("f.oma:2: R= record before any TRCFMT"), "{e}");
        let e = err("JOB=1\r\n\r\nhello\r\n");
        assert!(e.starts_with("f.oma:3: expected a record LABEL=VALUE, got 'hello'"), "{e}");
        let e = err("TRCFMT=1;2;E;R;F\r\nR=1;2\r\nA=0;18000\r\n");
        assert!(e.starts_with("f.oma:3: A= record in an equiangular (E) trace"), "{e}");
        let e = err("TRCFMT=1;2;U;R;F\r\nR=1;2\r\nA=0\r\n");
        assert!(e.starts_with("f.oma:1: TRCFMT declares 2 points (not equiangular, U), the A= records"), "{e}");
        let e = err("TRCFMT=1;2;U;R;F\r\nR=1;2\r\nA=0;1;2\r\n");
        assert!(e.starts_with("f.oma:3: more angles"), "{e}");
    }

    /// Every dataset has its own `...FMT` record: a job's lens thickness (`STHKFMT` and its
    /// own `R=`) before the traces is kept as it is, not taken for a trace's radii.
    #[test]
    fn datasets_by_their_own_fmt_record() {
        let text = "JOB=7\r\nSTHKFMT=1;4;E;R\r\nR=2574;2659;2745;2838\r\nHBOX=50.00;\r\n\
                    TRCFMT=1;4;E;R;F\r\nR=2500;2400;2500;2400\r\nSTHKFMT=1;2;E;L\r\nR=10;20\r\n";
        let f = parse(text, "job.oma").unwrap();
        assert_eq!(f.traces.len(), 1);
        assert_eq!(f.traces[0].n(), 4);
        assert!((f.traces[0].radii[1] - 0.024).abs() < 1e-12);
        let labels: Vec<&str> = f.other.iter().map(|(l, _)| l.as_str()).collect();
        assert_eq!(labels, ["STHKFMT", "R", "HBOX", "STHKFMT", "R"]);
        assert_eq!(f.other[1].1, "2574;2659;2745;2838");
        assert!(f.warnings.is_empty());
        assert_eq!(f.chiral("HBOX", Eye::Right), Some("50.00"));
        assert_eq!(f.chiral("hbox", Eye::Left), None);
        assert_eq!(f.chiral("HBOX", Eye::Both), Some("50.00"));
        let one = parse("CIRC=150.85\r\nTRCFMT=1;4;E;R;F\r\nR=2500;2400;2500;2400\r\n", "lib.oma").unwrap();
        assert_eq!([Eye::Right, Eye::Left, Eye::Both].map(|e| one.chiral("CIRC", e)), [Some("150.85"); 3]);
        // Written back and read again: the same traces and records.
        let again = parse(&render(&f).unwrap(), "again.oma").unwrap();
        assert_eq!(again.traces, f.traces);
        assert_eq!(again.other, f.other);
    }

    /// A maker's own trace format is not read, said in one line naming it; the rest of the
    /// file is (its other eye's trace in format 1, the heights of the one not read skipped).
    #[test]
    fn a_format_not_read_leaves_the_rest() {
        let text = "TRCFMT=6;100;E;R;F\r\nR=AAECAwQ=\r\nZFMT=6;100;E;R;F\r\nZ=1\r\n\
                    TRCFMT=1;2;E;L;F\r\nR=2000;2100\r\nZFMT=1;2;E;L;F\r\nZ=5;-5\r\n";
        let f = parse(text, "maker.oma").unwrap();
        assert_eq!(f.traces.len(), 1);
        assert_eq!(f.traces[0].eye, Eye::Left);
        assert_eq!(f.traces[0].heights.as_deref(), Some(&[5e-5, -5e-5][..]));
        assert_eq!(f.warnings.len(), 2, "{:?}", f.warnings);
        assert!(
            f.warnings[0]
                .starts_with("maker.oma:1: TRCFMT=6;100;E;R;F: format 6 (not the standard's: a maker's own) not read"),
            "{}",
            f.warnings[0]
        );
        assert!(f.warnings[1].starts_with("maker.oma:3: ZFMT=6;100;E;R;F: format 6"), "{}", f.warnings[1]);
        assert!(f.warnings.iter().all(|w| !w.contains('\n')));
        assert_eq!(f.other.len(), 4);
    }

    #[test]
    fn write_errors() {
        let one = |radii: Vec<f64>| OmaFile {
            traces: vec![Trace::equiangular(Eye::Left, TraceType::Frame, radii)],
            ..Default::default()
        };
        let err = |f: &OmaFile| render(f).unwrap_err().to_string();
        assert_eq!(err(&one(vec![])), "trace 1 (L eye): no radii");
        assert!(err(&one(vec![0.02, f64::NAN])).starts_with("trace 1 (L eye): radius 1 is NaN m"));
        assert!(err(&one(vec![-0.01])).contains("radius 0 is -0.01 m"));
        let mut f = one(vec![0.02; 3]);
        f.traces[0].angles = Some(vec![0.0; 2]);
        assert_eq!(err(&f), "trace 1 (L eye): 2 angles for 3 radii");
        let mut f = one(vec![0.02; 3]);
        f.job = Some("a\r\nTRCFMT=4".into());
        assert!(err(&f).starts_with("JOB 'a\\r\\nTRCFMT=4' contains a line break"));
        let mut f = one(vec![0.02; 3]);
        f.other.push(("A=B".into(), "1".into()));
        assert!(err(&f).contains("is not a plain label"));
    }

    #[test]
    fn file_round_trip() {
        let dir = std::env::temp_dir().join(format!("tracer_calib_oma_{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("t.oma");
        let file = OmaFile {
            job: Some("7".into()),
            traces: vec![Trace::equiangular(Eye::Right, TraceType::Frame, shape(512, 1.0))],
            ..Default::default()
        };
        write(&path, &file).unwrap();
        let back = read(&path).unwrap();
        assert_eq!(back.traces[0].n(), 512);
        let missing = read(&dir.join("missing.oma")).unwrap_err();
        assert!(
            matches!(&missing, FileError::Unreadable { source, .. } if source.kind() == std::io::ErrorKind::NotFound)
        );
        assert!(missing.to_string().contains("missing.oma: cannot read"), "{missing}");
        std::fs::write(dir.join("bad.oma"), "JOB=1\r\nTRCFMT=1;0;E;R;F\r\n").unwrap();
        assert!(matches!(read(&dir.join("bad.oma")), Err(FileError::Malformed(_))));
        // Not written: what cannot be an OMA file, and what the system refuses.
        let empty = OmaFile { traces: vec![Trace::equiangular(Eye::Left, TraceType::Frame, vec![])], ..file };
        let e = write(&dir.join("empty.oma"), &empty).unwrap_err();
        assert!(matches!(&e, WriteError::Unrenderable { source, .. } if source.0 == "trace 1 (L eye): no radii"));
        assert!(e.to_string().ends_with("empty.oma: trace 1 (L eye): no radii"), "{e}");
        assert!(!dir.join("empty.oma").exists());
        let e = write(&dir.join("no/such/t.oma"), &back).unwrap_err();
        assert!(
            matches!(&e, WriteError::Unwritable { source, .. } if source.kind() == std::io::ErrorKind::NotFound),
            "{e}"
        );
        assert!(e.to_string().contains("t.oma: cannot write: "), "{e}");
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
