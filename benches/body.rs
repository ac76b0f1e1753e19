//! Shape library timings: one body from macro parameters (candidate selection evaluates
//! many), the template analysis, loading the embedded library, and the flood that takes
//! the pockets out of every avatar's armpits after each fit.
use criterion::{criterion_group, criterion_main, Criterion};
use fitstation::body::{prepare, ShapeLibrary};
use fitstation::fit::armpit::ArmpitPeaks;
use std::hint::black_box;

fn bench(c: &mut Criterion) {
    let lib = ShapeLibrary::load_default().expect("embedded library");
    let mut buf = Vec::new();
    let mut seed = 0u64;
    c.bench_function("body_into (sample_adult)", |b| {
        b.iter(|| {
            seed = seed.wrapping_add(1);
            lib.body_into(&ShapeLibrary::sample_adult(seed % 64), &mut buf);
            black_box(&buf);
        })
    });
    c.bench_function("prepare (template)", |b| {
        b.iter(|| black_box(prepare(&lib.template().mesh)))
    });
    // Every frame's cost: the flood visits the whole zone whether or not a peak is there.
    let t = lib.template();
    let lm = &t.info.landmarks;
    let mut peaks = ArmpitPeaks::new(
        &t.mesh.positions,
        t.mesh.one_rings(),
        [lm.armpit_left, lm.armpit_right],
    );
    let mut pos = t.mesh.positions.clone();
    c.bench_function("armpit peaks flatten (template)", |b| {
        b.iter(|| black_box(peaks.flatten(&mut pos)))
    });
    let mut g = c.benchmark_group("load");
    g.sample_size(10);
    g.bench_function("load_default", |b| {
        b.iter(|| black_box(ShapeLibrary::load_default()))
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
