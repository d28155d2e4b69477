//! The mirrors against their definitions and the wire: CDR round trips of every type,
//! byte-exact layouts, names, and the drift checks (struct vs `.msg` text, `.msg` text vs
//! the files in `msg/`).

use std::fmt;

use rustdds::RepresentationIdentifier;
use serde::Serialize;

use super::shape::{check_struct_against_definition, check_struct_against_fields};
use super::*;
use crate::interfaces::definition;

/// `$f::<T>()` for every mirrored type.
macro_rules! for_every_type {
    ($f:ident) => {
        $f::<Time>();
        $f::<Header>();
        $f::<RawScan>();
        $f::<Contour>();
        $f::<Point>();
        $f::<Point32>();
        $f::<Polygon>();
        $f::<PolygonStamped>();
        $f::<KeyValue>();
        $f::<DiagnosticStatus>();
        $f::<DiagnosticArray>();
        $f::<CalibrateRequest>();
        $f::<CalibrateResponse>();
        $f::<Calibration>();
    };
}

/// A value of the type with distinct field values and non-empty sequences.
trait Sample: Sized {
    fn sample() -> Self;
    /// The sample as a publisher built before its trailing sequence was appended sends it,
    /// for a type that has one (`cdr::absent_at_end`).
    fn without_trailing(&self) -> Option<Self> {
        None
    }
}

impl Sample for Time {
    fn sample() -> Self {
        Time::new(1_700_000_123, 456_789)
    }
}
impl Sample for Header {
    fn sample() -> Self {
        Header { stamp: Time::sample(), frame_id: "tracer".into() }
    }
}
impl Sample for RawScan {
    fn sample() -> Self {
        RawScan {
            header: Header::sample(),
            scan_id: 42,
            target: RawScan::TARGET_LENS,
            steps_per_revolution: 400,
            step: vec![0, 1, 2, 399],
            counts: vec![-5, 0, 17_000_000, i32::MIN],
            height_counts: vec![3, -2, 0, i32::MAX],
        }
    }
    fn without_trailing(&self) -> Option<Self> {
        Some(RawScan { height_counts: Vec::new(), ..self.clone() })
    }
}
impl Sample for Point {
    fn sample() -> Self {
        Point { x: 0.25, y: -1.5e-3, z: 3.0 }
    }
}
impl Sample for Point32 {
    fn sample() -> Self {
        Point32 { x: 0.5, y: -2.25, z: 7.0 }
    }
}
impl Sample for Contour {
    fn sample() -> Self {
        Contour {
            header: Header::sample(),
            scan_id: 9,
            target: RawScan::TARGET_FRAME,
            calibrated: true,
            points: vec![Point::sample(), Point { x: 1.0, y: 2.0, z: 0.0 }],
            radii: vec![0.021, 0.0215, f64::MIN_POSITIVE],
            circumference: 0.1276,
            box_width: 0.05,
            box_height: 0.0305,
            effective_diameter: 0.0512,
            size_u95: [4.5e-6, 2.5e-6, 3.0e-6, 6.25e-6],
            radii_u95: vec![2e-6, 2.5e-6, 3e-6],
            calibration_stamp: Time::from_nanos(1_700_000_010_000_000_250),
            calibration_scan_id: 10,
            circumference_3d: 0.1286,
            circumference_3d_u95: 5.5e-6,
            frame_curve: 6.0,
        }
    }
}
impl Sample for Polygon {
    fn sample() -> Self {
        Polygon { points: vec![Point32::sample(), Point32 { x: 1.0, y: 0.0, z: 0.0 }] }
    }
}
impl Sample for PolygonStamped {
    fn sample() -> Self {
        PolygonStamped { header: Header::sample(), polygon: Polygon::sample() }
    }
}
impl Sample for KeyValue {
    fn sample() -> Self {
        KeyValue { key: "rms_residual".into(), value: "1.2e-6".into() }
    }
}
impl Sample for DiagnosticStatus {
    fn sample() -> Self {
        DiagnosticStatus {
            level: DiagnosticStatus::WARN,
            name: "tracer_calibrator: calibration".into(),
            message: "not calibrated".into(),
            hardware_id: "tracer-7".into(),
            values: vec![KeyValue::sample(), KeyValue { key: "ünïcode".into(), value: String::new() }],
        }
    }
}
impl Sample for DiagnosticArray {
    fn sample() -> Self {
        DiagnosticArray { header: Header::sample(), status: vec![DiagnosticStatus::sample()] }
    }
}
impl Sample for CalibrateRequest {
    fn sample() -> Self {
        CalibrateRequest { scan_id: 77, dry_run: true, ring_scan_id: 78, plate_scan_ids: vec![77, 79] }
    }
}
impl Sample for CalibrateResponse {
    fn sample() -> Self {
        CalibrateResponse {
            success: true,
            message: "converged".into(),
            alpha0: 0.0349,
            offset: -1.25e-4,
            delta_l: 3.5e-5,
            stddev: vec![1e-5, 2e-6, 3e-6],
            rms_residual: 4.5e-6,
            iterations: 12,
            samples_used: 398,
            scale: 1.0025,
            scale_stddev: 2.1e-4,
            tip_radius: 0.0,
            tip_radius_stddev: 0.0,
            covariance: (0..49).map(|i| if i % 8 == 0 { 1e-10 } else { 1e-12 }).collect(),
            covariance_names: ["alpha0", "offset", "delta_l", "scale", "tip_radius", "angle_c1", "angle_s1"]
                .map(String::from)
                .to_vec(),
            angle_harmonics: vec![1],
            angle_coefficients: vec![8.7e-4, -1.2e-4],
            error_code: CalibrateResponse::ERROR_NONE,
        }
    }
}
impl Sample for Calibration {
    fn sample() -> Self {
        Calibration {
            header: Header::sample(),
            valid: true,
            model: "full_scale".into(),
            scan_id: 31,
            alpha0: 0.0349,
            offset: -1.25e-4,
            delta_l: 3.5e-5,
            scale: 0.9975,
            stddev: vec![1e-5, 2e-6, 3e-6, 2e-4],
            rms_residual: 4.5e-6,
            samples_used: 398,
            tip_radius: 2.5e-4,
            covariance: vec![1e-12; 49],
            covariance_names: ["alpha0", "offset", "delta_l", "scale", "tip_radius", "angle_c2", "angle_s2"]
                .map(String::from)
                .to_vec(),
            angle_harmonics: vec![2],
            angle_coefficients: vec![3.5e-4, 1e-5],
        }
    }
}

