//! The contour panel: raw and corrected points over the reference outline, equal scaling,
//! in mm; alone in a picture, [`contours_svg`].

use std::fmt::Write as _;

use nalgebra::Vector2;

use super::ContourPlot;
use super::axes::{Axis, Frame, decimals, draw_axes, nice_step, no_data, ticks};
use super::legend::{Marker, draw_legend, plus_path};
use super::svg::{C_CORRECTED, M_BOTTOM, M_LEFT, M_RIGHT, M_TOP, one_panel};

const C_RAW: &str = "#ff7f0e";
const C_REFERENCE: &str = "#222222";

/// The raw and corrected contours (and the reference outline) in one plot, equal scaling,
/// axes in mm.
pub fn contours_svg(plot: &ContourPlot<'_>) -> String {
    one_panel(|out, x0, y0, w, h| contour_panel(out, x0, y0, w, h, plot))
}

fn finite(p: &Vector2<f64>) -> bool {
    p.x.is_finite() && p.y.is_finite()
}

/// `points="..."` lists of a polyline in mm, broken at non-finite points.
fn polyline_runs(f: &Frame, points: &[Vector2<f64>], closed: bool) -> Vec<String> {
    let mut runs: Vec<Vec<&Vector2<f64>>> = vec![Vec::new()];
    for p in points {
        if finite(p) {
            runs.last_mut().expect("never empty").push(p);
        } else if !runs.last().expect("never empty").is_empty() {
            runs.push(Vec::new());
        }
    }
    // Closing joins the last run to the first when the outline has no gap at the seam.
    let all_finite = points.iter().all(finite);
    runs.retain(|r| !r.is_empty());
    let mut out = Vec::new();
    for run in &runs {
        let mut s = String::new();
        for p in run.iter().copied().chain((closed && all_finite).then(|| run[0])) {
            let _ = write!(s, "{:.2},{:.2} ", f.px(p.x * 1e3), f.py(p.y * 1e3));
        }
        out.push(s.trim_end().to_string());
    }
    out
}

pub(super) fn contour_panel(out: &mut String, x0: f64, y0: f64, w: f64, h: f64, plot: &ContourPlot<'_>) {
    let reference_points = plot.reference.map(|r| r.points).unwrap_or(&[]);
    let all = plot.raw.iter().chain(plot.corrected).chain(reference_points).filter(|p| finite(p));
    let (mut xmin, mut xmax, mut ymin, mut ymax) = (f64::INFINITY, f64::NEG_INFINITY, f64::INFINITY, f64::NEG_INFINITY);
    let mut any = false;
    for p in all {
        any = true;
        xmin = xmin.min(p.x * 1e3);
        xmax = xmax.max(p.x * 1e3);
        ymin = ymin.min(p.y * 1e3);
        ymax = ymax.max(p.y * 1e3);
    }
    if !any {
        (xmin, xmax, ymin, ymax) = (-1.0, 1.0, -1.0, 1.0);
    }
    // Equal scaling: one mm is as long on x as on y; the data fill the area as far as
    // that allows, with a margin.
    let (pw, ph) = (w - M_LEFT - M_RIGHT, h - M_TOP - M_BOTTOM);
    let span = (xmax - xmin).max(ymax - ymin).max(1e-3);
    let pad = 0.06 * span;
    let (dx, dy) = ((xmax - xmin) + 2.0 * pad, (ymax - ymin) + 2.0 * pad);
    let scale = (pw / dx).min(ph / dy); // px per mm
    let (cx, cy) = ((xmin + xmax) / 2.0, (ymin + ymax) / 2.0);
    let (hx, hy) = (pw / scale / 2.0, ph / scale / 2.0);
    let f =
        Frame { x0: x0 + M_LEFT, y0: y0 + M_TOP, w: pw, h: ph, xlo: cx - hx, xhi: cx + hx, ylo: cy - hy, yhi: cy + hy };
    let step = nice_step(2.0 * hx.max(hy), 8.0);
    let dec = decimals(step);
    let x_axis = Axis { ticks: ticks(f.xlo, f.xhi, step), decimals: dec, label: "x [mm]", labels: Vec::new() };
    let y_axis = Axis { ticks: ticks(f.ylo, f.yhi, step), decimals: dec, label: "y [mm]", labels: Vec::new() };
    let _ = writeln!(out, r#"<g class="contour-panel">"#);
    draw_axes(out, &f, plot.title, &x_axis, &y_axis);

    let mut legend = Vec::new();
    let count = |pts: &[Vector2<f64>]| pts.iter().filter(|p| finite(p)).count();
    let _ = writeln!(out, r#"<g class="raw" fill="none" stroke="{C_RAW}" stroke-width="1">"#);
    for p in plot.raw.iter().filter(|p| finite(p)) {
        let _ = writeln!(out, r#"<circle cx="{:.2}" cy="{:.2}" r="2.3"/>"#, f.px(p.x * 1e3), f.py(p.y * 1e3));
    }
    out.push_str("</g>\n");
    legend.push((Marker::Ring(C_RAW), format!("raw, uncorrected ({})", count(plot.raw))));
    let _ = writeln!(out, r#"<g class="corrected" fill="{C_CORRECTED}">"#);
    for p in plot.corrected.iter().filter(|p| finite(p)) {
        let _ = writeln!(out, r#"<circle cx="{:.2}" cy="{:.2}" r="1.7"/>"#, f.px(p.x * 1e3), f.py(p.y * 1e3));
    }
    out.push_str("</g>\n");
    legend.push((Marker::Dot(C_CORRECTED), format!("corrected ({})", count(plot.corrected))));
    // The reference on top: a thin line through the corrected points when the fit is good.
    if let Some(reference) = plot.reference {
        let _ = writeln!(
            out,
            r#"<g class="reference" fill="none" stroke="{C_REFERENCE}" stroke-width="1" stroke-linejoin="round">"#
        );
        for run in polyline_runs(&f, reference.points, reference.closed) {
            let _ = writeln!(out, r#"<polyline points="{run}"/>"#);
        }
        out.push_str("</g>\n");
        legend.push((Marker::Line { color: C_REFERENCE, dash: "none" }, reference.label.to_string()));
    }
    // The rotation axis: the frame's origin.
    if f.xlo < 0.0 && 0.0 < f.xhi && f.ylo < 0.0 && 0.0 < f.yhi {
        let _ = writeln!(
            out,
            r#"<path class="origin" d="{}" stroke="black" stroke-width="1.2" fill="none"/>"#,
            plus_path(f.px(0.0), f.py(0.0), 6.0)
        );
    }
    legend.push((Marker::Plus("black"), "rotation axis".to_string()));
    if !any {
        no_data(out, &f);
    }
    draw_legend(out, &f, &legend);
    out.push_str("</g>\n");
}
