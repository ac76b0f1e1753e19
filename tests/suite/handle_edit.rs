//! Hand edits of a fitted avatar (issue 23): the bundled recording is fitted, a point on
//! the front of the waist is dragged 20 mm forward, and the edit must move that point
//! 20 mm, leave every vertex 30 cm away within 1 mm, change the waist girth, be undone
//! exactly and be marked in the report; `fitstation edit` does the same on a fit's
//! output folder, and undoing every edit gives back the fit's files byte for byte.

use crate::common;

use common::{tmp_dir, GIRTHS};
use fitstation::cli::{run_offline, RecordingSource};
use fitstation::edit::{AvatarEditor, DEFAULT_REACH_M};
use fitstation::mesh::TriMesh;
use fitstation::station::{default_library, StationOptions, StationProcessor};
use glam::DVec3;
use std::path::Path;
use std::process::Command;

const DEMO: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/recordings/demo");

/// The demo recording's fitted avatar and report.
fn demo_fit() -> (TriMesh, serde_json::Value) {
    let mut src = RecordingSource::open(Path::new(DEMO)).expect("open the demo recording");
    let calib = src.recording().calibration().clone();
    let library = default_library().expect("shape library");
    let mut station =
        StationProcessor::new(calib, library, StationOptions::default()).expect("station");
    let run = run_offline(&mut src, &mut station, None, false);
    (run.avatar.expect("the demo is fitted"), run.report)
}

/// The vertex at the front of the torso at the waist level: the most forward vertex
/// within 1 cm of the waist height and 6 cm of the body axis.
fn waist_front(editor: &AvatarEditor) -> u32 {
    let l = &editor.fit_measurements().levels;
    let (i, _) = editor
        .mesh()
        .positions
        .iter()
        .enumerate()
        .filter(|(_, p)| (p.y - l.waist_m).abs() < 0.01 && (p.x - l.axis_x_m).abs() < 0.06)
        .max_by(|a, b| a.1.z.total_cmp(&b.1.z))
        .expect("vertices at the waist");
    i as u32
}

#[test]
fn a_20_mm_drag_moves_the_point_keeps_the_far_body_and_undoes_exactly() {
    let (avatar, report) = demo_fit();
    let mut editor = AvatarEditor::new(avatar.clone()).expect("editor");
    let handle = waist_front(&editor);
    let offset = DVec3::new(0.0, 0.0, 0.020);
    let waist_before = editor.measurements().waist_girth_mm;

    // A live drag: picked up, moved in steps (the measurements follow), let go.
    editor.begin_drag(handle, DEFAULT_REACH_M).expect("pick up");
    for k in 1..=4 {
        editor.drag_to(offset * (k as f64 / 4.0)).expect("drag");
    }
    let edit = editor.end_drag().expect("an edit").clone();
    let after = editor.mesh().positions.clone();

    let h = handle as usize;
    let moved = after[h].distance(avatar.positions[h]);
    assert!(
        (moved - 0.020).abs() < 1e-9,
        "the point moved {:.4} mm",
        moved * 1e3
    );
    let mut far = 0usize;
    for (i, (a, b)) in after.iter().zip(&avatar.positions).enumerate() {
        if b.distance(avatar.positions[h]) >= 0.30 {
            far += 1;
            assert!(
                a.distance(*b) < 1e-3,
                "vertex {i}, 30 cm away, moved {:.3} mm",
                a.distance(*b) * 1e3
            );
        }
    }
    assert!(
        far > avatar.positions.len() / 2,
        "only {far} vertices are 30 cm away"
    );
    // Something between moved, smoothly: less than the handle, more than nothing.
    let between = after
        .iter()
        .zip(&avatar.positions)
        .filter(|(a, b)| {
            let d = a.distance(**b);
            d > 1e-4 && d < 0.0199
        })
        .count();
    assert!(between > 20, "{between} vertices follow the handle");

    let waist_after = editor.measurements().waist_girth_mm;
    assert!(
        waist_after - waist_before > 5.0,
        "waist {waist_before:.1} -> {waist_after:.1} mm"
    );
    assert_eq!(edit.vertex, handle);
    assert_eq!(edit.near, "waist");
    let change = edit
        .changes_mm
        .iter()
        .find(|(k, _)| k == "waist_girth")
        .map(|&(_, d)| d)
        .expect("the edit lists the waist change");
    assert!((change - (waist_after - waist_before)).abs() < 1e-9);

    // The report says what was edited, where and by how much.
    let mut marked = report.clone();
    editor.mark_report(&mut marked);
    let fit_waist = report["measurements_mm"]["waist_girth"]
        .as_f64()
        .expect("waist");
    assert_eq!(marked["measurements_fit_mm"], report["measurements_mm"]);
    let edited_waist = marked["measurements_mm"]["waist_girth"]
        .as_f64()
        .expect("waist");
    assert!(
        (edited_waist - (fit_waist + change)).abs() < 0.06,
        "{edited_waist} vs {fit_waist} + {change}"
    );
    assert!(marked["edited_by_hand"]
        .as_array()
        .expect("list")
        .iter()
        .any(|k| k == "waist_girth"));
    let listed = &marked["hand_edits"][0];
    assert_eq!(listed["vertex"], handle);
    assert_eq!(listed["near"], "waist");
    assert!((listed["distance_mm"].as_f64().expect("distance") - 20.0).abs() < 0.05);
    assert!(listed["changes_mm"]["waist_girth"].as_f64().is_some());
    // Values no edit reached are the fit's.
    for k in GIRTHS
        .iter()
        .filter(|k| !edit.changes_mm.iter().any(|(c, _)| c == *k))
    {
        assert_eq!(
            marked["measurements_mm"][k], report["measurements_mm"][k],
            "{k}"
        );
    }

    // Undo: bit for bit the fitted mesh and its measurements.
    let undone = editor.undo().expect("undo");
    assert_eq!(undone, edit);
    assert_eq!(editor.mesh().positions, avatar.positions);
    assert_eq!(editor.measurements(), editor.fit_measurements());
    assert!(editor.undo().is_none());
    let mut unmarked = report.clone();
    editor.mark_report(&mut unmarked);
    assert_eq!(unmarked, report);
}