// ---------------------------------------------------------------- round trips

fn round_trip<T: RosMsg + Sample + PartialEq + fmt::Debug>() {
    let value = T::sample();
    let bytes = to_cdr(&value).unwrap();
    assert_eq!(&bytes[..4], &CDR_LE_HEADER, "{}", T::NAME.ros_name());
    let back: T = from_cdr(&bytes).unwrap();
    assert_eq!(back, value, "{}", T::NAME.ros_name());
    // Every strict prefix of the payload is an error, never a panic or a wrong value; but
    // the one that ends where a trailing sequence a later version appended begins, which is
    // the message without it (and with up to 3 bytes after it, which plain CDR takes as
    // padding).
    for cut in 4..bytes.len() {
        let truncated = &bytes[..cut];
        match from_cdr::<T>(truncated) {
            Err(_) => {}
            Ok(v) => assert!(
                Some(&v) == value.without_trailing().as_ref()
                    && to_cdr(&v).is_ok_and(|b| (cut + 4).checked_sub(b.len()).is_some_and(|pad| pad < 4)),
                "{} decoded from {cut} of {} bytes",
                T::NAME.ros_name(),
                bytes.len()
            ),
        }
    }
    // Also through rustdds' DDS adapter, the path the publisher and subscription take.
    use rustdds::no_key::{Decode, DefaultDecoder, SerializerAdapter};
    use rustdds::serialization::{CDRDeserializerAdapter, CDRSerializerAdapter};
    let payload = <CDRSerializerAdapter<T> as SerializerAdapter<T>>::to_bytes(&value).unwrap();
    assert_eq!(&payload[..], &bytes[4..]);
    let decoder = <CDRDeserializerAdapter<T> as DefaultDecoder<T>>::DECODER;
    let back: T = decoder.decode_bytes(&payload[..], RepresentationIdentifier::CDR_LE).unwrap();
    assert_eq!(back, value);
}

#[test]
fn cdr_round_trip_of_every_type() {
    for_every_type!(round_trip);
}

