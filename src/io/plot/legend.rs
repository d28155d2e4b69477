//! Legends: a panel's legend entries under its x-axis label, their markers, and the marker
//! shapes the panels draw as data points too (cross, triangle, plus).

use std::fmt::Write as _;

use super::axes::Frame;
use super::svg::{M_LEFT, M_RIGHT, xml_escape};

/// A legend entry's marker.
pub(super) enum Marker<'a> {
    Dot(&'a str),
    Ring(&'a str),
    Cross(&'a str),
    Plus(&'a str),
    Triangle(&'a str),
    Line { color: &'a str, dash: &'a str },
}

/// Legend entries under the x-axis label: one centred row, or two if one is too wide.
pub(super) fn draw_legend(out: &mut String, f: &Frame, items: &[(Marker<'_>, String)]) {
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
pub(super) fn draw_marker(out: &mut String, marker: &Marker<'_>, mx: f64, my: f64) {
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

pub(super) fn cross_path(x: f64, y: f64, s: f64) -> String {
    format!("M{:.2} {:.2}L{:.2} {:.2}M{:.2} {:.2}L{:.2} {:.2}", x - s, y - s, x + s, y + s, x - s, y + s, x + s, y - s)
}

/// A small triangle pointing up (or down) with its tip at `(x, y)`.
pub(super) fn triangle_path(x: f64, y: f64, s: f64, up: bool) -> String {
    let base = if up { y + 1.6 * s } else { y - 1.6 * s };
    format!("M{x:.2} {y:.2}L{:.2} {base:.2}L{:.2} {base:.2}Z", x - s, x + s)
}

pub(super) fn plus_path(x: f64, y: f64, s: f64) -> String {
    format!("M{:.2} {y:.2}L{:.2} {y:.2}M{x:.2} {:.2}L{x:.2} {:.2}", x - s, x + s, y - s, y + s)
}
