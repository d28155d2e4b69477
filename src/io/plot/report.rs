//! The calibration report: the contour and residual panels side by side, the fit summary
//! under them, in one picture.

use super::CalibrationReport;
use super::contour::contour_panel;
use super::residuals::residual_panel;
use super::svg::{PANEL_H, PANEL_W, summary_box, titled, wrap};

/// Contours and residuals side by side, the summary text below, in one SVG.
pub fn calibration_report_svg(report: &CalibrationReport<'_>) -> String {
    let width = 2.0 * PANEL_W;
    let header = 40.0;
    let line_h = 17.0;
    let char_w = 7.3; // monospace at 12 px
    let max_chars = ((width - 40.0) / char_w) as usize;
    let lines = wrap(report.summary, max_chars);
    let text_h = if lines.is_empty() { 10.0 } else { 16.0 + line_h * lines.len() as f64 };
    let height = header + PANEL_H + text_h;
    let mut out = titled(width, height, 27, report.title);
    contour_panel(&mut out, 0.0, header, PANEL_W, PANEL_H, &report.contours);
    residual_panel(&mut out, PANEL_W, header, PANEL_W, PANEL_H, &report.residuals);
    if !lines.is_empty() {
        summary_box(&mut out, header + PANEL_H, width - 24.0, text_h - 8.0, line_h, &lines);
    }
    out.push_str("</svg>\n");
    out
}
