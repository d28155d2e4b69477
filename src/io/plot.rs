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

use std::fmt::Write as _;

use nalgebra::Vector2;

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

const PANEL_W: f64 = 640.0;
const PANEL_H: f64 = 600.0;
const M_LEFT: f64 = 72.0;
const M_RIGHT: f64 = 24.0;
const M_TOP: f64 = 56.0;
const M_BOTTOM: f64 = 92.0;

const FONT: &str = "DejaVu Sans, Arial, Helvetica, sans-serif";
const C_RAW: &str = "#ff7f0e";
const C_CORRECTED: &str = "#1f77b4";
const C_REFERENCE: &str = "#222222";
const C_USED: &str = "#1f77b4";
const C_REJECTED: &str = "#d62728";
const C_SIGMA: &str = "#d62728";
const C_GRID: &str = "#e4e4e4";

/// Escape text for XML content and attribute values; control characters (which XML 1.0
/// does not allow) become spaces.
pub fn xml_escape(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    for c in text.chars() {
        match c {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&apos;"),
            '\u{FFFE}' | '\u{FFFF}' => out.push(' '),
            c if c.is_control() => out.push(' '),
            c => out.push(c),
        }
    }
    out
}

/// The raw and corrected contours (and the reference outline) in one plot, equal scaling,
/// axes in mm.
pub fn contours_svg(plot: &ContourPlot<'_>) -> String {
    let mut out = String::new();
    svg_open(&mut out, PANEL_W, PANEL_H);
    contour_panel(&mut out, 0.0, 0.0, PANEL_W, PANEL_H, plot);
    out.push_str("</svg>\n");
    out
}

/// Residuals (µm) against angle (degrees): used samples as dots, rejected ones as crosses,
/// zero and ±3σ lines; the title gives the RMS of the used residuals.
pub fn residuals_svg(plot: &ResidualPlot<'_>) -> String {
    let mut out = String::new();
    svg_open(&mut out, PANEL_W, PANEL_H);
    residual_panel(&mut out, 0.0, 0.0, PANEL_W, PANEL_H, plot);
    out.push_str("</svg>\n");
    out
}

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
    let mut out = String::new();
    svg_open(&mut out, width, height);
    let _ = writeln!(
        out,
        r#"<text class="title" x="{:.1}" y="27" text-anchor="middle" font-size="20" font-weight="bold">{}</text>"#,
        width / 2.0,
        xml_escape(report.title)
    );
    contour_panel(&mut out, 0.0, header, PANEL_W, PANEL_H, &report.contours);
    residual_panel(&mut out, PANEL_W, header, PANEL_W, PANEL_H, &report.residuals);
    if !lines.is_empty() {
        summary_box(&mut out, header + PANEL_H, width - 24.0, text_h - 8.0, line_h, &lines);
    }
    out.push_str("</svg>\n");
    out
}

/// A grey box at `top`, `w` × `h`, of monospaced text lines `line_h` apart: a picture's
/// summary under its panels.
fn summary_box(out: &mut String, top: f64, w: f64, h: f64, line_h: f64, lines: &[String]) {
    let _ = writeln!(
        out,
        r##"<rect x="12" y="{top:.1}" width="{w:.1}" height="{h:.1}" fill="#f6f6f6" stroke="#cccccc"/>"##
    );
    let _ = writeln!(
        out,
        r#"<g class="summary" font-family="DejaVu Sans Mono, Menlo, Consolas, monospace" font-size="12">"#
    );
    for (k, line) in lines.iter().enumerate() {
        let _ = writeln!(
            out,
            r#"<text x="20" y="{:.1}" xml:space="preserve">{}</text>"#,
            top + 18.0 + line_h * k as f64,
            xml_escape(line)
        );
    }
    out.push_str("</g>\n");
}

