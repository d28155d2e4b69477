//! Regression tests for what fuzzing found (`fuzz/`, `scripts/fuzz.sh`): each replays the
//! minimised input through the same code path as its fuzz target and asserts the right
//! behaviour, a clear error rather than a panic or an abort.

use nalgebra::Vector2;
use tracer_calib::cell::NodeState;
use tracer_calib::engine::correct::resample_radii;
use tracer_calib::engine::geometry::Mounting;
use tracer_calib::interfaces::{CalibrateRequest, RawScan, from_cdr};
use tracer_calib::io::oma;
use tracer_calib::params::file as params_file;
use tracer_calib::params::{ParamValue, Parameters};

/// `fuzz/fuzz_targets/oma.rs`: a `TRCFMT` declaring an absurd point count made the reader
/// preallocate that many radii (`Vec::with_capacity(N)`): out of memory, or a "capacity
/// overflow" panic, before any radius was read. Now it is the usual count mismatch error.
#[test]
fn oma_absurd_point_count_is_an_error_not_an_allocation() {
    for n in ["99999999999", "4444444446", "18446744073709551615"] {
        let text = format!("TRCFMT=1;{n};E;R;F\r\nR=2350;2351\r\n");
        let e = oma::parse(&text, "huge.oma").unwrap_err().to_string();
        assert_eq!(e, format!("huge.oma:1: TRCFMT declares {n} points, the R= records that follow give 2 radii"));
    }
    // The fuzzer's own input, unminimised: CRLF, the TRCFMT, then a non-ASCII label.
    let crash = b"\r\nTRCFMT=1;4444444446;E;R;F\r\n\xd4=2";
    let e = oma::parse(&String::from_utf8_lossy(crash), "crash.oma").unwrap_err().to_string();
    assert!(e.starts_with("crash.oma:2: TRCFMT declares 4444444446 points"), "{e}");
}

/// The calibrated node of `fuzz/fuzz_targets/raw_scan.rs`.
fn calibrated_node() -> NodeState {
    let params = Parameters {
        calibration: Mounting::new(0.03, 0.004, -0.001),
        calibration_valid: true,
        resample_points: 360,
        ..Parameters::default()
    };
    NodeState::new("/cell1/tracer".into(), params)
}

/// `fuzz/fuzz_targets/raw_scan.rs`: a 3-sample scan of a 4-step revolution, one sample
/// 5 µm from the axis (counts -5) between two at 20 mm. The equal-angle resampling (a
/// cubic Hermite spline of radius over angle) dipped below zero next to the point near
/// the axis: the published `Contour.radii` held negative distances (down to -0.074 mm).
/// Now a radius is never negative. (Since then the node no longer resamples a scan with
/// a gap this wide; the spline is checked directly.)
#[test]
fn resampled_radii_are_never_negative() {
    const CDR: [u8; 64] = [
        0x00, 0x01, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x01, 0x00, 0x00, 0x00, 0x00, 0x00,
        0x00, 0x00, 0x06, 0x00, 0x00, 0x00, 0x02, 0x00, 0x00, 0x00, 0x04, 0x00, 0x00, 0x00, 0x03, 0x00, 0x00, 0x00,
        0x00, 0x00, 0x00, 0x00, 0x01, 0x00, 0x00, 0x00, 0x03, 0x00, 0x00, 0x00, 0x03, 0x00, 0x00, 0x00, 0x20, 0x4e,
        0x00, 0x00, 0x08, 0x52, 0x00, 0x00, 0xfb, 0xff, 0xff, 0xff,
    ];
    let msg: RawScan = from_cdr(&CDR).unwrap();
    assert_eq!(
        (msg.steps_per_revolution, &msg.step[..], &msg.counts[..]),
        (4, &[0, 1, 3][..], &[20_000, 21_000, -5][..])
    );
    let out = calibrated_node().on_raw_scan(&msg, true).unwrap();
    assert!(out.contour.points.iter().all(|p| p.x.is_finite() && p.y.is_finite()));
    // Since the default largest gap is at most 90°, the node gives this scan (a 180° gap)
    // no radii at all; the spline, allowed to bridge the gap, stays non-negative.
    assert!(out.contour.radii.is_empty());
    let points: Vec<Vector2<f64>> = out.contour.points.iter().map(|p| Vector2::new(p.x, p.y)).collect();
    let radii = resample_radii(&points, 360, std::f64::consts::TAU).unwrap();
    for (k, r) in radii.iter().enumerate() {
        assert!(r.is_finite() && *r >= 0.0, "radius {k} is {r}");
    }
}

