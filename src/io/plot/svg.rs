//! The document around a picture: its opening (XML header, size, background), the summary
//! box under the panels, text escaping and wrapping, and the sizes, margins and colours the
//! panels share.

use std::fmt::Write as _;

pub(super) const PANEL_W: f64 = 640.0;
pub(super) const PANEL_H: f64 = 600.0;
pub(super) const M_LEFT: f64 = 72.0;
pub(super) const M_RIGHT: f64 = 24.0;
pub(super) const M_TOP: f64 = 56.0;
pub(super) const M_BOTTOM: f64 = 92.0;

const FONT: &str = "DejaVu Sans, Arial, Helvetica, sans-serif";
pub(super) const C_CORRECTED: &str = "#1f77b4";

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

/// A grey box at `top`, `w` × `h`, of monospaced text lines `line_h` apart: a picture's
/// summary under its panels.
pub(super) fn summary_box(out: &mut String, top: f64, w: f64, h: f64, line_h: f64, lines: &[String]) {
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

/// One panel of `PANEL_W` × `PANEL_H` as a whole picture, drawn by `panel(out, x0, y0, w, h)`.
pub(super) fn one_panel(panel: impl FnOnce(&mut String, f64, f64, f64, f64)) -> String {
    let mut out = String::new();
    svg_open(&mut out, PANEL_W, PANEL_H);
    panel(&mut out, 0.0, 0.0, PANEL_W, PANEL_H);
    out.push_str("</svg>\n");
    out
}

/// A picture `w` wide, `h` high, opened (`svg_open`) with its title centred at `y`.
pub(super) fn titled(w: f64, h: f64, y: u32, title: &str) -> String {
    let mut out = String::new();
    svg_open(&mut out, w, h);
    let _ = writeln!(
        out,
        r#"<text class="title" x="{:.1}" y="{y}" text-anchor="middle" font-size="20" font-weight="bold">{}</text>"#,
        w / 2.0,
        xml_escape(title)
    );
    out
}

pub(super) fn svg_open(out: &mut String, w: f64, h: f64) {
    let _ = writeln!(out, r#"<?xml version="1.0" encoding="UTF-8"?>"#);
    let _ = writeln!(
        out,
        r#"<svg xmlns="http://www.w3.org/2000/svg" version="1.1" width="{w:.0}" height="{h:.0}" viewBox="0 0 {w:.0} {h:.0}" font-family="{FONT}" font-size="12">"#
    );
    let _ = writeln!(out, r#"<rect x="0" y="0" width="{w:.0}" height="{h:.0}" fill="white"/>"#);
}

/// Greedy word wrap; `\n` forces a break; words longer than a line are split.
pub(super) fn wrap(text: &str, max_chars: usize) -> Vec<String> {
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
