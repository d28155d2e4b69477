//! A panel's axes: tick steps and labels (numbers, and dates for a time axis), where data
//! go in the panel ([`Frame`]), the title, grid, frame, ticks and axis labels
//! ([`draw_axes`]), and the "no data" note.

use std::fmt::Write as _;

use super::svg::{M_LEFT, M_TOP, xml_escape};

const C_GRID: &str = "#e4e4e4";

/// A 1-2-5 step giving about `target` intervals over `span`.
pub(super) fn nice_step(span: f64, target: f64) -> f64 {
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
pub(super) fn decimals(step: f64) -> usize {
    (-(step.log10() + 1e-9).floor()).max(0.0) as usize
}

/// Multiples of `step` in `[lo, hi]`.
pub(super) fn ticks(lo: f64, hi: f64, step: f64) -> Vec<f64> {
    let mut out = Vec::new();
    let mut k = (lo / step - 1e-9).ceil();
    while k * step <= hi + step * 1e-9 && out.len() < 200 {
        out.push(if k == 0.0 { 0.0 } else { k * step });
        k += 1.0;
    }
    out
}

pub(super) fn tick_label(v: f64, dec: usize) -> String {
    let s = format!("{v:.dec$}");
    if s.trim_start_matches('-').chars().all(|c| c == '0' || c == '.') {
        s.trim_start_matches('-').to_string()
    } else {
        s
    }
}

/// Where the data go inside a panel: the plot area and the data ranges it shows.
pub(super) struct Frame {
    pub(super) x0: f64,
    pub(super) y0: f64,
    pub(super) w: f64,
    pub(super) h: f64,
    pub(super) xlo: f64,
    pub(super) xhi: f64,
    pub(super) ylo: f64,
    pub(super) yhi: f64,
}

impl Frame {
    pub(super) fn px(&self, x: f64) -> f64 {
        self.x0 + (x - self.xlo) / (self.xhi - self.xlo) * self.w
    }

    pub(super) fn py(&self, y: f64) -> f64 {
        self.y0 + self.h - (y - self.ylo) / (self.yhi - self.ylo) * self.h
    }
}

/// Axis description for [`draw_axes`].
pub(super) struct Axis<'a> {
    pub(super) ticks: Vec<f64>,
    pub(super) decimals: usize,
    pub(super) label: &'a str,
    /// Tick labels, one a tick; empty: the tick values with `decimals`.
    pub(super) labels: Vec<String>,
}

/// Title, grid, frame, tick labels and axis labels.
pub(super) fn draw_axes(out: &mut String, f: &Frame, title: &str, x: &Axis<'_>, y: &Axis<'_>) {
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

pub(super) fn no_data(out: &mut String, f: &Frame) {
    let _ = writeln!(
        out,
        r##"<text class="no-data" x="{:.1}" y="{:.1}" text-anchor="middle" font-size="16" fill="#888888">no data</text>"##,
        f.x0 + f.w / 2.0,
        f.y0 + f.h / 2.0 - 24.0
    );
}

/// Time ticks about `target` apart over `[lo, hi]` (seconds): a round step (minutes,
/// hours, days, weeks, 30-day months, years), aligned to UTC midnight for a day or more.
pub(super) fn time_ticks(lo: f64, hi: f64) -> (Vec<f64>, Vec<String>) {
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