#[test]
fn messages_of_an_earlier_layout_decode_with_the_appended_fields_absent() {
    // A contour as the version before the height channel wrote it: up to
    // calibration_scan_id, without the 3-D figures.
    let now = Contour { circumference_3d: 0.0, circumference_3d_u95: 0.0, frame_curve: 0.0, ..Contour::sample() };
    let c = now.clone();
    let before_3d = to_cdr(&(
        c.header,
        c.scan_id,
        c.target,
        c.calibrated,
        c.points,
        c.radii,
        c.circumference,
        c.box_width,
        c.box_height,
        c.effective_diameter,
        c.size_u95,
        c.radii_u95,
        c.calibration_stamp,
        c.calibration_scan_id,
    ))
    .unwrap();
    let full = to_cdr(&now).unwrap();
    assert!(full.starts_with(&before_3d) && full.len() > before_3d.len());
    assert!(from_cdr::<Contour>(&before_3d).is_err(), "not the current layout");
    assert_eq!(from_cdr_msg::<Contour>(&before_3d).unwrap(), now);
    // The one before: up to radii_u95, without the calibration it was corrected with (a
    // Time and a uint32: 12 bytes after the 8-aligned doubles).
    let now = Contour { calibration_stamp: Time::ZERO, calibration_scan_id: 0, ..now };
    let earlier = &before_3d[..before_3d.len() - 12];
    assert!(from_cdr::<Contour>(earlier).is_err(), "not the current layout");
    assert_eq!(from_cdr_msg::<Contour>(earlier).unwrap(), now);
    // And as the first version wrote it: up to radii, before the size figures.
    let first = Contour {
        circumference: 0.0,
        box_width: 0.0,
        box_height: 0.0,
        effective_diameter: 0.0,
        size_u95: [0.0; 4],
        radii_u95: Vec::new(),
        ..now.clone()
    };
    let f = first.clone();
    let first_bytes = to_cdr(&(f.header, f.scan_id, f.target, f.calibrated, f.points, f.radii)).unwrap();
    assert_eq!(from_cdr_msg::<Contour>(&first_bytes).unwrap(), first);
    // Cut anywhere else, it is still an error.
    for cut in [1, 4, 8, 13, 20] {
        assert!(from_cdr_msg::<Contour>(&first_bytes[..first_bytes.len() - cut]).is_err(), "cut {cut}");
    }
}

#[test]
fn a_raw_scan_of_a_driver_without_heights_reads_as_no_heights() {
    use rustdds::RepresentationIdentifier;
    use rustdds::no_key::{Decode, DefaultDecoder};
    use rustdds::serialization::CDRDeserializerAdapter;
    // What a driver built against the RawScan before height_counts sends: the message up to
    // counts. Over DDS (the subscription's decoder) and from a bag, it reads as no heights.
    let scan = RawScan { height_counts: Vec::new(), ..RawScan::sample() };
    let s = scan.clone();
    let earlier = to_cdr(&(s.header, s.scan_id, s.target, s.steps_per_revolution, s.step, s.counts)).unwrap();
    assert_eq!(to_cdr(&scan).unwrap().len(), earlier.len() + 4, "the current layout adds the heights' count");
    let decoder = || <CDRDeserializerAdapter<RawScan> as DefaultDecoder<RawScan>>::DECODER;
    let read: RawScan = decoder().decode_bytes(&earlier[4..], RepresentationIdentifier::CDR_LE).unwrap();
    assert_eq!(read, scan);
    assert_eq!(from_cdr_msg::<RawScan>(&earlier).unwrap(), scan);
    // A scan with heights, cut within them, is truncated: an error, not "no heights".
    let with = to_cdr(&RawScan::sample()).unwrap();
    for cut in [1, 4, 8, 12] {
        assert!(from_cdr_msg::<RawScan>(&with[..with.len() - cut]).is_err(), "cut {cut}");
        assert!(
            decoder().decode_bytes(&with[4..with.len() - cut], RepresentationIdentifier::CDR_LE).is_err(),
            "cut {cut}"
        );
    }
    // Cut within counts, it is an error too.
    assert!(from_cdr_msg::<RawScan>(&earlier[..earlier.len() - 4]).is_err());
}

