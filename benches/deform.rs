//! Criterion benches of the deformers: encoding, a fast decode from rest, a warm refit
//! and one paper-style sweep, on the committed station template (built into the binary)
//! with its rigid hands, feet and head, else on a generated cylinder. `fitstation bench deform` prints the same figures in one
//! run, with the paper-style decode to convergence and the libigl peer.

use criterion::{criterion_group, criterion_main, Criterion};
use fitstation::deform::bench::{load_mesh, problem, rigid_parts, BenchArgs};
use fitstation::deform::{DecodeOptions, DecoderKind, MeanValueEncoding, MvcDeformer};
use fitstation::mesh::{shapes, TriMesh};
use std::hint::black_box;

/// The station template and its rigid extremities, or a cylinder without any.
fn mesh() -> (TriMesh, Vec<Vec<u32>>) {
    {
        // mesh and makehuman both None: the committed template (`bench deform`'s default).
        let args = BenchArgs {
            mesh: None,
            makehuman: None,
            scale: 1.0,
            out: std::env::temp_dir(),
            no_libigl: true,
            tol_m: 1e-4,
            paper_max_sweeps: 1,
            free_extremities: false,
            repeats: 1,
        };
        if let (Ok(m), Ok(parts)) = (load_mesh(&args), rigid_parts(&args)) {
            return (m, parts);
        }
    }
    (
        shapes::elliptic_cylinder(0.15, 0.1, 1.0, 120, 110),
        Vec::new(),
    )
}

fn deform(c: &mut Criterion) {
    let (m, parts) = mesh();
    let rings = m.one_rings();
    let p = problem(&m, &parts);
    c.bench_function("deform/encode", |b| {
        b.iter(|| black_box(MeanValueEncoding::encode(&m, &rings)))
    });

    let opts = DecodeOptions {
        max_iterations: 500,
        ..Default::default()
    };
    let mut fast = MvcDeformer::new(&m, DecoderKind::FastGaussNewton, opts).unwrap();
    fast.set_controls(&p.controls).unwrap();
    let mut pos = m.positions.clone();
    c.bench_function("deform/fast_decode_from_rest", |b| {
        b.iter(|| {
            fast.reset_history();
            pos.copy_from_slice(&m.positions);
            black_box(fast.solve(&p.targets, &mut pos).unwrap())
        })
    });
    // A two-frame sequence per iteration (from rest, then the refit); only the refit is
    // timed. The coupled system stays linearised at rest.
    c.bench_function("deform/fast_warm_refit", |b| {
        b.iter_custom(|iters| {
            let mut total = std::time::Duration::ZERO;
            for _ in 0..iters {
                fast.reset_history();
                pos.copy_from_slice(&m.positions);
                fast.solve(&p.targets, &mut pos).unwrap();
                let t = std::time::Instant::now();
                black_box(fast.solve(&p.refit_targets, &mut pos).unwrap());
                total += t.elapsed();
            }
            total
        })
    });
    // The live station: linearised once at the first frame's result, then every frame a
    // warm refit from the previous frame after the targets moved a few millimetres
    // (alternating between the two target sets).
    pos.copy_from_slice(&m.positions);
    fast.solve(&p.targets, &mut pos).unwrap();
    fast.relinearise(&pos).unwrap();
    let mut frame = 0usize;
    c.bench_function("deform/fast_frame_sequence_refit", |b| {
        b.iter(|| {
            frame += 1;
            let t = if frame % 2 == 1 {
                &p.refit_targets
            } else {
                &p.targets
            };
            black_box(fast.solve(t, &mut pos).unwrap())
        })
    });

    let one = DecodeOptions {
        max_iterations: 1,
        ..Default::default()
    };
    let mut paper = MvcDeformer::new(&m, DecoderKind::PaperIterative, one).unwrap();
    paper.set_controls(&p.controls).unwrap();
    c.bench_function("deform/paper_sweep", |b| {
        b.iter(|| {
            pos.copy_from_slice(&m.positions);
            black_box(paper.solve(&p.targets, &mut pos).unwrap())
        })
    });
}

criterion_group! {
    name = benches;
    config = Criterion::default().sample_size(10);
    targets = deform
}
criterion_main!(benches);
