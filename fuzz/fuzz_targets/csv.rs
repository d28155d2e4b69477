//! The CSV reader of the offline tool: `io::csv::parse`.
//!
//! Invariants besides "no panic": a parsed revolution has as many counts as steps, and
//! renders (`io::csv::render`) to text that parses back to the same revolution; an error
//! names the file.
#![no_main]

use libfuzzer_sys::fuzz_target;
use tracer_calib::io::csv;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else { return };
    match csv::parse(text, "fuzz.csv") {
        Ok(rev) => {
            assert_eq!(rev.step.len(), rev.counts.len());
            let rendered = csv::render(&rev);
            let back = csv::parse(&rendered, "fuzz.csv").unwrap_or_else(|e| panic!("{e}\n{rendered}"));
            assert_eq!(back, rev);
        }
        Err(e) => assert!(e.to_string().starts_with("fuzz.csv"), "{e}"),
    }
});