#[test]
fn round_trip_of_defaults_and_empty_sequences() {
    let bytes = to_cdr(&RawScan::default()).unwrap();
    assert_eq!(from_cdr::<RawScan>(&bytes).unwrap(), RawScan::default());
    let bytes = to_cdr(&Contour::default()).unwrap();
    assert_eq!(from_cdr::<Contour>(&bytes).unwrap(), Contour::default());
    let bytes = to_cdr(&CalibrateResponse::default()).unwrap();
    assert_eq!(from_cdr::<CalibrateResponse>(&bytes).unwrap(), CalibrateResponse::default());
}

#[test]
fn big_endian_input_is_decoded() {
    // CalibrateRequest { scan_id: 0x01020304, dry_run: true, ring_scan_id: 5, plate_scan_ids: [9] } in
    // big-endian CDR.
    let bytes = [0x00, 0x00, 0x00, 0x00, 0x01, 0x02, 0x03, 0x04, 0x01, 0, 0, 0, 0, 0, 0, 5, 0, 0, 0, 1, 0, 0, 0, 9];
    let req: CalibrateRequest = from_cdr(&bytes).unwrap();
    assert_eq!(req, CalibrateRequest { scan_id: 0x0102_0304, dry_run: true, ring_scan_id: 5, plate_scan_ids: vec![9] });
}

#[test]
fn bad_cdr_is_rejected() {
    assert_eq!(from_cdr::<CalibrateRequest>(&[0, 1]), Err(CdrError::TooShort(2)));
    let xcdr2 = [0x00, 0x07, 0x00, 0x00, 1, 0, 0, 0, 1];
    assert_eq!(from_cdr::<CalibrateRequest>(&xcdr2), Err(CdrError::Encapsulation([0x00, 0x07])));
    // bool must be 0 or 1
    let bad_bool = [0x00, 0x01, 0x00, 0x00, 1, 0, 0, 0, 2];
    assert!(matches!(from_cdr::<CalibrateRequest>(&bad_bool), Err(CdrError::Codec(_))));
    // padding to 4 is fine, a whole extra word is not: KeyValue { key: "k", value: "a" }
    // is 14 bytes, padded to 16
    let padded = [0x00, 0x01, 0x00, 0x02, 2, 0, 0, 0, b'k', 0, 0, 0, 2, 0, 0, 0, b'a', 0, 0, 0];
    assert_eq!(from_cdr::<KeyValue>(&padded).unwrap(), KeyValue { key: "k".into(), value: "a".into() });
    let mut long = padded.to_vec();
    long.extend([0, 0, 0, 0]);
    assert_eq!(from_cdr::<KeyValue>(&long), Err(CdrError::TrailingBytes(6)));
}

// ---------------------------------------------------------------- byte-exact layout

#[test]
fn raw_scan_bytes_match_hand_computed_cdr() {
    let scan = RawScan {
        header: Header { stamp: Time::new(1, 2), frame_id: "ab".into() },
        scan_id: 7,
        target: RawScan::TARGET_CALIBRATION_PLATE,
        steps_per_revolution: 400,
        step: vec![0, 1],
        counts: vec![-1, 5],
        height_counts: Vec::new(),
    };
    #[rustfmt::skip]
    let expected: &[u8] = &[
        0x00, 0x01, 0x00, 0x00, // encapsulation: CDR little-endian, options 0
        0x01, 0x00, 0x00, 0x00, // [0]  header.stamp.sec = 1
        0x02, 0x00, 0x00, 0x00, // [4]  header.stamp.nanosec = 2
        0x03, 0x00, 0x00, 0x00, // [8]  header.frame_id length 3 (incl. NUL)
        b'a', b'b', 0x00,       // [12] "ab\0"
        0x00,                   // [15] pad to 4
        0x07, 0x00, 0x00, 0x00, // [16] scan_id = 7
        0x01,                   // [20] target = 1
        0x00, 0x00, 0x00,       // [21] pad to 4
        0x90, 0x01, 0x00, 0x00, // [24] steps_per_revolution = 400
        0x02, 0x00, 0x00, 0x00, // [28] step: 2 elements
        0x00, 0x00, 0x00, 0x00, // [32] 0
        0x01, 0x00, 0x00, 0x00, // [36] 1
        0x02, 0x00, 0x00, 0x00, // [40] counts: 2 elements
        0xff, 0xff, 0xff, 0xff, // [44] -1
        0x05, 0x00, 0x00, 0x00, // [48] 5
        0x00, 0x00, 0x00, 0x00, // [52] height_counts: none (no height channel)
    ];
    let bytes = to_cdr(&scan).unwrap();
    assert_eq!(bytes, expected);
    assert_eq!(from_cdr::<RawScan>(expected).unwrap(), scan);
    // From a driver built before height_counts was appended: the same, no heights.
    assert_eq!(from_cdr::<RawScan>(&expected[..expected.len() - 4]).unwrap(), scan);
}

