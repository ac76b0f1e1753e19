//! Times `measure()` on the MakeHuman body (13k vertices) against the per-frame budget:
//! a fresh call (builds the height index and buffers) and a warm `Measurer` call (what
//! the station pays per frame), then the same on the committed station template, the
//! closed surface the station's avatars have. Falls back to the committed station template
//! (`templates/makehuman-adult.obj`), then to a synthetic stick body, when the MakeHuman
//! data is missing.

use criterion::{criterion_group, criterion_main, Criterion};
use fitstation::measure::{girth_at, measure, LoopSelector, Measurer};
use fitstation::mesh::io::{read_mesh, read_obj};
use fitstation::mesh::{shapes, TriMesh};
use glam::DVec3;
use std::hint::black_box;
use std::path::Path;

fn makehuman() -> Option<TriMesh> {
    let mut m = read_obj(&fitstation::io::cache::makehuman_base_obj(), Some("body")).ok()?;
    let floor = m
        .positions
        .iter()
        .map(|p| p.y)
        .fold(f64::INFINITY, f64::min)
        * 0.1;
    m.map_positions(|p| p * 0.1 - DVec3::new(0.0, floor, 0.0));
    Some(m)
}

fn template() -> Option<TriMesh> {
    read_mesh(&Path::new(env!("CARGO_MANIFEST_DIR")).join("templates/makehuman-adult.obj")).ok()
}

fn stick_body() -> TriMesh {
    let mut body = TriMesh::default();
    let mut add = |a: f64, b: f64, y0: f64, y1: f64, x: f64| {
        let part = shapes::elliptic_cylinder(a, b, y1 - y0, 20, 128);
        let base = body.positions.len() as u32;
        body.positions
            .extend(part.positions.iter().map(|p| *p + DVec3::new(x, y0, 0.0)));
        body.triangles
            .extend(part.triangles.iter().map(|t| t.map(|v| v + base)));
    };
    for s in [-1.0, 1.0] {
        add(0.08, 0.08, 0.0, 0.8, 0.1 * s);
        add(0.04, 0.04, 0.75, 1.3, 0.25 * s);
    }
    add(0.16, 0.12, 0.8, 1.3, 0.0);
    add(0.3, 0.12, 1.3, 1.45, 0.0);
    add(0.09, 0.1, 1.45, 1.75, 0.0);
    body
}

fn bench(c: &mut Criterion) {
    let (name, body) = match (makehuman(), template()) {
        (Some(m), _) => ("makehuman", m),
        (None, Some(t)) => {
            eprintln!(
                "MakeHuman body missing at {}: timing the station template",
                fitstation::io::cache::makehuman_base_obj().display()
            );
            ("template", t)
        }
        (None, None) => {
            eprintln!("MakeHuman body and template missing: timing the stick body instead");
            ("stick", stick_body())
        }
    };
    // A new Measurer: edge table, index and buffers built from nothing.
    c.bench_function(&format!("measure_new_measurer_{name}"), |b| {
        b.iter(|| Measurer::new().measure(black_box(&body)))
    });
    // Per frame the template keeps its triangles and moves its vertices: alternate two
    // bodies so every call rebuilds the height index, as a fitted avatar would.
    let mut other = body.clone();
    other.map_positions(|p| p * 1.01);
    let pair = [body.clone(), other];
    let mut measurer = Measurer::new();
    let mut out = measurer.measure(&body).expect("bench body measures");
    let mut k = 0usize;
    c.bench_function(&format!("measure_per_frame_{name}"), |b| {
        b.iter(|| {
            k += 1;
            measurer.measure_into(black_box(&pair[k % 2]), &mut out)
        })
    });
    // The same, cutting every grid height of the armpit search (no critical heights).
    let mut cutting = Measurer::cutting_every_armpit_height();
    c.bench_function(
        &format!("measure_per_frame_cut_every_armpit_height_{name}"),
        |b| {
            b.iter(|| {
                k += 1;
                cutting.measure_into(black_box(&pair[k % 2]), &mut out)
            })
        },
    );
    // The free function, per frame (its thread's cached Measurer).
    c.bench_function(&format!("measure_fn_per_frame_{name}"), |b| {
        b.iter(|| {
            k += 1;
            measure(black_box(&pair[k % 2]))
        })
    });
    // The station's avatar is the committed template's closed surface: its sections walk
    // their loops and the armpit search skips heights by their critical heights, which
    // MakeHuman's raw base mesh (not closed) never does. Per frame, with and without.
    if let Some(t) = template() {
        let mut other = t.clone();
        other.map_positions(|p| p * 1.01);
        let closed = [t, other];
        for (how, mut m) in [
            ("", Measurer::new()),
            ("_without_short_cuts", Measurer::without_short_cuts()),
        ] {
            let mut out = m.measure(&closed[0]).expect("the template measures");
            c.bench_function(&format!("measure_per_frame_template{how}"), |b| {
                b.iter(|| {
                    k += 1;
                    m.measure_into(black_box(&closed[k % 2]), &mut out)
                })
            });
        }
    }
    let torso = LoopSelector::Torso { axis_x: 0.0 };
    c.bench_function(&format!("girth_at_new_measurer_{name}"), |b| {
        b.iter(|| Measurer::new().girth_at(black_box(&body), 1.0, torso))
    });
    c.bench_function(&format!("girth_at_same_mesh_{name}"), |b| {
        b.iter(|| girth_at(black_box(&body), 1.0, torso))
    });
}

criterion_group!(benches, bench);
criterion_main!(benches);
