//! SVG pictures of a calibration, so a technician sees at a glance whether a plate fit is good.
//!
//! - [`contours_svg`]: raw (uncorrected) and corrected contour points, and optionally a
//!   reference outline (e.g. the fitted plate), with equal scaling on both axes, in mm.
//!   A good fit puts the corrected points on the reference outline.
//! - [`residuals_svg`]: each sample's fit residual in µm against its angle in degrees; used
//!   samples as blue dots, rejected ones (outliers) as red crosses, the zero line and ±3σ
//!   (σ = the RMS of the used residuals). A good fit is a flat band of noise with no pattern.
//! - [`calibration_report_svg`]: both side by side in one picture, with the fit summary.
//! - [`history_svg`]: a tracer's calibrations over time, alpha0, d and dL with their
//!   error bars, so drift (and a tracer knocked out of true) shows at a glance.
//!
//! Pure string generation: inputs are plain data in SI units (metres, radians); the
//! pictures show millimetres, micrometres and degrees. Points with a non-finite coordinate
//! are skipped (a polyline is broken there); empty inputs give empty axes, not a panic.
//! The frame is the output frame: x to the right, y up, angles counter-clockwise from +x.
//!
//! The files, by what they draw:
//! - `svg.rs`: the document around a picture (XML header, background, the summary box under
//!   the panels), text escaping and wrapping, and the sizes and colours shared by the panels.
//! - `axes.rs`: a panel's frame, grid, ticks (numbers and dates) and axis labels, and the
//!   "no data" note.
//! - `legend.rs`: the legend under a panel and its markers (dot, ring, cross, plus, triangle,
//!   line).
//! - `contour.rs`: the contour panel, [`contours_svg`].
//! - `residuals.rs`: the residual panel, [`residuals_svg`].
//! - `report.rs`: both panels and the fit summary in one picture, [`calibration_report_svg`].
//! - `history.rs`: the three stacked panels of a calibration history, [`history_svg`].
//! - `tests.rs`: the checks of all of them (and sample pictures to look at, `--ignored`).

use nalgebra::Vector2;

mod axes;
mod contour;
mod history;
mod legend;
mod report;
mod residuals;
mod svg;
#[cfg(test)]
mod tests;

pub use contour::contours_svg;
pub use history::history_svg;
pub use report::calibration_report_svg;
pub use residuals::residuals_svg;
pub use svg::xml_escape;

/// A polyline drawn under the points, e.g. the fitted plate outline.
#[derive(Debug, Clone, Copy)]
pub struct Outline<'a> {
    /// Legend text.
    pub label: &'a str,
    /// Vertices, metres.
    pub points: &'a [Vector2<f64>],
    /// Whether the last vertex joins the first.
    pub closed: bool,
}

/// What [`contours_svg`] draws.
#[derive(Debug, Clone, Copy)]
pub struct ContourPlot<'a> {
    /// Title above the plot.
    pub title: &'a str,
    /// Points as the uncalibrated tracer reports them, metres.
    pub raw: &'a [Vector2<f64>],
    /// The same points corrected with the calibration, metres.
    pub corrected: &'a [Vector2<f64>],
    /// Optional outline to compare with, e.g. the fitted plate.
    pub reference: Option<Outline<'a>>,
}

/// One sample's residual, for [`residuals_svg`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ResidualSample {
    /// The sample's angle, radians (any turn; shown in [0°, 360°)).
    pub angle: f64,
    /// Fit residual, metres.
    pub residual: f64,
    /// Whether the fit used the sample (false: rejected as an outlier).
    pub used: bool,
}

/// What [`residuals_svg`] draws.
#[derive(Debug, Clone, Copy)]
pub struct ResidualPlot<'a> {
    /// Title; the RMS and the sample counts are appended.
    pub title: &'a str,
    /// The samples, in any order (e.g. scan order).
    pub samples: &'a [ResidualSample],
}

/// What [`calibration_report_svg`] draws.
#[derive(Debug, Clone, Copy)]
pub struct CalibrationReport<'a> {
    /// Title above both plots.
    pub title: &'a str,
    /// The left plot.
    pub contours: ContourPlot<'a>,
    /// The right plot.
    pub residuals: ResidualPlot<'a>,
    /// The fit summary, printed under the plots (wrapped; `\n` starts a new line).
    pub summary: &'a str,
}

/// One calibration of a history, for [`history_svg`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HistoryPoint {
    /// When it was applied, seconds since 1970-01-01 UTC.
    pub time: f64,
    /// `[alpha0 (rad), offset (m), delta_l (m)]`.
    pub values: [f64; 3],
    /// Their standard uncertainties, if known.
    pub stddev: Option<[f64; 3]>,
    /// Drawn in red, parameter by parameter: it moved further from the one before than
    /// the drift limit.
    pub flagged: [bool; 3],
}

/// What [`history_svg`] draws.
#[derive(Debug, Clone, Copy)]
pub struct HistoryPlot<'a> {
    /// Title above the three panels.
    pub title: &'a str,
    /// The calibrations, oldest first.
    pub points: &'a [HistoryPoint],
    /// Error bars are ±`coverage` standard uncertainties.
    pub coverage: f64,
    /// Legend text of a flagged point.
    pub flagged_label: &'a str,
    /// Printed under the panels (wrapped; `\n` starts a new line).
    pub summary: &'a str,
}