#[test]
fn calibrate_response_bytes_align_f64_after_the_header() {
    let resp = CalibrateResponse {
        success: true,
        message: "ok".into(),
        alpha0: 1.0,
        offset: -2.0,
        delta_l: 0.5,
        stddev: vec![0.25],
        rms_residual: 4.0,
        iterations: 3,
        samples_used: 400,
        scale: 1.5,
        scale_stddev: 0.125,
        tip_radius: 0.75,
        tip_radius_stddev: 0.0625,
        covariance: vec![2.0],
        covariance_names: vec!["alpha0".into()],
        angle_harmonics: vec![1],
        angle_coefficients: vec![0.5],
        error_code: CalibrateResponse::ERROR_RING_MISMATCH,
    };
    let mut expected = CDR_LE_HEADER.to_vec();
    expected.extend([0x01]); // [0] success
    expected.extend([0, 0, 0]); // [1] pad to 4
    expected.extend(3u32.to_le_bytes()); // [4] "ok\0" length
    expected.extend(b"ok\0"); // [8]
    expected.extend([0, 0, 0, 0, 0]); // [11] pad to 8 (counted after the header)
    expected.extend(1.0f64.to_le_bytes()); // [16] alpha0
    expected.extend((-2.0f64).to_le_bytes()); // [24] offset
    expected.extend(0.5f64.to_le_bytes()); // [32] delta_l
    expected.extend(1u32.to_le_bytes()); // [40] stddev count
    expected.extend([0, 0, 0, 0]); // [44] pad to 8
    expected.extend(0.25f64.to_le_bytes()); // [48] stddev[0]
    expected.extend(4.0f64.to_le_bytes()); // [56] rms_residual
    expected.extend(3u32.to_le_bytes()); // [64] iterations
    expected.extend(400u32.to_le_bytes()); // [68] samples_used
    expected.extend(1.5f64.to_le_bytes()); // [72] scale
    expected.extend(0.125f64.to_le_bytes()); // [80] scale_stddev
    expected.extend(0.75f64.to_le_bytes()); // [88] tip_radius
    expected.extend(0.0625f64.to_le_bytes()); // [96] tip_radius_stddev
    expected.extend(1u32.to_le_bytes()); // [104] covariance count
    expected.extend([0, 0, 0, 0]); // [108] pad to 8
    expected.extend(2.0f64.to_le_bytes()); // [112] covariance[0]
    expected.extend(1u32.to_le_bytes()); // [120] covariance_names count
    expected.extend(7u32.to_le_bytes()); // [124] "alpha0\0" length
    expected.extend(b"alpha0\0"); // [128]
    expected.extend([0]); // [135] pad to 4
    expected.extend(1u32.to_le_bytes()); // [136] angle_harmonics count
    expected.extend(1i32.to_le_bytes()); // [140] angle_harmonics[0]
    expected.extend(1u32.to_le_bytes()); // [144] angle_coefficients count
    expected.extend([0, 0, 0, 0]); // [148] pad to 8
    expected.extend(0.5f64.to_le_bytes()); // [152] angle_coefficients[0]
    expected.extend(12u16.to_le_bytes()); // [160] error_code
    assert_eq!(to_cdr(&resp).unwrap(), expected);
    assert_eq!(from_cdr::<CalibrateResponse>(&expected).unwrap(), resp);
}

#[test]
fn diagnostic_level_is_one_octet() {
    let status = DiagnosticStatus { level: DiagnosticStatus::STALE, ..Default::default() };
    let bytes = to_cdr(&status).unwrap();
    // level, pad 3, then three empty strings (length 1, NUL, pad 3), then a 0 count.
    let mut expected = CDR_LE_HEADER.to_vec();
    expected.extend([3, 0, 0, 0]);
    for _ in 0..3 {
        expected.extend([1, 0, 0, 0, 0, 0, 0, 0]);
    }
    expected.extend([0, 0, 0, 0]);
    assert_eq!(bytes, expected);
}

