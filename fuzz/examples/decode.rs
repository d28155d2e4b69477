// scratch: corpus stats for raw_scan
use tracer_calib::engine::ModelKind;
use tracer_calib::engine::calibrate::{Options, calibrate};
use tracer_calib::params::Parameters;
use tracer_calib::ros::msgs::{RawScan, from_cdr};
use tracer_calib::ros::state::NodeState;
fn main() {
    let (mut n, mut dec, mut val, mut fit, mut ok) = (0, 0, 0, 0, 0);
    let mut errs = std::collections::BTreeMap::<String, usize>::new();
    for a in std::env::args().skip(1) {
        for e in std::fs::read_dir(&a).unwrap() {
            let b = std::fs::read(e.unwrap().path()).unwrap();
            n += 1;
            let Ok(m) = from_cdr::<RawScan>(&b) else { continue };
            dec += 1;
            let st = NodeState::new("/t".into(), Parameters::default());
            let Ok(scan) = st.validate(&m) else { continue };
            val += 1;
            if scan.len() > 2000 {
                continue;
            }
            fit += 1;
            let model = if m.scan_id & 1 == 0 { ModelKind::Full } else { ModelKind::Paper };
            match calibrate(&scan, &st.params.plate, &Options { model, ..Options::default() }) {
                Ok(_) => ok += 1,
                Err(e) => *errs.entry(format!("{e}").chars().take(22).collect()).or_default() += 1,
            }
        }
    }
    println!("files {n} decoded {dec} valid {val} fitted {fit} ok {ok}");
    println!("{errs:#?}");
}
