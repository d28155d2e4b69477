//! The pictures' checks: well-formed XML, what each panel draws, degenerate inputs, and
//! the helpers; and sample pictures to look at.

use std::f64::consts::TAU;

use nalgebra::Vector2;

use super::axes::{decimals, nice_step, tick_label, ticks, time_ticks};
use super::history::C_FLAGGED;
use super::svg::{M_LEFT, PANEL_W, wrap};
use super::*;

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
        let svg = history_svg(&HistoryPlot { title: "", points: pts, coverage: 2.0, flagged_label: "", summary: "" });
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