// ---------------------------------------------------------------- names

#[test]
fn type_names_follow_ros_conventions() {
    assert_eq!(RawScan::NAME.ros_name(), "tracer_calib_msgs/msg/RawScan");
    assert_eq!(RawScan::NAME.dds_type_name(), "tracer_calib_msgs::msg::dds_::RawScan_");
    assert_eq!(Contour::NAME.dds_type_name(), "tracer_calib_msgs::msg::dds_::Contour_");
    assert_eq!(PolygonStamped::NAME.ros_name(), "geometry_msgs/msg/PolygonStamped");
    assert_eq!(DiagnosticArray::NAME.dds_type_name(), "diagnostic_msgs::msg::dds_::DiagnosticArray_");
    assert_eq!(Header::NAME.dds_type_name(), "std_msgs::msg::dds_::Header_");
    assert_eq!(CalibrateRequest::NAME.dds_type_name(), "tracer_calib_msgs::srv::dds_::Calibrate_Request_");
    assert_eq!(CalibrateResponse::NAME.dds_type_name(), "tracer_calib_msgs::srv::dds_::Calibrate_Response_");
    // ros2-client's own forms.
    let m = RawScan::NAME.message_type_name();
    assert_eq!(m.dds_msg_type(), "tracer_calib_msgs::msg::dds_::RawScan_");
    let s = Calibrate::type_name();
    assert_eq!((s.package_name(), s.type_name()), ("tracer_calib_msgs", "Calibrate"));
    // The request/response halves are named after the service.
    assert_eq!(<Calibrate as RosService>::Request::NAME.name, format!("{}_Request", Calibrate::NAME.name));
    assert_eq!(<Calibrate as RosService>::Response::NAME.name, format!("{}_Response", Calibrate::NAME.name));
}

#[test]
#[should_panic(expected = "is not a message type")]
fn service_names_are_not_message_type_names() {
    let _ = Calibrate::NAME.message_type_name();
}

#[test]
fn calibrate_response_json_has_the_contract_fields_in_order() {
    let json = serde_json::to_string(&CalibrateResponse::sample()).unwrap();
    let keys = [
        "success",
        "message",
        "alpha0",
        "offset",
        "delta_l",
        "stddev",
        "rms_residual",
        "iterations",
        "samples_used",
        "scale",
        "scale_stddev",
    ];
    let mut at = 0;
    for key in keys {
        let pos = json[at..].find(&format!("\"{key}\":")).unwrap_or_else(|| panic!("{key} missing in {json}"));
        at += pos + 1;
    }
}

// ---------------------------------------------------------------- struct vs definition

fn check_type<T: RosMsg + Sample>() {
    if let Err(e) = check_struct_against_definition(&T::sample(), T::DEFINITION.text(), T::NAME.package) {
        panic!("{}: {e}", T::NAME.ros_name());
    }
}

#[test]
fn every_struct_serializes_as_its_definition() {
    for_every_type!(check_type);
}

#[test]
fn every_type_is_known_with_its_complete_definition() {
    fn known<T: RosMsg>() {
        assert!(KNOWN.contains(&(T::NAME, T::DEFINITION)), "{} missing in KNOWN", T::NAME.ros_name());
        if T::NAME.kind == InterfaceKind::Msg {
            assert!(definition::full_definition_of::<T>().is_some(), "{}: dependencies", T::NAME.ros_name());
        }
    }
    for_every_type!(known);
    known::<ServiceEventInfo>();
    // Every text is known: each .msg once, each .srv as its two halves.
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    let count = |dir: &str, ext: &str| -> usize {
        let dir = root.join(dir);
        let mut dirs = vec![dir];
        let mut n = 0;
        while let Some(d) = dirs.pop() {
            for e in std::fs::read_dir(&d).unwrap() {
                let p = e.unwrap().path();
                if p.is_dir() {
                    dirs.push(p);
                } else if p.extension().is_some_and(|x| x == ext) {
                    n += 1;
                }
            }
        }
        n
    };
    let texts = count("msg/msg", "msg")
        + count("src/interfaces/standard/msg", "msg")
        + 2 * (count("msg/srv", "srv") + count("src/interfaces/standard/srv", "srv"));
    assert_eq!(KNOWN.len(), texts);
    for (name, _) in KNOWN {
        assert_eq!(KNOWN.iter().filter(|(n, _)| n == name).count(), 1, "{} twice", name.ros_name());
    }
}

