//! Property tests of the engine: for any input, no panic, and nothing non-finite is ever
//! reported as a success.

use nalgebra::Vector2;
use proptest::prelude::*;
use tracer_calib_engine::calibrate::{Options, calibrate};
use tracer_calib_engine::correct::{correct, default_max_gap, resample_radii};
use tracer_calib_engine::geometry::Mounting;
use tracer_calib_engine::model::{ModelKind, PlateSpec};
use tracer_calib_engine::scan::Scan;
use tracer_calib_engine::simulate::{SimOptions, simulate};

fn any_f64() -> impl Strategy<Value = f64> {
    prop_oneof![
        4 => -0.1f64..0.1,
        1 => prop::num::f64::ANY,
        1 => Just(0.0),
    ]
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 200, ..ProptestConfig::default() })]

    /// Arbitrary steps and counts: a scan is either rejected or calibrates to finite
    /// numbers, or fails with a reason.
    #[test]
    fn arbitrary_scans_never_panic_or_report_nan(
        steps_per_rev in prop_oneof![Just(400u32), 1u32..2000, Just(u32::MAX)],
        samples in prop::collection::vec((0u32..2000, -200_000i32..200_000), 0..500),
        mpc in prop_oneof![Just(1e-6), 1e-9f64..1e-3],
        model in prop_oneof![Just(ModelKind::Full), Just(ModelKind::Paper)],
    ) {
        let (steps, counts): (Vec<u32>, Vec<i32>) = samples.into_iter().unzip();
        if let Ok(scan) = Scan::from_counts(steps_per_rev, &steps, &counts, mpc) {
            let pts = correct(&scan, &Mounting::new(0.01, 0.002, 0.001));
            prop_assert!(pts.iter().all(|p| p.x.is_finite() && p.y.is_finite()));
            if let Some(r) = resample_radii(&pts, 400, default_max_gap(steps_per_rev)) {
                prop_assert!(r.iter().all(|v| v.is_finite()));
            }
            if let Ok(cal) = calibrate(&scan, &PlateSpec::default(), &Options { model, ..Options::default() }) {
                let m = cal.mounting;
                prop_assert!(m.alpha0.is_finite() && m.offset.is_finite() && m.delta_l.is_finite());
                prop_assert!(cal.stddev.iter().all(|s| s.is_finite()));
                prop_assert!(cal.rms_residual.is_finite());
            }
        }
    }

    /// Real plate scans with arbitrary (even absurd) mounting errors, noise, gaps and
    /// spikes: no panic, and a success is finite and in (-45°, 45°].
    #[test]
    fn perturbed_plate_scans(
        alpha_deg in -180f64..180.0,
        d_mm in -21f64..21.0,
        dl_mm in -5f64..5.0,
        noise_um in 0f64..200.0,
        missing in 0f64..0.9,
        spikes in 0usize..40,
        start in 0u32..400,
        seed in any::<u64>(),
    ) {
        use rand::SeedableRng;
        let plate = PlateSpec::default();
        let m = Mounting::new(alpha_deg.to_radians(), d_mm * 1e-3, dl_mm * 1e-3);
        let opt = SimOptions { noise: noise_um * 1e-6, missing, spikes, start_step: start, ..SimOptions::default() };
        let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
        if let Ok(sim) = simulate(&plate.at(Vector2::new(0.0005, -0.0003)), &m, &opt, &mut rng) {
            for model in [ModelKind::Full, ModelKind::Paper] {
                if let Ok(cal) = calibrate(&sim.scan, &plate, &Options { model, ..Options::default() }) {
                    prop_assert!(cal.mounting.alpha0 > -std::f64::consts::FRAC_PI_4 - 1e-12);
                    prop_assert!(cal.mounting.alpha0 <= std::f64::consts::FRAC_PI_4 + 1e-12);
                    prop_assert!(cal.stddev.iter().all(|s| s.is_finite() && *s >= 0.0));
                }
            }
        }
    }

    /// Arbitrary plate dimensions and options never panic.
    #[test]
    fn arbitrary_plates(side in any_f64(), r in any_f64(), thr in any_f64()) {
        let plate = PlateSpec { side, corner_radius: r };
        let steps: Vec<u32> = (0..400).collect();
        let rho: Vec<f64> = steps.iter().map(|k| 0.0225 + 1e-4 * (*k as f64 * 0.1).sin()).collect();
        let scan = Scan::new(400, &steps, &rho).unwrap();
        let opts = Options { outlier_threshold: thr, ..Options::default() };
        if let Ok(cal) = calibrate(&scan, &plate, &opts) {
            prop_assert!(cal.mounting.alpha0.is_finite() && cal.rms_residual.is_finite());
        }
    }
}
