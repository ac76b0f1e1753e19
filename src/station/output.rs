//! What a fit writes (`../shared/spec/formats.md`, "What a fit writes"): `avatar.obj`
//! (metres, station frame, template vertex order) and `report.json`.
//!
//! Outputs are written atomically: files go to a temporary folder beside `--out` and are
//! renamed into place only when all of them were written, so a failed run never leaves a
//! half-written result and never destroys an earlier good one.

use crate::mesh::{io::write_obj, TriMesh};
use std::path::{Path, PathBuf};

/// Errors writing the outputs.
#[derive(Debug, thiserror::Error)]
pub enum OutputError {
    #[error("{path}: {msg}")]
    Io { path: PathBuf, msg: String },
}

fn io_err(path: &Path) -> impl Fn(std::io::Error) -> OutputError + '_ {
    move |e| OutputError::Io {
        path: path.to_path_buf(),
        msg: e.to_string(),
    }
}

/// Writes `avatar.obj` and `report.json` into `out` atomically.
pub fn write_fit_outputs(
    out: &Path,
    avatar: &TriMesh,
    report: &serde_json::Value,
) -> Result<(), OutputError> {
    let parent = out
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    std::fs::create_dir_all(parent).map_err(io_err(parent))?;
    let name = out
        .file_name()
        .map(|n| n.to_string_lossy().to_string())
        .unwrap_or_else(|| "out".into());
    let tmp = parent.join(format!(".{name}.tmp-{}", std::process::id()));
    if tmp.exists() {
        std::fs::remove_dir_all(&tmp).map_err(io_err(&tmp))?;
    }
    std::fs::create_dir_all(&tmp).map_err(io_err(&tmp))?;
    let result = (|| {
        write_obj(&tmp.join("avatar.obj"), avatar).map_err(|e| OutputError::Io {
            path: tmp.join("avatar.obj"),
            msg: e.to_string(),
        })?;
        let text = serde_json::to_string_pretty(report).map_err(|e| OutputError::Io {
            path: tmp.join("report.json"),
            msg: e.to_string(),
        })?;
        std::fs::write(tmp.join("report.json"), text + "\n")
            .map_err(io_err(&tmp.join("report.json")))?;
        std::fs::create_dir_all(out).map_err(io_err(out))?;
        for f in ["avatar.obj", "report.json"] {
            std::fs::rename(tmp.join(f), out.join(f)).map_err(io_err(&out.join(f)))?;
        }
        Ok(())
    })();
    let _ = std::fs::remove_dir_all(&tmp);
    result
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