fn svg_open(out: &mut String, w: f64, h: f64) {
    let _ = writeln!(out, r#"<?xml version="1.0" encoding="UTF-8"?>"#);
    let _ = writeln!(
        out,
        r#"<svg xmlns="http://www.w3.org/2000/svg" version="1.1" width="{w:.0}" height="{h:.0}" viewBox="0 0 {w:.0} {h:.0}" font-family="{FONT}" font-size="12">"#
    );
    let _ = writeln!(out, r#"<rect x="0" y="0" width="{w:.0}" height="{h:.0}" fill="white"/>"#);
}

/// Greedy word wrap; `\n` forces a break; words longer than a line are split.
fn wrap(text: &str, max_chars: usize) -> Vec<String> {
    let max_chars = max_chars.max(10);
    let mut lines = Vec::new();
    for para in text.trim_end().split('\n') {
        let mut line = String::new();
        let mut len = 0;
        for word in para.split_whitespace() {
            let mut word: Vec<char> = word.chars().collect();
            loop {
                let need = if len == 0 { word.len() } else { len + 1 + word.len() };
                if need <= max_chars {
                    if len > 0 {
                        line.push(' ');
                    }
                    line.extend(word.iter());
                    len = need;
                    break;
                }
                if len > 0 {
                    lines.push(std::mem::take(&mut line));
                    len = 0;
                    continue;
                }
                // A word longer than a line: split it.
                let rest = word.split_off(max_chars);
                lines.push(word.into_iter().collect());
                word = rest;
            }
        }
        if len > 0 || para.trim().is_empty() {
            lines.push(line);
        }
    }
    while lines.last().is_some_and(|l| l.is_empty()) {
        lines.pop();
    }
    lines
}

/// A 1-2-5 step giving about `target` intervals over `span`.
fn nice_step(span: f64, target: f64) -> f64 {
    let span = if span.is_finite() && span > 0.0 { span } else { 1.0 };
    let raw = span / target;
    let mag = 10f64.powf(raw.log10().floor());
    let f = raw / mag;
    let nice = if f <= 1.0 {
        1.0
    } else if f <= 2.0 {
        2.0
    } else if f <= 5.0 {
        5.0
    } else {
        10.0
    };
    nice * mag
}

/// Decimals to print ticks of `step`.
fn decimals(step: f64) -> usize {
    (-(step.log10() + 1e-9).floor()).max(0.0) as usize
}

/// Multiples of `step` in `[lo, hi]`.
fn ticks(lo: f64, hi: f64, step: f64) -> Vec<f64> {
    let mut out = Vec::new();
    let mut k = (lo / step - 1e-9).ceil();
    while k * step <= hi + step * 1e-9 && out.len() < 200 {
        out.push(if k == 0.0 { 0.0 } else { k * step });
        k += 1.0;
    }
    out
}

fn tick_label(v: f64, dec: usize) -> String {
    let s = format!("{v:.dec$}");
    if s.trim_start_matches('-').chars().all(|c| c == '0' || c == '.') {
        s.trim_start_matches('-').to_string()
    } else {
        s
    }
}

/// Where the data go inside a panel: the plot area and the data ranges it shows.
struct Frame {
    x0: f64,
    y0: f64,
    w: f64,
    h: f64,
    xlo: f64,
    xhi: f64,
    ylo: f64,
    yhi: f64,
}

impl Frame {
    fn px(&self, x: f64) -> f64 {
        self.x0 + (x - self.xlo) / (self.xhi - self.xlo) * self.w
    }

    fn py(&self, y: f64) -> f64 {
        self.y0 + self.h - (y - self.ylo) / (self.yhi - self.ylo) * self.h
    }
}

/// Axis description for [`draw_axes`].
struct Axis<'a> {
    ticks: Vec<f64>,
    decimals: usize,
    label: &'a str,
    /// Tick labels, one a tick; empty: the tick values with `decimals`.
    labels: Vec<String>,
}

/// Title, grid, frame, tick labels and axis labels.
fn draw_axes(out: &mut String, f: &Frame, title: &str, x: &Axis<'_>, y: &Axis<'_>) {
    let _ = writeln!(
        out,
        r#"<text class="title" x="{:.1}" y="{:.1}" text-anchor="middle" font-size="15" font-weight="bold">{}</text>"#,
        f.x0 + f.w / 2.0,
        f.y0 - M_TOP + 30.0,
        xml_escape(title)
    );
    let _ = writeln!(out, r#"<g class="grid" stroke="{C_GRID}" stroke-width="1">"#);
    for &t in &x.ticks {
        let px = f.px(t);
        let _ = writeln!(out, r#"<line x1="{px:.2}" y1="{:.2}" x2="{px:.2}" y2="{:.2}"/>"#, f.y0, f.y0 + f.h);
    }
    for &t in &y.ticks {
        let py = f.py(t);
        let _ = writeln!(out, r#"<line x1="{:.2}" y1="{py:.2}" x2="{:.2}" y2="{py:.2}"/>"#, f.x0, f.x0 + f.w);
    }
    out.push_str("</g>\n");
    let _ = writeln!(
        out,
        r#"<rect class="frame" x="{:.2}" y="{:.2}" width="{:.2}" height="{:.2}" fill="none" stroke="black" stroke-width="1"/>"#,
        f.x0, f.y0, f.w, f.h
    );
    let _ = writeln!(out, r#"<g class="ticks" stroke="black" stroke-width="1">"#);
    for &t in &x.ticks {
        let px = f.px(t);
        let _ =
            writeln!(out, r#"<line x1="{px:.2}" y1="{:.2}" x2="{px:.2}" y2="{:.2}"/>"#, f.y0 + f.h, f.y0 + f.h + 5.0);
    }
    for &t in &y.ticks {
        let py = f.py(t);
        let _ = writeln!(out, r#"<line x1="{:.2}" y1="{py:.2}" x2="{:.2}" y2="{py:.2}"/>"#, f.x0 - 5.0, f.x0);
    }
    out.push_str("</g>\n");
    out.push_str("<g class=\"tick-labels\">\n");
    for (k, &t) in x.ticks.iter().enumerate() {
        let _ = writeln!(
            out,
            r#"<text x="{:.2}" y="{:.2}" text-anchor="middle">{}</text>"#,
            f.px(t),
            f.y0 + f.h + 19.0,
            x.labels.get(k).map_or_else(|| tick_label(t, x.decimals), |l| xml_escape(l))
        );
    }
    for &t in &y.ticks {
        let _ = writeln!(
            out,
            r#"<text x="{:.2}" y="{:.2}" text-anchor="end">{}</text>"#,
            f.x0 - 8.0,
            f.py(t) + 4.0,
            tick_label(t, y.decimals)
        );
    }
    out.push_str("</g>\n");
    let _ = writeln!(
        out,
        r#"<text class="xlabel" x="{:.2}" y="{:.2}" text-anchor="middle" font-size="13">{}</text>"#,
        f.x0 + f.w / 2.0,
        f.y0 + f.h + 40.0,
        xml_escape(x.label)
    );
    let (lx, ly) = (f.x0 - M_LEFT + 18.0, f.y0 + f.h / 2.0);
    let _ = writeln!(
        out,
        r#"<text class="ylabel" x="{lx:.2}" y="{ly:.2}" text-anchor="middle" font-size="13" transform="rotate(-90 {lx:.2} {ly:.2})">{}</text>"#,
        xml_escape(y.label)
    );
}

/// A legend entry's marker.
enum Marker<'a> {
    Dot(&'a str),
    Ring(&'a str),
    Cross(&'a str),
    Plus(&'a str),
    Triangle(&'a str),
    Line { color: &'a str, dash: &'a str },
}

/// Legend entries under the x-axis label: one centred row, or two if one is too wide.
fn draw_legend(out: &mut String, f: &Frame, items: &[(Marker<'_>, String)]) {
    // Rough text width at 12 px.
    let widths: Vec<f64> = items.iter().map(|(_, t)| 26.0 + 6.6 * t.chars().count() as f64 + 16.0).collect();
    let room = f.w + M_LEFT + M_RIGHT - 16.0;
    let mut rows: Vec<Vec<usize>> = vec![Vec::new()];
    let mut used = 0.0;
    for (k, w) in widths.iter().enumerate() {
        if used + w > room && !rows.last().expect("never empty").is_empty() {
            rows.push(Vec::new());
            used = 0.0;
        }
        rows.last_mut().expect("never empty").push(k);
        used += w;
    }
    let y0 = f.y0 + f.h + if rows.len() > 1 { 60.0 } else { 66.0 };
    out.push_str("<g class=\"legend\">\n");
    for (r, row) in rows.iter().enumerate() {
        let y = y0 + 19.0 * r as f64;
        let total: f64 = row.iter().map(|&k| widths[k]).sum();
        let mut x = f.x0 + ((f.w - total) / 2.0).max(-M_LEFT + 8.0);
        for &k in row {
            let (marker, text) = &items[k];
            draw_marker(out, marker, x + 10.0, y - 4.0);
            let _ = writeln!(out, r#"<text x="{:.1}" y="{y:.1}">{}</text>"#, x + 26.0, xml_escape(text));
            x += widths[k];
        }
    }
    out.push_str("</g>\n");
}

/// A legend entry's marker centred at `(mx, my)`.
fn draw_marker(out: &mut String, marker: &Marker<'_>, mx: f64, my: f64) {
    let _ = match marker {
        Marker::Dot(c) => writeln!(out, r#"<circle cx="{mx:.1}" cy="{my:.1}" r="3" fill="{c}"/>"#),
        Marker::Ring(c) => {
            writeln!(out, r#"<circle cx="{mx:.1}" cy="{my:.1}" r="3" fill="none" stroke="{c}" stroke-width="1.2"/>"#)
        }
        Marker::Cross(c) => {
            writeln!(out, r#"<path d="{}" stroke="{c}" stroke-width="1.6" fill="none"/>"#, cross_path(mx, my, 4.0))
        }
        Marker::Plus(c) => {
            writeln!(out, r#"<path d="{}" stroke="{c}" stroke-width="1.2" fill="none"/>"#, plus_path(mx, my, 5.0))
        }
        Marker::Triangle(c) => writeln!(out, r#"<path d="{}" fill="{c}"/>"#, triangle_path(mx, my - 4.0, 5.0, true)),
        Marker::Line { color, dash } => writeln!(
            out,
            r#"<line x1="{:.1}" y1="{my:.1}" x2="{:.1}" y2="{my:.1}" stroke="{color}" stroke-width="1.5" stroke-dasharray="{dash}"/>"#,
            mx - 10.0,
            mx + 10.0
        ),
    };
}

fn cross_path(x: f64, y: f64, s: f64) -> String {
    format!("M{:.2} {:.2}L{:.2} {:.2}M{:.2} {:.2}L{:.2} {:.2}", x - s, y - s, x + s, y + s, x - s, y + s, x + s, y - s)
}

/// A small triangle pointing up (or down) with its tip at `(x, y)`.
fn triangle_path(x: f64, y: f64, s: f64, up: bool) -> String {
    let base = if up { y + 1.6 * s } else { y - 1.6 * s };
    format!("M{x:.2} {y:.2}L{:.2} {base:.2}L{:.2} {base:.2}Z", x - s, x + s)
}

fn no_data(out: &mut String, f: &Frame) {
    let _ = writeln!(
        out,
        r##"<text class="no-data" x="{:.1}" y="{:.1}" text-anchor="middle" font-size="16" fill="#888888">no data</text>"##,
        f.x0 + f.w / 2.0,
        f.y0 + f.h / 2.0 - 24.0
    );
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

fn contour_panel(out: &mut String, x0: f64, y0: f64, w: f64, h: f64, plot: &ContourPlot<'_>) {
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

fn plus_path(x: f64, y: f64, s: f64) -> String {
    format!("M{:.2} {y:.2}L{:.2} {y:.2}M{x:.2} {:.2}L{x:.2} {:.2}", x - s, x + s, y - s, y + s)
}

fn residual_panel(out: &mut String, x0: f64, y0: f64, w: f64, h: f64, plot: &ResidualPlot<'_>) {
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

const C_FLAGGED: &str = "#d62728";
const C_TREND: &str = "#9a9a9a";
const HISTORY_W: f64 = 960.0;
const HISTORY_PANEL_H: f64 = 290.0;

/// Time ticks about `target` apart over `[lo, hi]` (seconds): a round step (minutes,
/// hours, days, weeks, 30-day months, years), aligned to UTC midnight for a day or more.
fn time_ticks(lo: f64, hi: f64) -> (Vec<f64>, Vec<String>) {
    const STEPS: [f64; 22] = [
        1.0,
        2.0,
        5.0,
        10.0,
        15.0,
        30.0,
        60.0,
        300.0,
        900.0,
        1800.0,
        3600.0,
        7200.0,
        21_600.0,
        43_200.0,
        86_400.0,
        172_800.0,
        604_800.0,
        1_209_600.0,
        2_592_000.0,
        7_776_000.0,
        15_552_000.0,
        31_536_000.0,
    ];
    let span = (hi - lo).max(1.0);
    let step =
        STEPS.iter().copied().find(|s| span / s <= 7.0).unwrap_or(31_536_000.0 * (span / 31_536_000.0 / 7.0).ceil());
    let ticks = ticks(lo, hi, step);
    let labels = ticks
        .iter()
        .map(|&t| {
            let iso =
                crate::records::format_utc(std::time::UNIX_EPOCH + std::time::Duration::from_secs_f64(t.max(0.0)));
            if step >= 86_400.0 {
                iso[..10].to_string()
            } else if step >= 60.0 {
                format!("{} {}", &iso[5..10], &iso[11..16])
            } else {
                iso[11..19].to_string()
            }
        })
        .collect();
    (ticks, labels)
}

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
    let mut out = String::new();
    svg_open(&mut out, HISTORY_W, height);
    let _ = writeln!(
        out,
        r#"<text class="title" x="{:.1}" y="28" text-anchor="middle" font-size="20" font-weight="bold">{}</text>"#,
        HISTORY_W / 2.0,
        xml_escape(plot.title)
    );
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

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::TAU;

    /// A tiny XML well-formedness check: balanced tags, quoted attributes without
    /// duplicates, entities only `&amp; &lt; &gt; &quot; &apos;`, one root element.
    fn check_well_formed(xml: &str) {
        fn check_text(t: &str) {
            let mut rest = t;
            while let Some(i) = rest.find('&') {
                rest = &rest[i..];
                let ok = ["&amp;", "&lt;", "&gt;", "&quot;", "&apos;"].iter().any(|e| rest.starts_with(e));
                assert!(ok, "bad entity at '{}'", &rest[..rest.len().min(20)]);
                rest = &rest[1..];
            }
            assert!(!t.chars().any(|c| c.is_control() && c != '\n' && c != '\t' && c != '\r'));
        }
        let mut stack: Vec<String> = Vec::new();
        let mut roots = 0;
        let mut rest = xml;
        while let Some(i) = rest.find('<') {
            check_text(&rest[..i]);
            if !rest[..i].trim().is_empty() {
                assert!(!stack.is_empty(), "text outside the root");
            }
            rest = &rest[i..];
            if rest.starts_with("<?") {
                let e = rest.find("?>").expect("unterminated <?");
                rest = &rest[e + 2..];
                continue;
            }
            if rest.starts_with("<!--") {
                let e = rest.find("-->").expect("unterminated comment");
                rest = &rest[e + 3..];
                continue;
            }
            // Find the tag's end, outside quotes.
            let mut in_quote = false;
            let mut end = None;
            for (k, c) in rest.char_indices().skip(1) {
                match c {
                    '"' => in_quote = !in_quote,
                    '<' if !in_quote => panic!("'<' inside a tag: {}", &rest[..k]),
                    '>' if !in_quote => {
                        end = Some(k);
                        break;
                    }
                    _ => {}
                }
            }
            let end = end.expect("unterminated tag");
            let tag = &rest[1..end];
            rest = &rest[end + 1..];
            if let Some(name) = tag.strip_prefix('/') {
                let open = stack.pop().expect("closing tag without an open one");
                assert_eq!(open, name.trim(), "mismatched tags");
                continue;
            }
            let self_closing = tag.ends_with('/');
            let body = tag.trim_end_matches('/');
            let name_end = body.find(char::is_whitespace).unwrap_or(body.len());
            let name = &body[..name_end];
            assert!(!name.is_empty() && name.chars().all(|c| c.is_alphanumeric() || c == ':' || c == '-'), "{name}");
            // Attributes: name="value" pairs.
            let mut attrs = body[name_end..].trim();
            let mut seen = Vec::new();
            while !attrs.is_empty() {
                let eq = attrs.find('=').expect("attribute without '='");
                let an = attrs[..eq].trim();
                assert!(!an.is_empty() && !an.contains(char::is_whitespace), "attribute name '{an}'");
                assert!(!seen.contains(&an), "duplicate attribute {an}");
                seen.push(an);
                let after = attrs[eq + 1..].trim_start();
                assert!(after.starts_with('"'), "unquoted attribute {an}");
                let close = after[1..].find('"').expect("unterminated attribute");
                check_text(&after[1..1 + close]);
                attrs = after[close + 2..].trim_start();
            }
            if stack.is_empty() {
                roots += 1;
            }
            if !self_closing {
                stack.push(name.to_string());
            }
        }
        check_text(rest);
        assert!(rest.trim().is_empty(), "text after the root");
        assert!(stack.is_empty(), "unclosed tags: {stack:?}");
        assert_eq!(roots, 1, "one root element");
    }

    /// The elements `<tag` inside the first `<g class="class" ...> ... </g>`.
    fn count_in_group(svg: &str, class: &str, tag: &str) -> usize {
        let start = match svg.find(&format!("<g class=\"{class}\"")) {
            Some(s) => s,
            None => return 0,
        };
        let end = start + svg[start..].find("</g>").unwrap();
        svg[start..end].matches(&format!("<{tag} ")).count()
    }

    fn plate_outline(n: usize, half: f64, r: f64, c: Vector2<f64>) -> Vec<Vector2<f64>> {
        // A rounded square by its support: exact enough for a picture.
        (0..n)
            .map(|k| {
                let a = TAU * k as f64 / n as f64;
                let (s, co) = a.sin_cos();
                let p = 8.0;
                let rad = (half - r) / (co.abs().powf(p) + s.abs().powf(p)).powf(1.0 / p) + r;
                c + Vector2::new(rad * co, rad * s)
            })
            .collect()
    }

    /// A plate scan's worth of plot inputs: raw, corrected, true outline, residuals.
    struct SampleData {
        raw: Vec<Vector2<f64>>,
        corrected: Vec<Vector2<f64>>,
        truth: Vec<Vector2<f64>>,
        residuals: Vec<ResidualSample>,
    }

    fn sample_data() -> SampleData {
        let c = Vector2::new(0.0012, -0.0007);
        let truth = plate_outline(400, 0.0225, 0.003, c);
        let mut state = 12345u64;
        let mut noise = move || {
            state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            ((state >> 11) as f64 / (1u64 << 53) as f64 - 0.5) * 1.2e-5
        };
        let corrected: Vec<_> = truth.iter().map(|p| p + Vector2::new(noise(), noise())).collect();
        // Raw: rotated by 1.7°, shifted, stretched radially by dL-like 1.3 mm.
        let (s, co) = 1.7f64.to_radians().sin_cos();
        let raw: Vec<_> = corrected
            .iter()
            .map(|p| {
                let q = Vector2::new(co * p.x - s * p.y, s * p.x + co * p.y);
                q * (1.0 + 0.0013 / q.norm()) + Vector2::new(0.0, 0.0042 * 0.1)
            })
            .collect();
        let mut residuals: Vec<ResidualSample> = (0..400)
            .map(|k| ResidualSample { angle: TAU * k as f64 / 400.0, residual: noise() * 0.8, used: true })
            .collect();
        residuals[57] = ResidualSample { angle: residuals[57].angle, residual: 4.1e-4, used: false };
        residuals[230] = ResidualSample { angle: residuals[230].angle, residual: -8.0e-6, used: false };
        SampleData { raw, corrected, truth, residuals }
    }

    #[test]
    fn contours_points_and_scaling() {
        let SampleData { raw, corrected, truth, .. } = sample_data();
        let mut raw_nan = raw.clone();
        raw_nan[3].x = f64::NAN;
        raw_nan[4].y = f64::INFINITY;
        let svg = contours_svg(&ContourPlot {
            title: "Plate <45 mm> & fit",
            raw: &raw_nan,
            corrected: &corrected,
            reference: Some(Outline { label: "fitted plate", points: &truth, closed: true }),
        });
        check_well_formed(&svg);
        assert!(svg.contains("Plate &lt;45 mm&gt; &amp; fit"));
        assert_eq!(count_in_group(&svg, "raw", "circle"), 398);
        assert_eq!(count_in_group(&svg, "corrected", "circle"), 400);
        assert_eq!(count_in_group(&svg, "reference", "polyline"), 1);
        assert!(svg.contains("raw, uncorrected (398)"));
        assert!(!svg.contains("NaN") && !svg.contains("inf"));
        assert!(svg.contains("class=\"origin\""));
        // Equal scaling: the grid's x and y spacing in pixels are the same.
        let grid_start = svg.find("<g class=\"grid\"").unwrap();
        let grid = &svg[grid_start..grid_start + svg[grid_start..].find("</g>").unwrap()];
        let attr = |line: &str, a: &str| -> f64 {
            let s = line.find(&format!(" {a}=\"")).unwrap() + a.len() + 3;
            line[s..s + line[s..].find('"').unwrap()].parse().unwrap()
        };
        let lines: Vec<&str> = grid.lines().filter(|l| l.starts_with("<line")).collect();
        let xs: Vec<f64> = lines.iter().filter(|l| attr(l, "x1") == attr(l, "x2")).map(|l| attr(l, "x1")).collect();
        let ys: Vec<f64> = lines.iter().filter(|l| attr(l, "y1") == attr(l, "y2")).map(|l| attr(l, "y1")).collect();
        assert!(xs.len() >= 4 && ys.len() >= 4);
        let (gx, gy) = (xs[1] - xs[0], ys[0] - ys[1]);
        assert!((gx - gy).abs() < 0.02, "{gx} vs {gy}");
    }

    #[test]
    fn polyline_breaks_at_nan() {
        let mut pts: Vec<Vector2<f64>> = (0..10).map(|k| Vector2::new(k as f64 * 1e-3, 0.0)).collect();
        pts[4] = Vector2::new(f64::NAN, 0.0);
        let svg = contours_svg(&ContourPlot {
            title: "t",
            raw: &[],
            corrected: &[],
            reference: Some(Outline { label: "ref", points: &pts, closed: true }),
        });
        check_well_formed(&svg);
        assert_eq!(count_in_group(&svg, "reference", "polyline"), 2);
    }

    #[test]
    fn residual_markers() {
        let SampleData { mut residuals, .. } = sample_data();
        residuals[10].residual = f64::NAN;
        residuals[11].angle = f64::NAN;
        let svg = residuals_svg(&ResidualPlot { title: "Fit residuals", samples: &residuals });
        check_well_formed(&svg);
        assert_eq!(count_in_group(&svg, "used", "circle"), 396);
        // One rejected sample in range (a cross), one far off (a triangle on the edge).
        assert_eq!(count_in_group(&svg, "rejected", "path"), 1);
        assert_eq!(count_in_group(&svg, "off-scale", "path"), 1);
        assert_eq!(count_in_group(&svg, "sigma", "line"), 2);
        assert!(svg.contains("class=\"zero\""));
        let used: Vec<f64> = residuals
            .iter()
            .filter(|s| s.used && s.residual.is_finite() && s.angle.is_finite())
            .map(|s| s.residual * 1e6)
            .collect();
        let rms = (used.iter().map(|r| r * r).sum::<f64>() / used.len() as f64).sqrt();
        assert!(svg.contains(&format!("RMS {rms:.2} µm (396 used, 2 rejected)")), "{rms}");
        assert!(svg.contains("up to 410 µm"));
        assert!(!svg.contains("NaN"));
    }

    #[test]
    fn empty_inputs() {
        let svg = contours_svg(&ContourPlot { title: "", raw: &[], corrected: &[], reference: None });
        check_well_formed(&svg);
        assert!(svg.contains("no data"));
        let nan = [Vector2::new(f64::NAN, f64::NAN)];
        let svg = contours_svg(&ContourPlot {
            title: "",
            raw: &nan,
            corrected: &nan,
            reference: Some(Outline { label: "", points: &nan, closed: true }),
        });
        check_well_formed(&svg);
        assert_eq!(count_in_group(&svg, "raw", "circle"), 0);
        let svg = residuals_svg(&ResidualPlot { title: "r", samples: &[] });
        check_well_formed(&svg);
        assert!(svg.contains("no samples used") && svg.contains("no data"));
        // Only rejected samples; all residuals zero; one point.
        let only_rejected = [ResidualSample { angle: 1.0, residual: 1e-4, used: false }];
        check_well_formed(&residuals_svg(&ResidualPlot { title: "r", samples: &only_rejected }));
        let zeros = [ResidualSample { angle: -1.0, residual: 0.0, used: true }; 3];
        let svg = residuals_svg(&ResidualPlot { title: "r", samples: &zeros });
        check_well_formed(&svg);
        assert_eq!(count_in_group(&svg, "sigma", "line"), 0);
        let one = [Vector2::new(0.01, 0.02)];
        check_well_formed(&contours_svg(&ContourPlot { title: "", raw: &one, corrected: &[], reference: None }));
        let report = calibration_report_svg(&CalibrationReport {
            title: "",
            contours: ContourPlot { title: "", raw: &[], corrected: &[], reference: None },
            residuals: ResidualPlot { title: "", samples: &[] },
            summary: "",
        });
        check_well_formed(&report);
    }

    #[test]
    fn report_side_by_side() {
        let SampleData { raw, corrected, truth, residuals } = sample_data();
        let summary = "full model: alpha0 = 1.6884° ± 0.0130°, d = 4.2044 ± 0.0061 mm, dL = 1.3002 ± 0.0011 mm, rms residual 0.0050 mm, 398 samples used, 2 rejected, 7 iterations, and a <tag> & \"quote\" with\u{7} a bell\nsecond line";
        let svg = calibration_report_svg(&CalibrationReport {
            title: "Calibration of tracer 1",
            contours: ContourPlot {
                title: "Plate contour",
                raw: &raw,
                corrected: &corrected,
                reference: Some(Outline { label: "fitted plate", points: &truth, closed: true }),
            },
            residuals: ResidualPlot { title: "Residuals", samples: &residuals },
            summary,
        });
        check_well_formed(&svg);
        assert!(svg.contains("width=\"1280\""));
        assert!(svg.contains("&lt;tag&gt;") && svg.contains("&amp; &quot;quote&quot;"));
        assert_eq!(count_in_group(&svg, "summary", "text"), 3);
        assert_eq!(count_in_group(&svg, "raw", "circle"), 400);
        assert_eq!(count_in_group(&svg, "used", "circle"), 398);
        // The residual panel is to the right of the contour panel.
        let r = svg.find("<g class=\"residual-panel\">").unwrap();
        let first_circle = &svg[r..][svg[r..].find("<g class=\"used\"").unwrap()..];
        let cx_at = first_circle.find("cx=\"").unwrap() + 4;
        let cx: f64 = first_circle[cx_at..cx_at + first_circle[cx_at..].find('"').unwrap()].parse().unwrap();
        assert!(cx > PANEL_W + M_LEFT - 1.0);
    }

    #[test]
    fn helpers() {
        assert_eq!(xml_escape("a<b>&\"c'\u{1}"), "a&lt;b&gt;&amp;&quot;c&apos; ");
        assert_eq!(nice_step(50.0, 8.0), 10.0);
        assert_eq!(nice_step(0.07, 8.0), 0.01);
        assert_eq!(nice_step(f64::NAN, 8.0), 0.2);
        assert_eq!(decimals(0.5), 1);
        assert_eq!(decimals(0.01), 2);
        assert_eq!(decimals(5.0), 0);
        assert_eq!(ticks(-1.0, 1.0, 0.5), vec![-1.0, -0.5, 0.0, 0.5, 1.0]);
        assert_eq!(tick_label(-0.0000001, 2), "0.00");
        assert_eq!(tick_label(-2.5, 1), "-2.5");
        assert_eq!(wrap("aaa bbb ccc", 10), vec!["aaa bbb", "ccc"]);
        assert_eq!(wrap("abcdefghijklmnop x", 10), vec!["abcdefghij", "klmnop x"]);
        assert_eq!(wrap("a\n\nb\n", 10), vec!["a", "", "b"]);
        assert!(wrap("", 10).is_empty());
    }

    #[test]
    fn history_panels_error_bars_and_flags() {
        let day = 86_400.0;
        let t0 = 1_795_428_757.0;
        let points: Vec<HistoryPoint> = (0..6)
            .map(|i| HistoryPoint {
                time: t0 + 7.0 * day * i as f64,
                values: [0.0349 + 1e-5 * i as f64, 0.005 + if i == 4 { 1e-4 } else { 0.0 }, 0.002],
                stddev: if i == 0 { None } else { Some([2e-4, 6e-6, 1e-6]) },
                flagged: [false, i == 4, false],
            })
            .collect();
        let svg = history_svg(&HistoryPlot {
            title: "Calibration history of /tracer & co",
            points: &points,
            coverage: 2.0,
            flagged_label: "moved > 10σ",
            summary: "6 calibrations",
        });
        check_well_formed(&svg);
        assert_eq!(svg.matches("<g class=\"history-panel\">").count(), 3);
        assert_eq!(svg.matches("r=\"3.2\"").count(), 18);
        assert_eq!(svg.matches("class=\"error-bar\"").count(), 15, "none for the one without uncertainties");
        assert_eq!(svg.matches(&format!("fill=\"{C_FLAGGED}\"")).count(), 1 + 1, "the point of d and the legend");
        assert!(svg.contains(">2026-1") && svg.contains("&amp; co"), "dates on the time axis");
        assert!(svg.contains("error bar ±2σ"));
        // Degenerate inputs draw empty or single-point panels, never NaN.
        for pts in [&points[..0], &points[..1]] {
            let svg =
                history_svg(&HistoryPlot { title: "", points: pts, coverage: 2.0, flagged_label: "", summary: "" });
            check_well_formed(&svg);
            assert!(!svg.contains("NaN") && !svg.contains("inf"), "{svg}");
        }
        let (ticks, labels) = time_ticks(t0, t0 + 3600.0);
        assert!(ticks.len() >= 3 && labels[0].len() == 11, "{labels:?}");
        let (ticks, labels) = time_ticks(t0, t0 + 20.0);
        assert!(ticks.len() >= 3 && labels[0].len() == 8, "{labels:?}");
    }

    /// Not a check: writes sample pictures for a person to look at
    /// (`cargo test --lib io::plot -- --ignored`; files in the temp directory).
    #[test]
    #[ignore]
    fn write_samples() {
        let SampleData { raw, corrected, truth, residuals } = sample_data();
        let contours = ContourPlot {
            title: "Calibration plate: raw vs corrected",
            raw: &raw,
            corrected: &corrected,
            reference: Some(Outline { label: "fitted plate outline", points: &truth, closed: true }),
        };
        let res = ResidualPlot { title: "Fit residuals", samples: &residuals };
        let dir = std::env::temp_dir();
        std::fs::write(dir.join("tracer_calib_contours.svg"), contours_svg(&contours)).unwrap();
        std::fs::write(dir.join("tracer_calib_residuals.svg"), residuals_svg(&res)).unwrap();
        let summary = "full model: alpha0 = 1.6884° ± 0.0130°, d = 4.2044 ± 0.0061 mm, dL = 1.3002 ± 0.0011 mm, rms residual 0.0050 mm, 398 samples used, 2 rejected, 7 iterations";
        let report = CalibrationReport { title: "Tracer calibration report", contours, residuals: res, summary };
        std::fs::write(dir.join("tracer_calib_report.svg"), calibration_report_svg(&report)).unwrap();
        let empty = CalibrationReport {
            title: "Empty",
            contours: ContourPlot { title: "No contour", raw: &[], corrected: &[], reference: None },
            residuals: ResidualPlot { title: "No residuals", samples: &[] },
            summary: "no fit",
        };
        std::fs::write(dir.join("tracer_calib_empty.svg"), calibration_report_svg(&empty)).unwrap();
    }
}