#[test]
fn a_cancelled_drag_and_a_refused_edit_leave_the_avatar_as_it_was() {
    let (avatar, _) = demo_fit();
    let mut editor = AvatarEditor::new(avatar.clone()).expect("editor");
    let handle = waist_front(&editor);
    editor.begin_drag(handle, 0.1).expect("pick up");
    editor.drag_to(DVec3::new(0.01, 0.0, 0.01)).expect("drag");
    assert_ne!(editor.mesh().positions, avatar.positions);
    editor.cancel_drag();
    assert_eq!(editor.mesh().positions, avatar.positions);
    assert!(editor
        .apply(handle, DVec3::new(0.0, 0.0, 0.4), 0.1)
        .is_err());
    assert!(editor
        .apply(handle, DVec3::new(f64::NAN, 0.0, 0.0), 0.1)
        .is_err());
    assert!(editor
        .apply(u32::MAX, DVec3::new(0.0, 0.0, 0.01), 0.1)
        .is_err());
    assert!(editor
        .apply(handle, DVec3::new(0.0, 0.0, 0.01), -1.0)
        .is_err());
    assert_eq!(editor.mesh().positions, avatar.positions);
    assert_eq!(editor.edits().len(), 0);
}

fn fitstation(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_fitstation"))
        .args(args)
        .output()
        .expect("run fitstation")
}

#[test]
fn the_edit_command_marks_the_report_and_undo_gives_back_the_fit_byte_for_byte() {
    let dir = tmp_dir("edit", "cli");
    let out = dir.join("fit");
    let o = fitstation(&["replay", DEMO, "--out", out.to_str().expect("utf-8")]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let fit_obj = std::fs::read(out.join("avatar.obj")).expect("avatar");
    let fit_report = std::fs::read(out.join("report.json")).expect("report");
    // A point 5 mm in front of the waist's front vertex.
    let mesh = fitstation::mesh::io::read_mesh(&out.join("avatar.obj")).expect("mesh");
    let front =
        mesh.positions[waist_front(&AvatarEditor::new(mesh.clone()).expect("editor")) as usize];
    let at = format!("{},{},{}", front.x, front.y, front.z + 0.005);
    let dir_s = out.to_str().expect("utf-8");
    let o = fitstation(&["edit", dir_s, "--at", &at, "--by", "0,0,20"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let o = fitstation(&[
        "edit",
        dir_s,
        "--vertex",
        "0",
        "--by",
        "0,5,0",
        "--reach-mm",
        "60",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let report: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("report.json")).expect("report"))
            .expect("JSON");
    assert_eq!(
        report["hand_edits"].as_array().map(Vec::len),
        Some(2),
        "{report}"
    );
    assert!(report["edited_by_hand"]
        .as_array()
        .expect("list")
        .iter()
        .any(|k| k == "waist_girth"));
    let fitted: serde_json::Value = serde_json::from_slice(&fit_report).expect("JSON");
    assert_eq!(report["measurements_fit_mm"], fitted["measurements_mm"]);
    assert!(
        report["measurements_mm"]["waist_girth"].as_f64()
            > fitted["measurements_mm"]["waist_girth"].as_f64()
    );
    assert!(out.join("avatar.fit.obj").exists());
    assert_ne!(
        std::fs::read(out.join("avatar.obj")).expect("avatar"),
        fit_obj
    );

    for _ in 0..2 {
        let o = fitstation(&["edit", dir_s, "--undo"]);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    }
    assert_eq!(
        std::fs::read(out.join("avatar.obj")).expect("avatar"),
        fit_obj
    );
    assert_eq!(
        std::fs::read(out.join("report.json")).expect("report"),
        fit_report
    );
    assert!(!out.join("avatar.fit.obj").exists());
    let o = fitstation(&["edit", dir_s, "--undo"]);
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("no hand edit to undo"));
    let _ = std::fs::remove_dir_all(&dir);
}
