//! Speed of the synthetic recorder and the recording codec, per 720p frame.
//!
//! `cargo bench --bench synth`: rasterising a 36k-triangle mesh, developing a frame
//! (blur, vignetting, gamma, noise), ray casting the empty room (once per recording),
//! H.264 encoding and decoding one 1280x720 frame.

use criterion::{criterion_group, criterion_main, Criterion};
use fitstation::camera::StationCalibration;
use fitstation::mesh::shapes;
use fitstation::recording::h264::{Mp4VideoReader, Mp4VideoWriter};
use fitstation::synth::raster::Rasterizer;
use fitstation::synth::rng::SplitMix64;
use fitstation::synth::scene::{Background, Film, Scene};
use glam::DVec3;
use std::time::{Duration, Instant};

fn setup() -> (StationCalibration, Scene, Film, Background) {
    let mut calib = StationCalibration::nominal(1280, 720, 1000.0, 3.0, 1.2, 1.0);
    calib.front.intrinsics.dist = [-0.1, 0.03, 0.0005, -0.0005, 0.0];
    let mut rng = SplitMix64::new(4);
    let scene = Scene::random(&mut rng, [&calib.front, &calib.side]);
    let film = Film::random(&mut rng);
    let bg = Background::render(&scene, &calib.front);
    (calib, scene, film, bg)
}

fn frames(film: &Film, bg: &Background, n: usize) -> Vec<image::RgbImage> {
    let mut scratch = Vec::new();
    (0..n)
        .map(|k| {
            let mut rad = bg.empty.clone();
            let mut img = image::RgbImage::new(bg.width, bg.height);
            film.develop(
                &mut rad,
                &mut scratch,
                1.0,
                &mut SplitMix64::new(k as u64),
                &mut img,
            );
            img
        })
        .collect()
}

fn bench(c: &mut Criterion) {
    let (calib, scene, film, bg) = setup();
    let mut g = c.benchmark_group("synth_720p");
    g.sample_size(10).measurement_time(Duration::from_secs(4));
    let mut sphere = shapes::uv_sphere(0.4, 96, 192);
    sphere.map_positions(|p| p + DVec3::new(0.0, 1.0, 0.0));
    let mut r = Rasterizer::new(1280, 720);
    g.bench_function("rasterise_36k_triangles", |b| {
        b.iter(|| {
            r.clear();
            r.draw_mesh(&calib.front, &sphere.positions, &sphere.triangles);
        })
    });
    let mut rad = bg.empty.clone();
    let mut scratch = Vec::new();
    let mut img = image::RgbImage::new(1280, 720);
    let mut nrng = SplitMix64::new(1);
    g.bench_function("develop_frame", |b| {
        b.iter(|| {
            rad.copy_from_slice(&bg.empty);
            film.develop(&mut rad, &mut scratch, 1.0, &mut nrng, &mut img);
        })
    });
    g.bench_function("background_ray_cast_once_per_recording", |b| {
        b.iter(|| Background::render(&scene, &calib.front))
    });
    let fr = frames(&film, &bg, 30);
    let dir = std::env::temp_dir().join(format!("fitstation-bench-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("bench.mp4");
    g.bench_function("h264_encode_frame", |b| {
        b.iter_custom(|iters| {
            let mut w = Mp4VideoWriter::create(&path, 1280, 720, 30.0).unwrap();
            let t = Instant::now();
            for i in 0..iters {
                w.push(&fr[i as usize % fr.len()]).unwrap();
            }
            let e = t.elapsed();
            w.finish().unwrap();
            e
        })
    });
    let mut w = Mp4VideoWriter::create(&path, 1280, 720, 30.0).unwrap();
    for f in &fr {
        w.push(f).unwrap();
    }
    w.finish().unwrap();
    g.bench_function("h264_decode_frame", |b| {
        b.iter_custom(|iters| {
            let mut total = Duration::ZERO;
            let mut left = iters as usize;
            while left > 0 {
                let mut rdr = Mp4VideoReader::open(&path).unwrap();
                let n = left.min(rdr.len());
                let t = Instant::now();
                for k in 0..n {
                    std::hint::black_box(rdr.frame(k).unwrap());
                }
                total += t.elapsed();
                left -= n;
            }
            total
        })
    });
    g.finish();
    let _ = std::fs::remove_dir_all(&dir);
}

criterion_group!(benches, bench);
criterion_main!(benches);
