//! Size figures and their 95 % uncertainty by Monte Carlo: a lens traced from
//! outside and a frame from inside, by a tracer calibrated from its own noisy plate (and
//! ring gauge) scans each trial; the reported U95 of circumference, A, B and FED covers the
//! truth in about 95 % of the trials (90-99 % asserted), and the circumference is unbiased.

#[path = "common/size_coverage.rs"]
#[allow(dead_code)] // shared with the accuracy example and tests/stylus_tip.rs
mod size_coverage;

use nalgebra::Vector2;
use rand::SeedableRng;
use rand::rngs::StdRng;
use size_coverage::{Coverage, run};
use tracer_calib_engine::angle::HarmonicOrders;
use tracer_calib_engine::correct::{correct, resample_radii};
use tracer_calib_engine::geometry::Mounting;
use tracer_calib_engine::model::ModelKind;
use tracer_calib_engine::shape::{Ellipse, RoundedRect};
use tracer_calib_engine::simulate::{SimOptions, simulate};
use tracer_calib_engine::size::{Correction, HARMONICS, Sizes, Smooth};
use tracer_calib_engine::stylus::{Traced, touched_surface};

fn check(name: &str, c: &Coverage, sigma: f64) {
    let share = c.covered.map(|k| k as f64 / c.n as f64);
    eprintln!(
        "{name}, σ = {:.0} µm: covered [C, A, B, FED] {:?}, radii {:.3}, mean U95 {:?} µm, bias {:?} µm",
        sigma * 1e6,
        share,
        c.radii_covered,
        c.u95.map(|u| (u * 1e7).round() / 10.0),
        c.bias.map(|b| (b * 1e7).round() / 10.0)
    );
    // 95 % expected (the target: 93-97 % in 2000 trials); 400 trials have a
    // standard error of 1.1 %. What is reached (docs/engine.md): 92.3-99.0 % for every
    // figure (C 92.3-95.8 %), a FED biased by about its noise (the largest distance of a
    // noisy smooth), inside its U95; each radius 95.1-96.2 %.
    for (f, s) in share.iter().enumerate() {
        assert!((0.90..=0.99).contains(s), "{name}, σ = {sigma}: figure {f} covered in {s}");
    }
    assert!((0.93..=0.975).contains(&c.radii_covered), "{name}, σ = {sigma}: radii covered in {}", c.radii_covered);
    assert!(c.bias[0].abs() < 2e-6, "{name}: circumference biased by {} µm", c.bias[0] * 1e6);
}

#[test]
fn a_lens_u95_covers_the_truth() {
    let lens = Ellipse { center: Vector2::new(0.0005, -0.0003), a: 0.026, b: 0.016, angle: 0.3 };
    for (i, sigma) in [1e-6, 5e-6, 10e-6].into_iter().enumerate() {
        let c = run(&lens, lens.exact_sizes(), Traced::Outside, ModelKind::Full, 0.0, sigma, 400, 10 + i as u64);
        check("lens, full", &c, sigma);
    }
}

#[test]
fn a_frame_traced_with_a_tip_u95_covers_the_truth() {
    let frame = RoundedRect { center: Vector2::new(0.001, -0.0005), half_w: 0.025, half_h: 0.015, radius: 0.008 };
    for (i, sigma) in [1e-6, 5e-6, 10e-6].into_iter().enumerate() {
        let c = run(&frame, frame.exact_sizes(), Traced::Inside, ModelKind::FullTip, 0.0005, sigma, 400, 20 + i as u64);
        check("frame, full_tip, 0.5 mm tip", &c, sigma);
    }
}

/// The figures' response to each tracer parameter, as the uncertainty uses it, against
/// the whole chain redone with the parameter moved (correct, tip, resample, smooth).
#[test]
fn the_calibration_responses_are_the_chains_own() {
    let m = Mounting::new(2f64.to_radians(), 0.005, 0.002).with_scale(1.001);
    let tip = 0.0005;
    for (traced, inside) in [(Traced::Outside, false), (Traced::Inside, true)] {
        let lens = Ellipse { center: Vector2::new(0.0005, -0.0003), a: 0.026, b: 0.016, angle: 0.3 };
        let opt = SimOptions { tip_radius: tip, inside, ..SimOptions::default() };
        let scan = simulate(&lens, &m, &opt, &mut StdRng::seed_from_u64(1)).unwrap().scan;
        let figures = |m: &Mounting, tip: f64| {
            let mut points = correct(&scan, m);
            touched_surface(&mut points, tip, traced, true);
            Sizes::of(&Smooth::fit(&resample_radii(&points, 400, 0.2).unwrap(), HARMONICS).unwrap())
        };
        let base = figures(&m, tip);
        let smooth = Smooth::fit(
            &{
                let mut p = correct(&scan, &m);
                touched_surface(&mut p, tip, traced, true);
                resample_radii(&p, 400, 0.2).unwrap()
            },
            HARMONICS,
        )
        .unwrap();
        let correction = Correction {
            mounting: m,
            tip_radius: tip,
            traced,
            groove: Default::default(),
            angle_orders: HarmonicOrders::NONE,
            noise: Default::default(),
        };
        let h = [1e-5, 1e-6, 1e-6, 1e-5, 1e-6];
        for (j, hj) in h.into_iter().enumerate() {
            let mut moved = m;
            let mut moved_tip = tip;
            match j {
                0 => moved.alpha0 += hj,
                1 => moved.offset += hj,
                2 => moved.delta_l += hj,
                3 => moved.scale += hj,
                _ => moved_tip += hj,
            }
            let numeric: Vec<f64> =
                figures(&moved, moved_tip).figures().iter().zip(base.figures()).map(|(a, b)| (a - b) / hj).collect();
            let predicted = base.response(|t| correction.radial_sensitivities(&smooth, t)[j]);
            for f in 0..4 {
                assert!(
                    (numeric[f] - predicted[f]).abs() <= 0.02 * numeric[f].abs() + 2e-3,
                    "{traced:?}, parameter {j}, figure {f}: chain {} vs predicted {}",
                    numeric[f],
                    predicted[f]
                );
            }
        }
    }
}
