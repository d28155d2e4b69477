//! The residual panel: each sample's residual in µm against its angle, used and rejected
//! samples, the zero line and ±3σ; alone in a picture, [`residuals_svg`].

use std::fmt::Write as _;

use super::ResidualPlot;
use super::axes::{Axis, Frame, decimals, draw_axes, nice_step, no_data, ticks};
use super::legend::{Marker, cross_path, draw_legend, triangle_path};
use super::svg::{M_BOTTOM, M_LEFT, M_RIGHT, M_TOP, one_panel};

const C_USED: &str = "#1f77b4";
const C_REJECTED: &str = "#d62728";
const C_SIGMA: &str = "#d62728";

/// Residuals (µm) against angle (degrees): used samples as dots, rejected ones as crosses,
/// zero and ±3σ lines; the title gives the RMS of the used residuals.
pub fn residuals_svg(plot: &ResidualPlot<'_>) -> String {
    one_panel(|out, x0, y0, w, h| residual_panel(out, x0, y0, w, h, plot))
}

pub(super) fn residual_panel(out: &mut String, x0: f64, y0: f64, w: f64, h: f64, plot: &ResidualPlot<'_>) {
    let shown: Vec<(f64, f64, bool)> = plot
        .samples
        .iter()
        .filter(|s| s.angle.is_finite() && s.residual.is_finite())
        .map(|s| (s.angle.to_degrees().rem_euclid(360.0), s.residual * 1e6, s.used))
        .collect();
    let used: Vec<f64> = shown.iter().filter(|s| s.2).map(|s| s.1).collect();
    let n_rejected = shown.len() - used.len();
    let rms =
        if used.is_empty() { f64::NAN } else { (used.iter().map(|r| r * r).sum::<f64>() / used.len() as f64).sqrt() };
    let max_used = used.iter().fold(0.0f64, |m, r| m.max(r.abs()));
    let max_all = shown.iter().fold(0.0f64, |m, s| m.max(s.1.abs()));
    // The scale follows the used samples and ±3σ; rejected samples beyond it are drawn as
    // triangles on the edge, so one dust spike does not flatten the picture.
    let mut limit = if used.is_empty() { max_all } else { max_used.max(3.0 * rms) } * 1.15;
    if !(limit.is_finite() && limit > 0.0) {
        limit = 1.0;
    }
    let step = nice_step(2.0 * limit, 8.0);
    let limit = (limit / step - 1e-9).ceil() * step;

    let (pw, ph) = (w - M_LEFT - M_RIGHT, h - M_TOP - M_BOTTOM);
    let f = Frame { x0: x0 + M_LEFT, y0: y0 + M_TOP, w: pw, h: ph, xlo: 0.0, xhi: 360.0, ylo: -limit, yhi: limit };
    let title = if used.is_empty() {
        format!("{} — no samples used", plot.title)
    } else {
        format!("{} — RMS {:.2} µm ({} used, {} rejected)", plot.title, rms, used.len(), n_rejected)
    };
    let x_axis = Axis { ticks: ticks(0.0, 360.0, 45.0), decimals: 0, label: "sample angle [°]", labels: Vec::new() };
    let y_axis = Axis {
        ticks: ticks(-limit, limit, step),
        decimals: decimals(step),
        label: "residual [µm]",
        labels: Vec::new(),
    };
    let _ = writeln!(out, r#"<g class="residual-panel">"#);
    draw_axes(out, &f, &title, &x_axis, &y_axis);

    let _ = writeln!(
        out,
        r##"<line class="zero" x1="{:.2}" y1="{y:.2}" x2="{:.2}" y2="{y:.2}" stroke="#555555" stroke-width="1.2"/>"##,
        f.x0,
        f.x0 + f.w,
        y = f.py(0.0)
    );
    let mut legend = vec![(Marker::Dot(C_USED), format!("used ({})", used.len()))];
    legend.push((Marker::Cross(C_REJECTED), format!("rejected ({n_rejected})")));
    if rms.is_finite() && rms > 0.0 {
        let _ = writeln!(out, r#"<g class="sigma" stroke="{C_SIGMA}" stroke-width="1.2" stroke-dasharray="6 4">"#);
        for s in [3.0 * rms, -3.0 * rms] {
            let y = f.py(s);
            let _ = writeln!(out, r#"<line x1="{:.2}" y1="{y:.2}" x2="{:.2}" y2="{y:.2}"/>"#, f.x0, f.x0 + f.w);
        }
        out.push_str("</g>\n");
        for (s, text) in [(3.0 * rms, "+3σ"), (-3.0 * rms, "−3σ")] {
            let _ = writeln!(
                out,
                r#"<text x="{:.2}" y="{:.2}" text-anchor="end" fill="{C_SIGMA}" font-size="11">{text}</text>"#,
                f.x0 + f.w - 4.0,
                f.py(s) + if s > 0.0 { -4.0 } else { 12.0 }
            );
        }
        legend.push((Marker::Line { color: C_SIGMA, dash: "6 4" }, format!("±3σ = ±{:.2} µm", 3.0 * rms)));
    }
    let _ = writeln!(out, r#"<g class="used" fill="{C_USED}">"#);
    for &(a, r, _) in shown.iter().filter(|s| s.2) {
        let _ = writeln!(out, r#"<circle cx="{:.2}" cy="{:.2}" r="2"/>"#, f.px(a), f.py(r));
    }
    out.push_str("</g>\n");
    let _ = writeln!(out, r#"<g class="rejected" stroke="{C_REJECTED}" stroke-width="1.6" fill="none">"#);
    let mut off_scale = Vec::new();
    for &(a, r, _) in shown.iter().filter(|s| !s.2) {
        if r.abs() > limit {
            off_scale.push((a, r));
        } else {
            let _ = writeln!(out, r#"<path d="{}"/>"#, cross_path(f.px(a), f.py(r), 3.5));
        }
    }
    out.push_str("</g>\n");
    if !off_scale.is_empty() {
        let _ = writeln!(out, r#"<g class="off-scale" fill="{C_REJECTED}">"#);
        for &(a, r) in &off_scale {
            let up = r > 0.0;
            let tip = if up { f.y0 + 1.0 } else { f.y0 + f.h - 1.0 };
            let _ = writeln!(out, r#"<path d="{}"/>"#, triangle_path(f.px(a), tip, 4.5, up));
        }
        out.push_str("</g>\n");
        let worst = off_scale.iter().fold(0.0f64, |m, s| m.max(s.1.abs()));
        legend.push((
            Marker::Triangle(C_REJECTED),
            format!("rejected, off scale ({}, up to {:.0} µm)", off_scale.len(), worst),
        ));
    }
    if shown.is_empty() {
        no_data(out, &f);
    }
    draw_legend(out, &f, &legend);
    out.push_str("</g>\n");
}
