//! Criterion benches of the learned person models (`fitstation::person`, tract-onnx, one
//! thread) on a frame of the bundled demo recording: the input resampling alone, selfie
//! segmentation and the BlazePose landmark network (each with its resampling), and the
//! pose mask rendered at frame resolution.

use criterion::{criterion_group, criterion_main, Criterion};
use fitstation::person::{
    resample_roi, FrameRef, PersonModel, PersonOutput, PoseLandmarker, Roi, SelfieSegmenter,
    INPUT_SIZE,
};
use fitstation::recording::Recording;
use std::hint::black_box;
use std::path::Path;
use std::time::Duration;

fn bench(c: &mut Criterion) {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("recordings/demo");
    let mut rec = Recording::open(&dir).expect("open recordings/demo");
    let (front, _) = rec.frame_pair(17).expect("decode demo frame 17");
    let frame = FrameRef::from_image(&front);
    // a person crop the size of the demo subject's (about 470 px tall) enlarged by 1.25
    let roi = Roi::square_around(560.0, 150.0, 720.0, 620.0, 1.25);
    let mut out = PersonOutput::new();

    let mut g = c.benchmark_group("person");
    g.sample_size(10)
        .warm_up_time(Duration::from_secs(1))
        .measurement_time(Duration::from_secs(3));
    let mut buf = vec![0.0f32; INPUT_SIZE * INPUT_SIZE * 3];
    g.bench_function("resample_roi 256x256", |b| {
        b.iter(|| resample_roi(black_box(frame), black_box(roi), &mut buf))
    });
    let mut selfie = SelfieSegmenter::load_default().expect("load the selfie model");
    g.bench_function("selfie_segmentation", |b| {
        b.iter(|| {
            selfie
                .infer(black_box(frame), roi, &mut out)
                .expect("selfie")
        })
    });
    let mut pose = PoseLandmarker::load_default().expect("load the pose model");
    g.bench_function("pose_landmark_full", |b| {
        b.iter(|| pose.infer(black_box(frame), roi, &mut out).expect("pose"))
    });
    let mut full = Vec::new();
    g.bench_function("mask write_frame 1280x720", |b| {
        b.iter(|| out.mask.write_frame(1280, 720, black_box(&mut full)))
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
