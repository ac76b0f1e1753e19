//! `eval` on a result that is the truth itself reports zero error; on a deliberately
//! shrunk body it reports the shrink; the CLI writes its table and a self-contained
//! HTML report.

use fitstation::eval::{evaluate, FitResult};
use fitstation::mesh::io::{read_obj, write_obj};
use fitstation::mesh::TriMesh;
use fitstation::recording::FrameFormat;
use fitstation::synth::{self, load_truth, render_recording, truth_dir, SynthConfig};
use std::path::{Path, PathBuf};

/// Horizontal shrink of the deliberately wrong body.
const SHRINK: f64 = 0.97;

fn body_available() -> bool {
    match synth::subject_mesh(&synth::subject::SubjectParams::sample(1)) {
        Ok(_) => true,
        Err(e) => {
            println!("SKIPPED: no body source ({e}); eval tests did not run");
            false
        }
    }
}

fn recording(name: &str) -> PathBuf {
    let out = std::env::temp_dir().join(format!("fitstation-eval-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&out);
    let mut cfg = SynthConfig::from_seed(21);
    cfg.empty_frames = 10;
    cfg.subject_frames = 2;
    cfg.format = FrameFormat::Png;
    render_recording(&cfg, &out).unwrap();
    out
}

/// A fit result folder holding `mesh`, measured by the same measurement function the
/// truth uses, with the truth's landmarks moved like the mesh (`map`).
fn result_folder(
    dir: &Path,
    mesh: &TriMesh,
    truth_dir: &Path,
    map: &dyn Fn([f64; 3]) -> [f64; 3],
    masks: bool,
) {
    std::fs::create_dir_all(dir).unwrap();
    write_obj(&dir.join("avatar.obj"), mesh).unwrap();
    let avatar = read_obj(&dir.join("avatar.obj"), None).unwrap();
    let m = synth::subject::measurements_mm(&avatar).unwrap();
    let truth = load_truth(truth_dir).unwrap();
    let lm: serde_json::Map<String, serde_json::Value> = truth
        .landmarks
        .iter()
        .map(|(k, p)| (k.clone(), serde_json::json!(map(*p))))
        .collect();
    let report = serde_json::json!({
        "measurements_mm": m,
        "landmarks": lm,
        "frames": { "total": 12, "with_subject": 2, "fitted": 2 },
        "timings_ms": { "segment": { "median": 1.5, "p95": 2.0 }, "fit": { "median": 20.0, "p95": 31.0 } }
    });
    std::fs::write(
        dir.join("report.json"),
        serde_json::to_string_pretty(&report).unwrap(),
    )
    .unwrap();
    if masks {
        for view in ["front", "side"] {
            let src = truth_dir.join("masks").join(view);
            let dst = dir.join("masks").join(view);
            std::fs::create_dir_all(&dst).unwrap();
            for e in std::fs::read_dir(&src).unwrap() {
                let p = e.unwrap().path();
                std::fs::copy(&p, dst.join(p.file_name().unwrap())).unwrap();
            }
        }
    }
}

#[test]
fn truth_scores_zero_and_a_shrunk_body_reports_the_shrink() {
    if !body_available() {
        return;
    }
    let rec = recording("score");
    let tdir = truth_dir(&rec);
    let truth = load_truth(&tdir).unwrap();
    let true_mesh = read_obj(&tdir.join("mesh.obj"), None).unwrap();

    // The truth itself.
    let same = rec.with_file_name(format!(
        "{}-same",
        rec.file_name().unwrap().to_string_lossy()
    ));
    result_folder(&same, &true_mesh, &tdir, &|p| p, true);
    let row = evaluate(&tdir, &FitResult::load(&same).unwrap()).unwrap();
    assert_eq!(row.measurements.len(), truth.measurements_mm.len());
    for m in &row.measurements {
        let e = m.error_mm.unwrap();
        assert!(
            e.abs() < 1e-9,
            "{}: error {e} mm on the truth itself",
            m.name
        );
    }
    let s = row.surface.unwrap();
    assert!(s.mean_mm < 0.01 && s.p95_mm < 0.01, "{s:?}");
    for (view, iou) in &row.mask_iou {
        assert!((iou - 1.0).abs() < 1e-12, "{view} IoU {iou}");
    }
    assert_eq!(row.mask_iou.len(), 2);
    assert!(row.landmarks.distance_mm.values().all(|e| *e < 0.01));
    assert_eq!(row.timings_ms["fit"].p95, 31.0);

    // Shrunk horizontally about the body axis (the crotch's vertical line).
    let c = truth.landmarks["crotch"];
    let shrink = |p: [f64; 3]| {
        [
            c[0] + SHRINK * (p[0] - c[0]),
            p[1],
            c[2] + SHRINK * (p[2] - c[2]),
        ]
    };
    let mut small = true_mesh.clone();
    small.map_positions(|p| glam::DVec3::from_array(shrink(p.to_array())));
    let shrunk = rec.with_file_name(format!(
        "{}-shrunk",
        rec.file_name().unwrap().to_string_lossy()
    ));
    result_folder(&shrunk, &small, &tdir, &shrink, false);
    let row = evaluate(&tdir, &FitResult::load(&shrunk).unwrap()).unwrap();
    for m in &row.measurements {
        let e = m.error_mm.unwrap();
        if m.name.contains("girth") {
            let rel = e / m.true_mm;
            assert!(
                (rel - (SHRINK - 1.0)).abs() < 0.004,
                "{}: relative error {rel}, expected {}",
                m.name,
                SHRINK - 1.0
            );
        } else if m.name == "stature" {
            assert!(e.abs() < 0.05, "stature error {e}");
        }
    }
    let s = row.surface.unwrap();
    assert!(s.mean_mm > 1.0 && s.p95_mm > s.mean_mm, "{s:?}");
    assert!(row.landmarks.distance_mm.values().any(|e| *e > 1.0));
    assert!(row.mask_iou.is_empty());

    // The CLI: table, JSON and HTML report.
    let exe = env!("CARGO_BIN_EXE_fitstation");
    let report_dir = rec.with_file_name(format!(
        "{}-report",
        rec.file_name().unwrap().to_string_lossy()
    ));
    let out = std::process::Command::new(exe)
        .arg("eval")
        .arg(&rec)
        .arg("--result")
        .arg(&shrunk)
        .arg("--report")
        .arg(&report_dir)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(text.contains("hip_girth") && text.contains("MAE"), "{text}");
    let html = std::fs::read_to_string(report_dir.join("index.html")).unwrap();
    assert!(html.contains("<svg") && html.contains("data:image/png;base64,"));
    // The shrunk result's report carries the shrunk truth landmarks.
    assert!(
        html.contains("Landmarks: silhouettes"),
        "no landmark table in the report"
    );
    assert!(
        !html.contains("src=\"http") && !html.contains("href=\"http"),
        "external asset in the report"
    );
    let out = std::process::Command::new(exe)
        .arg("eval")
        .arg(&rec)
        .arg("--result")
        .arg(&same)
        .arg("--json")
        .output()
        .unwrap();
    assert!(out.status.success());
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert!(v["summary"]
        .as_array()
        .unwrap()
        .iter()
        .all(|m| m["mean_abs_error_mm"].as_f64().unwrap() < 1e-9));

    for d in [&rec, &tdir, &same, &shrunk, &report_dir] {
        let _ = std::fs::remove_dir_all(d);
    }
}
