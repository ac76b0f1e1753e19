//! Timings of the calibration stages: rendering a board view (test support), detecting
//! the board's corners in a 1280x720 frame, and the Levenberg-Marquardt refinement.
use criterion::{criterion_group, criterion_main, Criterion};
use fitstation::calibrate::board::BoardSpec;
use fitstation::calibrate::corners::CornerDetector;
use fitstation::calibrate::intrinsics::{calibrate_intrinsics, CameraViews, ViewInput};
use fitstation::calibrate::render::{rigs, Background, BoardRenderer, RenderOptions};

fn bench(c: &mut Criterion) {
    let board = BoardSpec {
        cols: 9,
        rows: 6,
        square_m: 0.08,
    };
    let intr = rigs::landscape_intrinsics();
    let poses = rigs::handheld_poses(&board, &intr, 8, 3);
    let mut r = BoardRenderer::new(intr);
    let opts = RenderOptions {
        supersample: 3,
        ..RenderOptions::default()
    };
    let imgs: Vec<_> = poses
        .iter()
        .map(|p| r.render(&board, p, Background::Wall, &opts))
        .collect();
    let mut g = c.benchmark_group("calibrate");
    g.sample_size(10);
    g.bench_function("render_1280x720_ss3", |b| {
        b.iter(|| r.render(&board, &poses[0], Background::Wall, &opts))
    });
    let mut det = CornerDetector::new();
    g.bench_function("detect_corners_1280x720", |b| {
        b.iter(|| det.detect(&imgs[0], &board).is_ok())
    });
    let views = CameraViews {
        camera: "bench".into(),
        width: intr.width,
        height: intr.height,
        views: imgs
            .iter()
            .map(|i| ViewInput {
                name: String::new(),
                detection: det.detect(i, &board),
            })
            .collect(),
    };
    g.bench_function("calibrate_intrinsics_8_views", |b| {
        b.iter(|| calibrate_intrinsics(&views, &board, &mut |_| {}).is_ok())
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
