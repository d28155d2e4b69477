//! A calibration history: alpha0, d and dL in three stacked panels against the time each
//! calibration was applied, with error bars, the legend and the summary.

use std::fmt::Write as _;

use super::axes::{Axis, Frame, decimals, draw_axes, nice_step, no_data, ticks, time_ticks};
use super::legend::{Marker, draw_marker};
use super::svg::{C_CORRECTED, M_LEFT, M_RIGHT, M_TOP, summary_box, titled, wrap, xml_escape};
use super::{HistoryPlot, HistoryPoint};

pub(super) const C_FLAGGED: &str = "#d62728";
const C_TREND: &str = "#9a9a9a";
const HISTORY_W: f64 = 960.0;
const HISTORY_PANEL_H: f64 = 290.0;

/// Three panels stacked, alpha0 (degrees), d and dL (mm) against the time each calibration
/// was applied, with error bars of ±`coverage` standard uncertainties and a grey line
/// from each calibration to the next: drift, and a tracer knocked out of true, show at a
/// glance. Flagged calibrations are red.
pub fn history_svg(plot: &HistoryPlot<'_>) -> String {
    let header = 44.0;
    let legend_h = 40.0;
    let line_h = 17.0;
    let lines = wrap(plot.summary, ((HISTORY_W - 40.0) / 7.3) as usize);
    let text_h = if lines.is_empty() { 0.0 } else { 16.0 + line_h * lines.len() as f64 };
    let height = header + 3.0 * HISTORY_PANEL_H + legend_h + text_h;
    let mut out = titled(HISTORY_W, height, 28, plot.title);
    let shown: Vec<&HistoryPoint> =
        plot.points.iter().filter(|p| p.time.is_finite() && p.values.iter().all(|v| v.is_finite())).collect();
    // One time axis for all three panels, with a margin; a single calibration gets a day.
    let (tmin, tmax) =
        shown.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), p| (a.min(p.time), b.max(p.time)));
    let (tlo, thi) = if shown.is_empty() {
        (0.0, 86_400.0)
    } else if tmax - tmin < 1.0 {
        (tmin - 43_200.0, tmax + 43_200.0)
    } else {
        let pad = 0.05 * (tmax - tmin);
        (tmin - pad, tmax + pad)
    };
    let (tt, tl) = time_ticks(tlo, thi);
    let panels: [(&str, &str, f64); 3] = [
        ("alpha0: rail angle at step 0", "alpha0 [°]", 180.0 / std::f64::consts::PI),
        ("d: rail offset from the axis", "d [mm]", 1e3),
        ("dL: encoder zero offset", "dL [mm]", 1e3),
    ];
    let mut any_flagged = false;
    for (k, (title, unit, factor)) in panels.iter().enumerate() {
        let y0 = header + HISTORY_PANEL_H * k as f64 - 16.0;
        let bar = |p: &HistoryPoint| p.stddev.map_or(0.0, |s| plot.coverage * s[k] * factor);
        let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
        for p in &shown {
            let v = p.values[k] * factor;
            let b = if bar(p).is_finite() { bar(p) } else { 0.0 };
            lo = lo.min(v - b);
            hi = hi.max(v + b);
        }
        if shown.is_empty() {
            (lo, hi) = (-1.0, 1.0);
        }
        let span = (hi - lo).max(1e-9 * hi.abs().max(lo.abs())).max(1e-12);
        let (lo, hi) = (lo - 0.08 * span, hi + 0.08 * span);
        let step = nice_step(hi - lo, 5.0);
        let f = Frame {
            x0: M_LEFT + 20.0,
            y0: y0 + M_TOP,
            w: HISTORY_W - M_LEFT - 20.0 - M_RIGHT - 10.0,
            h: HISTORY_PANEL_H - M_TOP - 52.0,
            xlo: tlo,
            xhi: thi,
            ylo: lo,
            yhi: hi,
        };
        let x_axis = Axis {
            ticks: tt.clone(),
            decimals: 0,
            label: if k == 2 { "applied (UTC)" } else { "" },
            labels: tl.clone(),
        };
        let y_axis = Axis { ticks: ticks(lo, hi, step), decimals: decimals(step), label: unit, labels: Vec::new() };
        let _ = writeln!(out, r#"<g class="history-panel">"#);
        draw_axes(&mut out, &f, title, &x_axis, &y_axis);
        if shown.len() > 1 {
            let pts: Vec<String> =
                shown.iter().map(|p| format!("{:.2},{:.2}", f.px(p.time), f.py(p.values[k] * factor))).collect();
            let _ = writeln!(
                out,
                r#"<polyline class="trend" points="{}" fill="none" stroke="{C_TREND}" stroke-width="1"/>"#,
                pts.join(" ")
            );
        }
        let _ = writeln!(out, r#"<g class="calibrations" stroke-width="1.3">"#);
        for p in &shown {
            let color = if p.flagged[k] { C_FLAGGED } else { C_CORRECTED };
            any_flagged |= p.flagged[k];
            let (x, v) = (f.px(p.time), p.values[k] * factor);
            let b = bar(p);
            if b.is_finite() && b > 0.0 {
                let (y1, y2) = (f.py(v - b), f.py(v + b));
                let _ = writeln!(
                    out,
                    r#"<path class="error-bar" d="M{x:.2} {y1:.2}L{x:.2} {y2:.2}M{:.2} {y1:.2}L{:.2} {y1:.2}M{:.2} {y2:.2}L{:.2} {y2:.2}" stroke="{color}" fill="none"/>"#,
                    x - 4.0,
                    x + 4.0,
                    x - 4.0,
                    x + 4.0
                );
            }
            let _ = writeln!(out, r#"<circle cx="{x:.2}" cy="{:.2}" r="3.2" fill="{color}"/>"#, f.py(v));
        }
        out.push_str("</g>\n");
        if shown.is_empty() {
            no_data(&mut out, &f);
        }
        out.push_str("</g>\n");
    }
    // The legend, under the last panel.
    let ly = header + 3.0 * HISTORY_PANEL_H + 6.0;
    let mut items = vec![(Marker::Dot(C_CORRECTED), format!("calibration, error bar ±{}σ", plot.coverage))];
    if any_flagged {
        items.push((Marker::Dot(C_FLAGGED), plot.flagged_label.to_string()));
    }
    items.push((Marker::Line { color: C_TREND, dash: "none" }, "one calibration to the next".to_string()));
    let _ = writeln!(out, r#"<g class="legend">"#);
    let mut x = M_LEFT + 20.0;
    for (marker, text) in &items {
        draw_marker(&mut out, marker, x + 10.0, ly - 4.0);
        let _ = writeln!(out, r#"<text x="{:.1}" y="{ly:.1}">{}</text>"#, x + 26.0, xml_escape(text));
        x += 26.0 + 6.6 * text.chars().count() as f64 + 28.0;
    }
    out.push_str("</g>\n");
    if !lines.is_empty() {
        let top = header + 3.0 * HISTORY_PANEL_H + legend_h - 12.0;
        summary_box(&mut out, top, HISTORY_W - 24.0, text_h - 4.0, line_h, &lines);
    }
    out.push_str("</svg>\n");
    out
}
