//! What a fit writes (`../shared/spec/formats.md`, "What a fit writes"): `avatar.obj`
//! (metres, station frame, template vertex order) and `report.json`.
//!
//! Outputs are written atomically ([`crate::io::atomic`]): both files are written and
//! fsynced under temporary names beside their final ones, then renamed into place, so a
//! failed or killed run never leaves a half-written file and never destroys an earlier
//! good one (each file is the old one or the complete new one).

use crate::io::atomic::{self, AtomicError};
use crate::mesh::{io::write_obj_to, TriMesh};
use std::path::{Path, PathBuf};

/// Errors writing the outputs.
#[derive(Debug, thiserror::Error)]
pub enum OutputError {
    #[error("{path}: {msg}")]
    Io { path: PathBuf, msg: String },
    #[error(transparent)]
    Output(#[from] AtomicError),
}

/// Writes `avatar.obj` and `report.json` into `out` atomically.
///
/// # Errors
/// `out` is an existing file (said in words), or a write failed.
pub fn write_fit_outputs(
    out: &Path,
    avatar: &TriMesh,
    report: &serde_json::Value,
) -> Result<(), OutputError> {
    atomic::create_dir(out)?;
    let obj_path = out.join("avatar.obj");
    let mut obj = Vec::new();
    write_obj_to(&mut obj, avatar).map_err(|e| OutputError::Io {
        path: obj_path.clone(),
        msg: e.to_string(),
    })?;
    let json_path = out.join("report.json");
    let text = serde_json::to_string_pretty(report).map_err(|e| OutputError::Io {
        path: json_path.clone(),
        msg: e.to_string(),
    })? + "\n";
    atomic::write_all(&[(&obj_path, &obj), (&json_path, text.as_bytes())])?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::shapes;

    #[test]
    fn writes_both_files_and_no_temporary_remains() {
        let dir = std::env::temp_dir().join(format!("fitstation-out-{}", std::process::id()));
        let out = dir.join("result");
        let m = shapes::uv_sphere(0.1, 4, 8);
        write_fit_outputs(
            &out,
            &m,
            &serde_json::json!({"measurements_mm": {"stature": 1.0}}),
        )
        .unwrap();
        assert!(out.join("avatar.obj").exists());
        let r: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(out.join("report.json")).unwrap())
                .unwrap();
        assert_eq!(r["measurements_mm"]["stature"], 1.0);
        let leftovers: Vec<_> = std::fs::read_dir(&dir)
            .unwrap()
            .filter_map(|e| e.ok())
            .filter(|e| e.file_name().to_string_lossy().starts_with('.'))
            .collect();
        assert!(leftovers.is_empty());
        std::fs::remove_dir_all(&dir).ok();
    }
}