#[test]
fn the_struct_check_catches_rust_side_drift() {
    #[derive(Serialize)]
    struct Reordered {
        scan_id: u32,
        dry_run: bool,
        extra: u8,
    }
    #[derive(Serialize)]
    struct Swapped {
        dry_run: bool,
        scan_id: u32,
    }
    #[derive(Serialize)]
    struct Renamed {
        scan: u32,
        dry_run: bool,
    }
    #[derive(Serialize)]
    struct Retyped {
        scan_id: u64,
        dry_run: bool,
    }
    #[derive(Serialize)]
    struct Skips {
        scan_id: u32,
        #[serde(skip_serializing_if = "std::ops::Not::not")]
        dry_run: bool,
    }
    // The request's first two fields, `scan_id` and `dry_run`.
    let fields = definition::fields(CalibrateRequest::DEFINITION.text(), "tracer_calib_msgs").unwrap();
    let fields = &fields[..2].to_vec();
    assert!(check_struct_against_fields(&Reordered { scan_id: 1, dry_run: true, extra: 2 }, fields).is_err());
    assert!(check_struct_against_fields(&Swapped { dry_run: true, scan_id: 1 }, fields).is_err());
    assert!(check_struct_against_fields(&Renamed { scan: 1, dry_run: true }, fields).is_err());
    assert!(check_struct_against_fields(&Retyped { scan_id: 1, dry_run: true }, fields).is_err());
    assert!(check_struct_against_fields(&Skips { scan_id: 1, dry_run: false }, fields).is_err());
    // and a correct twin passes
    #[derive(Serialize)]
    struct Twin {
        scan_id: u32,
        dry_run: bool,
    }
    assert_eq!(check_struct_against_fields(&Twin { scan_id: 1, dry_run: true }, fields), Ok(()));
    // nested types are compared by name
    let mut wrong_nested = definition::fields(Contour::DEFINITION.text(), "tracer_calib_msgs").unwrap();
    wrong_nested[4] = ("geometry_msgs/msg/Point32[]".into(), "points".into());
    assert!(check_struct_against_fields(&Contour::sample(), &wrong_nested).is_err());
}

// ---------------------------------------------------------------- .msg / .srv drift

fn read_interface(relative: &str) -> String {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join(relative);
    std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("cannot read {}: {e}", path.display()))
}

/// Checks a message's struct and constants against a `.msg` text.
fn check_msg_text<T: RosMsg + Sample>(file: &str, text: &str) -> Result<(), String> {
    check_struct_against_definition(&T::sample(), text, T::NAME.package).map_err(|e| format!("{file}: {e}"))?;
    let (declared, ours) = (definition::constants(text)?, definition::constants(T::DEFINITION.text())?);
    if declared != ours {
        return Err(format!("{file}: constants {declared:?}, the mirror's {ours:?}"));
    }
    Ok(())
}

/// Checks the request and response structs against a `.srv` text.
fn check_srv_text(file: &str, text: &str) -> Result<(), String> {
    let parts: Vec<&str> = text.split("\n---\n").collect();
    if parts.len() != 2 {
        return Err(format!("{file}: a service has exactly one '---', found {}", parts.len() - 1));
    }
    let package = Calibrate::NAME.package;
    check_struct_against_definition(&CalibrateRequest::sample(), parts[0], package)
        .map_err(|e| format!("{file} section 0: {e}"))?;
    check_struct_against_definition(&CalibrateResponse::sample(), parts[1], package)
        .map_err(|e| format!("{file} section 1: {e}"))
}

#[test]
fn mirrors_match_the_interface_files() {
    check_msg_text::<RawScan>("msg/msg/RawScan.msg", &read_interface("msg/msg/RawScan.msg")).unwrap();
    check_msg_text::<Contour>("msg/msg/Contour.msg", &read_interface("msg/msg/Contour.msg")).unwrap();
    check_msg_text::<Calibration>("msg/msg/Calibration.msg", &read_interface("msg/msg/Calibration.msg")).unwrap();
    check_srv_text("msg/srv/Calibrate.srv", &read_interface("msg/srv/Calibrate.srv")).unwrap();
    // The definitions the bags store and the type hashes are computed from are those files.
    assert_eq!(RawScan::DEFINITION.text(), read_interface("msg/msg/RawScan.msg"));
    assert_eq!(
        format!("{}---\n{}", CalibrateRequest::DEFINITION.text(), CalibrateResponse::DEFINITION.text()),
        read_interface("msg/srv/Calibrate.srv")
    );
}

