//! Speed of the engine: one full-model fit on 400 samples (ours, and the same residuals
//! solved by the `levenberg-marquardt` crate), whole calibrations, and correction.
//!
//! ```text
//! cargo bench --bench fit
//! ```
//!
//! The scan: 45 mm plate, alpha0 = 2°, d = 5 mm, dL = 2 mm, c = (0.8, -0.5) mm,
//! σ = 0.01 mm. The LM fits start 1° (and 0.5 mm) off, as in `docs/model.md`.

use criterion::{Criterion, black_box, criterion_group, criterion_main};
use levenberg_marquardt::{LeastSquaresProblem, LevenbergMarquardt};
use nalgebra::{Dyn, Owned, U5, Vector2};
use rand::SeedableRng;
use rand::rngs::StdRng;
use tracer_calib::cell::NodeState;
use tracer_calib::engine::calibrate::{Options, calibrate};
use tracer_calib::engine::correct::{Corrector, correct, default_max_gap, resample_radii, resample_radii_with_gain};
use tracer_calib::engine::geometry::Mounting;
use tracer_calib::engine::lm::{self, Problem};
use tracer_calib::engine::model::full::{self, FullModel};
use tracer_calib::engine::model::{ModelKind, PlateSpec};
use tracer_calib::engine::scan::Scan;
use tracer_calib::engine::shape::Ellipse;
use tracer_calib::engine::simulate::{SimOptions, simulate};
use tracer_calib::engine::size;
use tracer_calib::interfaces::{Header, RawScan, from_cdr, to_cdr};

/// The full model behind the `levenberg-marquardt` crate's trait: residuals and the
/// n×5 Jacobian from the same `for_each_row` our solver uses.
struct CrateAdapter {
    model: FullModel,
    x: full::Params,
}

impl LeastSquaresProblem<f64, Dyn, U5> for CrateAdapter {
    type ResidualStorage = Owned<f64, Dyn>;
    type JacobianStorage = Owned<f64, Dyn, U5>;
    type ParameterStorage = Owned<f64, U5>;

    fn set_params(&mut self, x: &full::Params) {
        self.x = *x;
    }
    fn params(&self) -> full::Params {
        self.x
    }
    fn residuals(&self) -> Option<nalgebra::DVector<f64>> {
        lm::residuals(&self.model, &self.x)
    }
    fn jacobian(&self) -> Option<nalgebra::OMatrix<f64, Dyn, U5>> {
        let n = self.model.residual_count();
        let mut jac = nalgebra::OMatrix::<f64, Dyn, U5>::zeros(n);
        let mut i = 0;
        self.model
            .for_each_row(&self.x, |_, j| {
                jac.row_mut(i).copy_from(&j.transpose());
                i += 1;
            })
            .then_some(jac)
    }
}

fn plate_scan() -> (PlateSpec, Scan, full::Params) {
    let plate = PlateSpec { side: 0.045, corner_radius: 0.003 };
    let m = Mounting::new(2f64.to_radians(), 0.005, 0.002);
    let c = Vector2::new(0.0008, -0.0005);
    let mut rng = StdRng::seed_from_u64(1);
    let sim = simulate(&plate.at(c), &m, &SimOptions { noise: 10e-6, ..SimOptions::default() }, &mut rng).unwrap();
    (plate, sim.scan, full::params(&m, c))
}

