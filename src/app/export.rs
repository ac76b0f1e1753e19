//! Operator exports: the avatar (OBJ, PLY or glTF binary through `mesh::io::write_mesh`)
//! and the measurements (JSON with `measurements_mm` as in `report.json`, or CSV with
//! `name,value_mm,stability_mm,uncertainty_mm,hand_edit_mm`). Values in millimetres,
//! avatar in metres, station frame. Hand edits of the avatar are carried as in
//! `report.json` (`AvatarEditor::mark_report`: `measurements_mm` edited,
//! `measurements_fit_mm`, `edited_by_hand`, `hand_edits`) and in the CSV's last column.

use crate::edit::AvatarEditor;
use crate::mesh::io::{write_mesh, MeshIoError};
use crate::mesh::TriMesh;
use crate::pipeline::MeasurementValue;
use std::path::{Path, PathBuf};

#[derive(Debug, thiserror::Error)]
pub enum ExportError {
    #[error(transparent)]
    Mesh(#[from] MeshIoError),
    #[error("{path}: {source}")]
    Io {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error(transparent)]
    Output(#[from] crate::io::atomic::AtomicError),
    #[error("nothing to export: {0}")]
    Nothing(&'static str),
}

/// Avatar file formats offered to the operator.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum AvatarFormat {
    Obj,
    Ply,
    Glb,
}

impl AvatarFormat {
    pub const ALL: [AvatarFormat; 3] = [AvatarFormat::Obj, AvatarFormat::Ply, AvatarFormat::Glb];
    pub fn extension(self) -> &'static str {
        match self {
            AvatarFormat::Obj => "obj",
            AvatarFormat::Ply => "ply",
            AvatarFormat::Glb => "glb",
        }
    }
}

/// Writes `<dir>/avatar.<ext>`; returns the path.
pub fn export_avatar(
    dir: &Path,
    mesh: Option<&TriMesh>,
    format: AvatarFormat,
) -> Result<PathBuf, ExportError> {
    let mesh = mesh.ok_or(ExportError::Nothing("no avatar has been fitted yet"))?;
    crate::io::atomic::create_dir(dir)?;
    let path = dir.join(format!("avatar.{}", format.extension()));
    write_mesh(&path, mesh)?;
    Ok(path)
}

/// Measurements as JSON: `{"measurements_mm": {...}, "stability_mm": {...},
/// "uncertainty_mm": {...}, "uncertain": [...]}`, values rounded to 0.1 mm (an unknown
/// uncertainty is left out).
pub fn measurements_json(m: &[MeasurementValue]) -> serde_json::Value {
    let round = |v: f64| (v * 10.0).round() / 10.0;
    let mut values = serde_json::Map::new();
    let mut stability = serde_json::Map::new();
    let mut uncertainty = serde_json::Map::new();
    for v in m {
        values.insert(v.name.clone(), serde_json::json!(round(v.value_mm)));
        stability.insert(v.name.clone(), serde_json::json!(round(v.stability_mm)));
        if v.uncertainty_mm.is_finite() {
            uncertainty.insert(v.name.clone(), serde_json::json!(round(v.uncertainty_mm)));
        }
    }
    let uncertain: Vec<&str> = m
        .iter()
        .filter(|v| v.uncertain)
        .map(|v| v.name.as_str())
        .collect();
    serde_json::json!({ "measurements_mm": values, "stability_mm": stability,
        "uncertainty_mm": uncertainty, "uncertain": uncertain })
}

/// Measurements as CSV with a header line; `hand_edits_mm` (report key, change) are
/// added to the values they changed and listed in the last column.
pub fn measurements_csv(m: &[MeasurementValue], hand_edits_mm: &[(String, f64)]) -> String {
    let mut s = String::from("name,value_mm,stability_mm,uncertainty_mm,hand_edit_mm\n");
    for v in m {
        let edit = hand_edits_mm
            .iter()
            .find(|(k, _)| *k == v.name)
            .map(|e| e.1);
        // Names are report keys (no commas); quote defensively anyway.
        let name = if v.name.contains([',', '"']) {
            format!("\"{}\"", v.name.replace('"', "\"\""))
        } else {
            v.name.clone()
        };
        let pm = if v.uncertainty_mm.is_finite() {
            format!("{:.1}", v.uncertainty_mm)
        } else {
            String::new()
        };
        s.push_str(&format!(
            "{},{:.1},{:.1},{pm},{}\n",
            name,
            v.value_mm + edit.unwrap_or(0.0),
            v.stability_mm,
            edit.map(|d| format!("{d:.1}")).unwrap_or_default()
        ));
    }
    s
}

/// Writes `<dir>/measurements.json` and `<dir>/measurements.csv`; returns both paths.
/// `m` are the fit's values; an `editor` with hand edits marks both files with them.
pub fn export_measurements(
    dir: &Path,
    m: &[MeasurementValue],
    editor: Option<&AvatarEditor>,
) -> Result<[PathBuf; 2], ExportError> {
    if m.is_empty() {
        return Err(ExportError::Nothing("no measurements yet"));
    }
    crate::io::atomic::create_dir(dir)?;
    let json = dir.join("measurements.json");
    let mut report = measurements_json(m);
    let mut changes = Vec::new();
    if let Some(e) = editor {
        e.mark_report(&mut report);
        if e.edits().len() > 0 {
            changes = e.changes_mm();
        }
    }
    let text = serde_json::to_string_pretty(&report).unwrap_or_default();
    let csv = dir.join("measurements.csv");
    let csv_text = measurements_csv(m, &changes);
    crate::io::atomic::write_all(&[(&json, text.as_bytes()), (&csv, csv_text.as_bytes())])?;
    Ok([json, csv])
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::io::read_mesh;
    use crate::mesh::shapes;

    fn values() -> Vec<MeasurementValue> {
        vec![
            MeasurementValue {
                name: "chest_girth".into(),
                value_mm: 1001.04,
                stability_mm: 0.26,
                uncertainty_mm: 9.04,
                uncertain: false,
            },
            MeasurementValue {
                name: "odd,name".into(),
                value_mm: 5.0,
                stability_mm: 0.0,
                uncertainty_mm: f64::INFINITY,
                uncertain: true,
            },
        ]
    }

    #[test]
    fn json_and_csv_carry_every_value() {
        let j = measurements_json(&values());
        assert_eq!(
            j["measurements_mm"]["chest_girth"],
            serde_json::json!(1001.0)
        );
        assert_eq!(j["stability_mm"]["chest_girth"], serde_json::json!(0.3));
        assert_eq!(j["uncertainty_mm"]["chest_girth"], serde_json::json!(9.0));
        assert!(j["uncertainty_mm"].get("odd,name").is_none());
        assert_eq!(j["uncertain"], serde_json::json!(["odd,name"]));
        let csv = measurements_csv(&values(), &[("chest_girth".into(), 12.34)]);
        let lines: Vec<&str> = csv.lines().collect();
        assert_eq!(
            lines[0],
            "name,value_mm,stability_mm,uncertainty_mm,hand_edit_mm"
        );
        assert_eq!(lines[1], "chest_girth,1013.4,0.3,9.0,12.3");
        assert_eq!(lines[2], "\"odd,name\",5.0,0.0,,");
    }

    #[test]
    fn exports_read_back() {
        let dir = std::env::temp_dir().join(format!("fitstation-export-{}", std::process::id()));
        let mesh = shapes::uv_sphere(0.5, 6, 8);
        for f in AvatarFormat::ALL {
            let p = export_avatar(&dir, Some(&mesh), f).expect("export");
            if f != AvatarFormat::Glb {
                let back = read_mesh(&p).expect("read back");
                assert_eq!(back.vertex_count(), mesh.vertex_count());
            } else {
                assert!(std::fs::metadata(&p).expect("glb").len() > 0);
            }
        }
        assert!(matches!(
            export_avatar(&dir, None, AvatarFormat::Obj),
            Err(ExportError::Nothing(_))
        ));
        let [j, c] = export_measurements(&dir, &values(), None).expect("measurements");
        let parsed: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(j).expect("json")).expect("valid json");
        assert_eq!(
            parsed["measurements_mm"]["odd,name"],
            serde_json::json!(5.0)
        );
        assert!(std::fs::read_to_string(c)
            .expect("csv")
            .starts_with("name,"));
        assert!(matches!(
            export_measurements(&dir, &[], None),
            Err(ExportError::Nothing(_))
        ));
        let _ = std::fs::remove_dir_all(&dir);
    }
}
