//! The OMA (VCA) trace reader: `io::oma::parse`.
//!
//! Invariants besides "no panic": every trace has N finite, non-negative radii (and N finite
//! angles if not equiangular); a file that renders (`io::oma::render`) reads back to the
//! same traces and records, and rendering that again gives the same text.
#![no_main]

use libfuzzer_sys::fuzz_target;
use tracer_calib::io::oma;

fuzz_target!(|data: &[u8]| {
    // `oma::read` is lenient with stray bytes; do as it does.
    let text = String::from_utf8_lossy(data);
    let file = match oma::parse(&text, "fuzz.oma") {
        Ok(f) => f,
        Err(e) => {
            assert!(e.to_string().starts_with("fuzz.oma"), "{e}");
            return;
        }
    };
    for t in &file.traces {
        assert!(t.n() > 0);
        assert!(t.radii.iter().all(|r| r.is_finite() && *r >= 0.0), "{:?}", t.radii);
        if let Some(a) = &t.angles {
            assert_eq!(a.len(), t.n());
            assert!(a.iter().all(|v| v.is_finite()), "{a:?}");
        }
        for i in 0..t.n() {
            assert!(t.angle(i).is_finite());
        }
    }
    let Ok(rendered) = oma::render(&file) else { return };
    let back =
        oma::parse(&rendered, "fuzz.oma").unwrap_or_else(|e| panic!("rendered file does not parse: {e}\n{rendered}"));
    assert_eq!(back.job, file.job);
    assert_eq!(back.other, file.other);
    assert_eq!(back.traces.len(), file.traces.len());
    for (b, t) in back.traces.iter().zip(&file.traces) {
        assert_eq!((b.eye, b.trace_type, b.n()), (t.eye, t.trace_type, t.n()));
        assert_eq!(b.radii, t.radii, "radii changed in a round trip");
        assert_eq!(b.angles.is_some(), t.angles.is_some());
    }
    let again = oma::render(&back).expect("a file read back from a rendering renders");
    assert_eq!(again, rendered, "rendering is not stable");
});
