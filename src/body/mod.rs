//! The body template and the shape library.
//!
//! # Conventions
//! - Station frame (`../shared/spec/formats.md`): metres, +Y up, the subject faces +Z,
//!   +X is the subject's LEFT; bodies stand with their soles on y = 0 and are centred on
//!   the mark (x = z = 0 at the midpoint between the two feet).
//! - A *template* is any watertight triangle mesh of a person in an A-pose
//!   ([`Template`]). What the fit needs to know about it (skeleton joints of method.md
//!   section 1, landmark heights, rigid parts as vertex sets) is found geometrically by
//!   [`prepare`] and stored in a JSON sidecar (`MESH.template.json`); nothing here or
//!   downstream depends on MakeHuman vertex indices.
//! - The *shape library* ([`ShapeLibrary`]) is MakeHuman's macro model restricted to adults
//!   (CC0 data imported by [`import`], stored in the compact format of [`library`]):
//!   any [`ShapeParams`] gives one body, deterministically, with the topology and vertex
//!   order of the library's template.
//!
//! Sub-modules: [`import`] (MakeHuman/MPFB2 folder -> `templates/`), [`library`] (file
//! format and fast body evaluation), [`prepare`] (geometric skeleton, landmarks, rigid
//! parts), [`decimate`] (edge-collapse simplification, used to make a template of another
//! topology), [`cli`] (`fitstation templates ...`).

pub mod cli;
pub mod decimate;
pub mod import;
pub mod library;
pub mod prepare;
#[cfg(test)]
mod tests;

use crate::mesh::io::MeshIoError;
use crate::mesh::TriMesh;
use std::path::PathBuf;

pub use cli::{run, TemplatesArgs};
pub use library::ShapeLibrary;
pub use prepare::surface::{surface_landmarks, SurfaceLandmarks};
pub use prepare::{prepare, Joints, Landmarks, RigidParts, TemplateInfo};

/// Errors of the body module. File errors name the file and the line (text) or the
/// record (binary data).
#[derive(Debug, thiserror::Error)]
pub enum BodyError {
    #[error("{file}: {source}")]
    Io {
        file: PathBuf,
        source: std::io::Error,
    },
    #[error("{file}:{line}: {msg}")]
    Parse {
        file: PathBuf,
        line: usize,
        msg: String,
    },
    #[error("{file}: {msg}")]
    Format { file: PathBuf, msg: String },
    #[error(transparent)]
    Mesh(#[from] MeshIoError),
    #[error("template analysis failed: {0}")]
    Prepare(String),
}

impl BodyError {
    pub(crate) fn io(file: &std::path::Path, source: std::io::Error) -> Self {
        BodyError::Io {
            file: file.to_path_buf(),
            source,
        }
    }
    pub(crate) fn parse(file: &std::path::Path, line: usize, msg: impl Into<String>) -> Self {
        BodyError::Parse {
            file: file.to_path_buf(),
            line,
            msg: msg.into(),
        }
    }
    pub(crate) fn format(file: &std::path::Path, msg: impl Into<String>) -> Self {
        BodyError::Format {
            file: file.to_path_buf(),
            msg: msg.into(),
        }
    }
}

/// Youngest age the adult library represents (MakeHuman's "young" key, age value 0.5).
pub const AGE_MIN_YEARS: f64 = 25.0;
/// Oldest age (MakeHuman's "old" key, age value 1.0).
pub const AGE_MAX_YEARS: f64 = 90.0;

/// Macro parameters of one adult body of the shape library.
///
/// Ranges (see [`ShapeParams::clamp`]): `gender` 0 (female) .. 1 (male); `age_years`
/// 25 .. 90 (younger adults are represented by 25: MakeHuman's targets below 25 years
/// are child shapes); `muscle`, `weight`, `height`, `proportions` 0 .. 1 with 0.5 the
/// average (MakeHuman's macro sliders; `proportions` 0 = uncommon, 1 = ideal); `cup` 0 ..
/// 1, the breasts' size (MakeHuman's cup size: 0 the smallest, 0.5 the average body's,
/// 1 the largest; on men it shapes the pectoral region the same way).
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct ShapeParams {
    pub gender: f64,
    pub age_years: f64,
    pub muscle: f64,
    pub weight: f64,
    pub height: f64,
    pub proportions: f64,
    /// Absent from files written before it existed: the average, 0.5.
    #[serde(default = "ShapeParams::average_slider")]
    pub cup: f64,
}

impl Default for ShapeParams {
    /// The average adult: MakeHuman's neutral macro settings (gender 0.5, 25 years, all
    /// sliders 0.5, the three race targets mixed equally).
    fn default() -> Self {
        ShapeParams {
            gender: 0.5,
            age_years: AGE_MIN_YEARS,
            muscle: 0.5,
            weight: 0.5,
            height: 0.5,
            proportions: 0.5,
            cup: 0.5,
        }
    }
}

impl ShapeParams {
    /// Clamps every field into its documented range (NaN becomes the default value).
    pub fn clamp(&self) -> ShapeParams {
        let d = ShapeParams::default();
        let c = |v: f64, lo: f64, hi: f64, def: f64| if v.is_nan() { def } else { v.clamp(lo, hi) };
        ShapeParams {
            gender: c(self.gender, 0.0, 1.0, d.gender),
            age_years: c(self.age_years, AGE_MIN_YEARS, AGE_MAX_YEARS, d.age_years),
            muscle: c(self.muscle, 0.0, 1.0, d.muscle),
            weight: c(self.weight, 0.0, 1.0, d.weight),
            height: c(self.height, 0.0, 1.0, d.height),
            proportions: c(self.proportions, 0.0, 1.0, d.proportions),
            cup: c(self.cup, 0.0, 1.0, d.cup),
        }
    }

    fn average_slider() -> f64 {
        0.5
    }

    /// MakeHuman's age slider value (0.5 at 25 years, 1.0 at 90 years) of a clamped age.
    pub fn makehuman_age(&self) -> f64 {
        let y = self.clamp().age_years;
        0.5 + 0.5 * (y - AGE_MIN_YEARS) / (AGE_MAX_YEARS - AGE_MIN_YEARS)
    }
}

/// A template body: its mesh (station frame) and what [`prepare`] found on it.
#[derive(Clone, Debug)]
pub struct Template {
    pub mesh: TriMesh,
    pub info: TemplateInfo,
}

impl Template {
    /// Reads a template mesh (OBJ/PLY) and its sidecar `MESH.template.json` if present,
    /// else prepares it.
    ///
    /// # Errors
    /// Unreadable mesh or sidecar, a sidecar for another vertex count, or a mesh
    /// [`prepare`] cannot analyse.
    pub fn load(mesh_path: &std::path::Path) -> Result<Template, BodyError> {
        let mesh = crate::mesh::io::read_mesh(mesh_path)?;
        let side = sidecar_path(mesh_path);
        let info = if side.exists() {
            TemplateInfo::load(&side, mesh.vertex_count())?
        } else {
            prepare(&mesh)?
        };
        Ok(Template { mesh, info })
    }
}

/// The sidecar path of a mesh: `dir/name.obj` -> `dir/name.template.json`.
pub fn sidecar_path(mesh_path: &std::path::Path) -> PathBuf {
    let stem = mesh_path
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "mesh".into());
    mesh_path.with_file_name(format!("{stem}.template.json"))
}
