//! `fitstation measure MESH [--json]`: measures a body mesh file (OBJ or PLY, metres,
//! station frame: +Y up, the subject faces +Z, +X the subject's left) after
//! `shared/spec/measurements.md`
//! and prints a table, or JSON whose `measurements_mm` object has the `report.json`
//! keys of `shared/spec/formats.md`.

use super::{Measurements, Measurer};
use anyhow::Context;
use std::path::PathBuf;
use std::time::Instant;

/// How far the timing copy is moved (metres): any change forces an index rebuild.
const FRAME_SHIFT_M: f64 = 1e-3;

/// Arguments of `fitstation measure`.
#[derive(Debug, Clone, clap::Args)]
pub struct MeasureArgs {
    /// Body mesh (.obj or .ply) in metres, station frame (heights from its lowest point).
    pub mesh: PathBuf,
    /// Print JSON (`measurements_mm` with the report keys, levels, torso profile).
    #[arg(long)]
    pub json: bool,
}

/// Runs `fitstation measure`.
pub fn run(args: MeasureArgs) -> anyhow::Result<()> {
    let mesh = crate::mesh::io::read_mesh(&args.mesh)?;
    let mut measurer = Measurer::new();
    let t0 = Instant::now();
    let m = measurer
        .measure(&mesh)
        .with_context(|| format!("measuring {}", args.mesh.display()))?;
    let first_ms = t0.elapsed().as_secs_f64() * 1e3;
    // A second call on a moved copy (same triangles, new positions) shows what a
    // frame costs: the height index is rebuilt, the buffers and edge table are reused.
    let mut moved = mesh.clone();
    moved.map_positions(|p| p + glam::DVec3::new(0.0, 0.0, FRAME_SHIFT_M));
    let t1 = Instant::now();
    let _ = measurer.measure(&moved);
    let frame_ms = t1.elapsed().as_secs_f64() * 1e3;
    if args.json {
        let json = json_report(&m, first_ms, frame_ms);
        println!("{}", serde_json::to_string_pretty(&json)?);
    } else {
        print!("{}", table(&m));
        println!(
            "{} vertices, {} triangles; measure() wall clock: {first_ms:.2} ms first call, \
             {frame_ms:.2} ms next frame",
            mesh.vertex_count(),
            mesh.triangle_count()
        );
    }
    Ok(())
}

/// The JSON printed by `--json`: `measurements_mm` (report keys), `levels_m`,
/// `torso_profile`, and the wall-clock time of the first and of a next-frame call.
pub fn json_report(m: &Measurements, first_ms: f64, frame_ms: f64) -> serde_json::Value {
    serde_json::json!({
        "measurements_mm": m.to_report_map(),
        "levels_m": m.levels,
        "torso_profile": m.torso_profile,
        "timings_ms": { "measure_first_call": first_ms, "measure_next_frame": frame_ms },
    })
}

/// A readable table of the measurements and their levels.
pub fn table(m: &Measurements) -> String {
    let l = &m.levels;
    let rows = [
        ("stature", m.stature_mm, None, "ISO 8559-1 5.1.1"),
        ("chest girth", m.chest_girth_mm, Some(l.chest_m), "5.3.4"),
        ("waist girth", m.waist_girth_mm, Some(l.waist_m), "5.3.10"),
        ("hip girth", m.hip_girth_mm, Some(l.hip_m), "5.3.13"),
        (
            "thigh girth left",
            m.thigh_girth_left_mm,
            Some(l.thigh_left_m),
            "5.3.20",
        ),
        (
            "thigh girth right",
            m.thigh_girth_right_mm,
            Some(l.thigh_right_m),
            "5.3.20",
        ),
        (
            "hip girth max",
            m.hip_girth_max_mm,
            Some(l.hip_girth_max_m),
            "(informational)",
        ),
    ];
    let mut s = format!(
        "{:<18} {:>9} {:>10}  {}\n",
        "measurement", "mm", "level m", "ISO 8559-1"
    );
    for (name, mm, level, iso) in rows {
        let level = level.map_or("-".to_string(), |y| format!("{y:.4}"));
        s += &format!("{name:<18} {mm:>9.1} {level:>10}  {iso}\n");
    }
    s += &format!(
        "levels: crotch {:.4} m, armpit {:.4} m, body axis x {:.4} m; torso profile: {} samples\n",
        l.crotch_m,
        l.armpit_m,
        l.axis_x_m,
        m.torso_profile.len()
    );
    s
}