/// `fuzz/fuzz_targets/params_file.rs` (found with the empty file): `params::file::render`
/// of no parameters wrote a bare `ros__parameters:` (a YAML null), which no reader takes
/// back ("expected a map of parameter names to values"). Now it writes an empty map.
#[test]
fn rendering_no_parameters_reads_back() {
    let parsed = params_file::parse("", "fuzz").unwrap();
    assert!(parsed.sections.is_empty());
    for fqn in ["/tracer_calibrator", "/cell1/tracer"] {
        let list: Vec<(String, ParamValue)> =
            parsed.entries_for(fqn).map(|e| (e.name.clone(), e.value.clone())).collect();
        let text = params_file::render(fqn, &list, "nothing to say");
        let back = params_file::parse(&text, "fuzz").unwrap_or_else(|e| panic!("{e}\n{text}"));
        assert_eq!(back.entries_for(fqn).count(), 0, "{text}");
        assert_eq!(back.sections.len(), 1, "{text}");
        let mut p = Parameters::default();
        assert!(p.apply_file(&back, fqn, "fuzz").unwrap().is_empty());
        assert_eq!(p, Parameters::default());
    }
}

/// `fuzz/fuzz_targets/raw_scan.rs`: steps 0, 1, 3 of a 6-step revolution, the third 5 µm
/// *behind* the axis (counts -5), so its point lies at angle -1e-16, which `rem_euclid`
/// maps to 2π itself: the same direction as the first point, at angle 0, but not merged
/// with it. The resampling then had a zero-width segment and published `inf` radii (and
/// NaN ones) in `Contour.radii`, with the default, uncalibrated parameters.
#[test]
fn resampled_radii_are_finite_when_two_points_meet_across_the_wrap() {
    const CDR: [u8; 64] = [
        0x00, 0x01, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x01, 0x00, 0x00, 0x00, 0x00, 0x00,
        0x00, 0x00, 0x06, 0x00, 0x00, 0x00, 0x02, 0x00, 0x00, 0x00, 0x06, 0x00, 0x00, 0x00, 0x03, 0x00, 0x00, 0x00,
        0x00, 0x00, 0x00, 0x00, 0x01, 0x00, 0x00, 0x00, 0x03, 0x00, 0x00, 0x00, 0x03, 0x00, 0x00, 0x00, 0x20, 0x4e,
        0x00, 0x00, 0x08, 0x52, 0x00, 0x00, 0xfb, 0xff, 0xff, 0xff,
    ];
    let msg: RawScan = from_cdr(&CDR).unwrap();
    assert_eq!(
        (msg.steps_per_revolution, &msg.step[..], &msg.counts[..]),
        (6, &[0, 1, 3][..], &[20_000, 21_000, -5][..])
    );
    for mut st in [NodeState::new("/tracer_calibrator".into(), Parameters::default()), calibrated_node()] {
        let out = st.on_raw_scan(&msg, true).unwrap();
        // A 180° gap: since the default largest gap is at most 90°, the node gives no
        // radii; the spline, allowed to bridge the gap, is checked on its points.
        assert!(out.contour.radii.is_empty());
        let points: Vec<Vector2<f64>> = out.contour.points.iter().map(|p| Vector2::new(p.x, p.y)).collect();
        // (None when the points meeting across the wrap merge to fewer than three.)
        let radii = resample_radii(&points, 360, std::f64::consts::TAU).unwrap_or_default();
        for (k, r) in radii.iter().enumerate() {
            assert!(r.is_finite() && *r >= 0.0, "radius {k} is {r}");
        }
    }
    // The resampling itself: a point at angle 0 and one at a hair below 2π are one.
    let pts = [Vector2::new(0.02, 0.0), Vector2::new(0.0, 0.021), Vector2::new(-0.02, 0.0), Vector2::new(5e-6, -1e-21)];
    let radii = resample_radii(&pts, 8, 10.0).unwrap();
    assert!(radii.iter().all(|r| r.is_finite() && *r >= 0.0), "{radii:?}");
}