fn bench(c: &mut Criterion) {
    let (plate, scan, truth) = plate_scan();
    let model = FullModel::from_scan(&plate, &scan);
    let start = truth + full::Params::from([1f64.to_radians(), 0.5e-3, -0.5e-3, 0.2e-3, 0.2e-3]);

    let ours = lm::minimize(&model, start, &lm::Options::default());
    let (theirs, report) = LevenbergMarquardt::new().minimize(CrateAdapter { model: model.clone(), x: start });
    println!(
        "ours: {:?}, {} iterations, {} evaluations; levenberg-marquardt crate: {:?}, {} evaluations; max |Δx| between them {:.2e}",
        ours.termination,
        ours.iterations,
        ours.evaluations,
        report.termination,
        report.number_of_evaluations,
        (ours.x - theirs.x).amax()
    );

    c.bench_function("fit/full_lm_400 (ours)", |b| {
        b.iter(|| lm::minimize(black_box(&model), black_box(start), &lm::Options::default()))
    });
    c.bench_function("fit/full_lm_400 (levenberg-marquardt crate)", |b| {
        b.iter(|| LevenbergMarquardt::new().minimize(CrateAdapter { model: black_box(&model).clone(), x: start }))
    });
    c.bench_function("fit/normal_equations_pass_400", |b| b.iter(|| lm::normal_equations(black_box(&model), &start)));
    for kind in ModelKind::ALL.into_iter().filter(|k| !k.fits_tip()) {
        let opts = Options { model: kind, ..Options::default() };
        c.bench_function(&format!("calibrate/{kind}_400 (start + fit + outlier test + checks)"), |b| {
            b.iter(|| calibrate(black_box(&scan), &plate, &opts).unwrap())
        });
    }
    // The turntable's angle error fitted too (nine parameters, a run-time size): the same
    // scan, and two placements of it (the second as if turned: its own start and centre).
    let harmonics = Options {
        angle_harmonics: tracer_calib::engine::angle::HarmonicOrders::new(&[1, 2]).unwrap(),
        ..Options::default()
    };
    c.bench_function("calibrate/full_400 with angle harmonics 1, 2", |b| {
        b.iter(|| calibrate(black_box(&scan), &plate, &harmonics).unwrap())
    });
    c.bench_function("calibrate/full_400 x 2 placements, angle harmonics 1, 2", |b| {
        b.iter(|| {
            tracer_calib::engine::calibrate::calibrate_placements(&[black_box(&scan), &scan], None, &plate, &harmonics)
                .unwrap()
        })
    });

    let m = Mounting::new(2f64.to_radians(), 0.005, 0.002);
    let lens = Ellipse { center: Vector2::zeros(), a: 0.025, b: 0.015, angle: 0.0 };
    let mut rng = StdRng::seed_from_u64(2);
    // A real trace: 5 µm of noise, 1 µm counts.
    let lens_scan = simulate(&lens, &m, &SimOptions { noise: 5e-6, quantum: 1e-6, ..SimOptions::default() }, &mut rng)
        .unwrap()
        .scan;
    let corrector = Corrector::new(m, 400);
    c.bench_function("correct/400 (cached corrector)", |b| b.iter(|| corrector.correct(black_box(&lens_scan))));
    c.bench_function("correct/400 (fresh, builds the table)", |b| b.iter(|| correct(black_box(&lens_scan), &m)));
    let pts = corrector.correct(&lens_scan);
    c.bench_function("resample/400_to_400", |b| b.iter(|| resample_radii(black_box(&pts), 400, default_max_gap(400))));

    // The node's whole handling of one raw scan (validate, correct, resample, build the
    // Contour and PolygonStamped), and the CDR encoding of what it publishes.
    let raw = RawScan {
        header: Header::default(),
        scan_id: 1,
        target: RawScan::TARGET_LENS,
        steps_per_revolution: 400,
        step: lens_scan.samples().iter().map(|s| s.step).collect(),
        counts: lens_scan.samples().iter().map(|s| (s.rho * 1e6).round() as i32).collect(),
        height_counts: Vec::new(),
    };
    // A calibration in force with its covariance, as after /calibrate: the size figures'
    // uncertainty has its calibration part.
    let mut covariance = vec![0.0; 25];
    for (i, v) in [4e-8, 4e-11, 2e-12].into_iter().enumerate() {
        covariance[i * 6] = v;
    }
    let params =
        tracer_calib::params::Parameters { calibration: m, calibration_valid: true, covariance, ..Default::default() };
    let mut state = NodeState::new("/tracer_calibrator".into(), params);
    c.bench_function("node/on_raw_scan_400 (validate, correct, resample, build messages)", |b| {
        b.iter(|| state.on_raw_scan(black_box(&raw), true).unwrap())
    });
    c.bench_function("node/on_raw_scan_400 (no polygon subscriber: the latency bench's case)", |b| {
        b.iter(|| state.on_raw_scan(black_box(&raw), false).unwrap())
    });
    let contour_pts: Vec<Vector2<f64>> = pts.clone();
    let (radii, gain) = resample_radii_with_gain(&contour_pts, 400, default_max_gap(400)).unwrap();
    let correction = size::Correction {
        mounting: m,
        tip_radius: 0.0,
        traced: tracer_calib::engine::Traced::Outside,
        groove: Default::default(),
        angle_orders: tracer_calib::engine::angle::HarmonicOrders::NONE,
        noise: Default::default(),
    };
    let cov = tracer_calib::engine::calibrate::named_covariance_from_values(&state.params.covariance).unwrap();
    c.bench_function("size/uncertainty_400 (smooth fit, C, A, B, FED, U95, radii U95)", |b| {
        b.iter(|| size::uncertainty(black_box(&contour_pts), &radii, &gain, &correction, Some(&cov)).unwrap())
    });
    // A symmetric frame: four far corners, so the FED is the largest of four candidates
    // corrected for its bias (`size::largest_of`, its draws).
    let frame = tracer_calib::engine::shape::RoundedRect {
        center: Vector2::new(0.001, -0.0005),
        half_w: 0.026,
        half_h: 0.016,
        radius: 0.005,
    };
    let frame_pts = corrector.correct(
        &simulate(&frame, &m, &SimOptions { noise: 10e-6, quantum: 1e-6, ..SimOptions::default() }, &mut rng)
            .unwrap()
            .scan,
    );
    let (frame_radii, frame_gain) = resample_radii_with_gain(&frame_pts, 400, default_max_gap(400)).unwrap();
    c.bench_function("size/uncertainty_400, a symmetric frame (four far corners: the largest's bias)", |b| {
        b.iter(|| size::uncertainty(black_box(&frame_pts), &frame_radii, &frame_gain, &correction, Some(&cov)).unwrap())
    });
    let out = state.on_raw_scan(&raw, true).unwrap();
    c.bench_function("node/encode Contour + PolygonStamped (CDR)", |b| {
        b.iter(|| (to_cdr(black_box(&out.contour)).unwrap(), to_cdr(black_box(out.polygon.as_ref().unwrap())).unwrap()))
    });
    c.bench_function("node/decode RawScan (CDR)", |b| {
        let bytes = to_cdr(&raw).unwrap();
        b.iter(|| from_cdr::<RawScan>(black_box(&bytes)).unwrap())
    });
}

criterion_group!(benches, bench);
criterion_main!(benches);