#[test]
fn the_file_check_catches_interface_drift() {
    let original = read_interface("msg/msg/RawScan.msg");
    let file = "RawScan.msg (edited)";
    assert_eq!(check_msg_text::<RawScan>(file, &original), Ok(()));
    // a field added
    let added = format!("{original}float64 temperature\n");
    assert!(check_msg_text::<RawScan>(file, &added).is_err());
    // a field renamed
    let renamed = original.replace("int32[] counts", "int32[] count");
    assert_ne!(renamed, original);
    assert!(check_msg_text::<RawScan>(file, &renamed).is_err());
    // a field retyped
    let retyped = original.replace("uint32 scan_id", "uint64 scan_id");
    assert_ne!(retyped, original);
    assert!(check_msg_text::<RawScan>(file, &retyped).is_err());
    // two fields swapped
    let swapped = original
        .replace("uint32[] step", "@@STEP@@")
        .replace("int32[] counts", "uint32[] step")
        .replace("@@STEP@@", "int32[] counts");
    assert!(check_msg_text::<RawScan>(file, &swapped).is_err());
    // a constant changed or added
    let constant = original.replace("TARGET_LENS=3", "TARGET_LENS=4");
    assert_ne!(constant, original);
    assert!(check_msg_text::<RawScan>(file, &constant).is_err());
    let more = format!("uint8 TARGET_PATTERN=4\n{original}");
    assert!(check_msg_text::<RawScan>(file, &more).is_err());
    // comments and blank lines do not matter
    let commented = format!("# a new comment\n\n{}", original.replace('#', "  # more #"));
    assert_eq!(check_msg_text::<RawScan>(file, &commented), Ok(()));
    // `Header` vs `std_msgs/Header` vs `std_msgs/msg/Header` are the same type
    let long = original.replace("std_msgs/Header", "std_msgs/msg/Header");
    assert_eq!(check_msg_text::<RawScan>(file, &long), Ok(()));

    let srv = read_interface("msg/srv/Calibrate.srv");
    assert_eq!(check_srv_text("Calibrate.srv", &srv), Ok(()));
    let moved = srv.replacen("---\n", "", 1).replacen("string message", "---\nstring message", 1);
    assert!(check_srv_text("Calibrate.srv", &moved).is_err());
    let no_sep = srv.replacen("---", "", 1);
    assert!(check_srv_text("Calibrate.srv", &no_sep).is_err());
    let response_field = srv.replace("uint32 samples_used", "uint32 samples");
    assert!(check_srv_text("Calibrate.srv", &response_field).is_err());
}

#[test]
fn constants_match_their_associated_consts() {
    let declared = |text: &str| -> Vec<(String, u8)> {
        definition::constants(text)
            .unwrap()
            .into_iter()
            .map(|(_, name, value)| (name, value.parse().unwrap()))
            .collect()
    };
    let rust: Vec<(String, u8)> = [
        ("TARGET_UNKNOWN", RawScan::TARGET_UNKNOWN),
        ("TARGET_CALIBRATION_PLATE", RawScan::TARGET_CALIBRATION_PLATE),
        ("TARGET_FRAME", RawScan::TARGET_FRAME),
        ("TARGET_LENS", RawScan::TARGET_LENS),
        ("TARGET_RING_GAUGE", RawScan::TARGET_RING_GAUGE),
    ]
    .map(|(n, v)| (n.to_string(), v))
    .to_vec();
    assert_eq!(declared(RawScan::DEFINITION.text()), rust);
    let rust: Vec<(String, u8)> = [
        ("OK", DiagnosticStatus::OK),
        ("WARN", DiagnosticStatus::WARN),
        ("ERROR", DiagnosticStatus::ERROR),
        ("STALE", DiagnosticStatus::STALE),
    ]
    .map(|(n, v)| (n.to_string(), v))
    .to_vec();
    assert_eq!(declared(DiagnosticStatus::DEFINITION.text()), rust);
}