/// `fuzz/fuzz_targets/params_file.rs`: a quoted string in a sequence came out of the
/// reader with YAML quotes in its value (`[a, "b c"]` gave `["a", "'b c'"]`: the items
/// were turned into strings with `to_string`, which writes YAML), and each render and
/// read added another layer of quotes.
#[test]
fn quoted_strings_in_arrays_read_as_written() {
    let text = "n:\n  ros__parameters:\n    tags: [a, \"b \\x25c\", 'd e', \"1\", '']\n";
    let f = params_file::parse(text, "fuzz").unwrap();
    let want = ParamValue::StringArray(vec!["a".into(), "b %c".into(), "d e".into(), "1".into(), String::new()]);
    let got: Vec<_> = f.entries_for("/n").map(|e| e.value.clone()).collect();
    assert_eq!(got, std::slice::from_ref(&want));
    let rendered = params_file::render("/n", &[("tags".into(), want.clone())], "");
    let back = params_file::parse(&rendered, "fuzz").unwrap();
    assert_eq!(
        back.entries_for("/n").map(|e| e.value.clone()).collect::<Vec<_>>(),
        std::slice::from_ref(&want),
        "{rendered}"
    );
    assert_eq!(ParamValue::parse_yaml(&want.to_yaml()).unwrap(), want);
}

/// `fuzz/fuzz_targets/raw_scan.rs`, its node with parameters from the message (`frame_id`
/// "meters_per_count[,alpha0,offset,delta_l]"): parameters the node accepts (any positive
/// finite `encoder.meters_per_count`, any finite `calibration.offset` / `delta_l`) can put
/// the corrected points near 1e308 m: `Contour.radii` came out NaN (sqrt(x² + y²)
/// overflows) and the `PolygonStamped` points inf (f32). Now such a scan is refused with
/// a message naming the parameters, and counted; a plate scan is still kept for
/// `/calibrate`.
#[test]
fn contours_out_of_float_range_are_refused() {
    let msg = RawScan {
        target: RawScan::TARGET_CALIBRATION_PLATE,
        steps_per_revolution: 8,
        step: (0..8).collect(),
        counts: vec![1_000_000_000; 8],
        ..Default::default()
    };
    let cases: [&[(&str, f64)]; 3] = [
        &[("encoder.meters_per_count", 1e299)],
        &[("calibration.offset", 1e308)],
        &[("encoder.meters_per_count", 1e-6), ("calibration.delta_l", -1e300)],
    ];
    for case in cases {
        let mut p = Parameters::default();
        for (name, v) in case {
            p.set(name, &ParamValue::Double(*v)).unwrap();
        }
        p.calibration_valid = case.iter().any(|(n, _)| n.starts_with("calibration."));
        let mut st = NodeState::new("/tuned".into(), p);
        let e = st.on_raw_scan(&msg, true).unwrap_err();
        assert!(matches!(e, tracer_calib::cell::intake::ScanRejected::OutOfRange { .. }), "{case:?}: {e}");
        assert!(e.to_string().contains("is out of range (check encoder.meters_per_count and the calibration)"), "{e}");
        assert_eq!(st.stats.scans_rejected, 1);
        assert_eq!(st.stats.contours_published, 0);
        // The plate scan was kept: /calibrate finds it (and fails on its own terms).
        let out =
            st.on_calibrate(&CalibrateRequest { scan_id: 0, dry_run: true, ring_scan_id: 0, plate_scan_ids: vec![] });
        assert!(!out.response.message.contains("no calibration-plate scan"), "{}", out.response.message);
    }
    // The largest scale that still fits is published, finite.
    let mut p = Parameters::default();
    p.set("encoder.meters_per_count", &ParamValue::Double(1e28)).unwrap();
    let out = NodeState::new("/tuned".into(), p).on_raw_scan(&msg, true).unwrap();
    assert!(out.contour.points.iter().all(|q| q.x.is_finite() && q.y.is_finite()));
    assert!(out.contour.radii.iter().all(|r| r.is_finite() && *r >= 0.0), "{:?}", out.contour.radii);
    assert!(out.polygon.unwrap().polygon.points.iter().all(|q| q.x.is_finite() && q.y.is_finite()));
}
