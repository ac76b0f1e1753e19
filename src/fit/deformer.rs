//! The fit's deformer: the mean value deformer (method.md section 2, the default) or
//! Laplacian editing (Kazmi et al. 2015, section 3.5.3), behind one `new` /
//! `set_controls` / `solve`. Both take the same controls (correspondence, dense section
//! targets, the rigid parts' vertices) in the same order; only how the free vertices
//! follow differs: mean value encodings keep each vertex's offset from its one-ring's
//! plane (rotation and scale invariant, a Gauss-Newton solve), Laplacian coordinates keep
//! its offset from the one-ring's cotangent mean (one linear solve, not rotated).
//!
//! Units: metres, station frame.

use crate::deform::{
    DecodeOptions, DecodeReport, DecoderKind, DeformError, LaplacianDeformer, MvcDeformer,
};
use crate::mesh::TriMesh;
use glam::DVec3;

/// Which deformer moves the avatar to its targets (`--deformer`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, clap::ValueEnum, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum DeformerKind {
    /// Mean value encoding and decoding (Zhong; Kraevoy and Sheffer).
    #[default]
    Mvc,
    /// Laplacian editing with cotangent weights (Kazmi et al.; Sorkine et al.).
    Laplacian,
}

impl DeformerKind {
    pub fn name(self) -> &'static str {
        match self {
            DeformerKind::Mvc => "mvc",
            DeformerKind::Laplacian => "laplacian",
        }
    }
}

/// A built deformer of the chosen kind on one rest (candidate) mesh.
pub enum FitDeformer {
    Mvc(Box<MvcDeformer>),
    Laplacian(Box<LaplacianDeformer>),
}

impl FitDeformer {
    /// Encodes `rest` for the chosen deformer (`decoder`: the mean value decoder).
    ///
    /// # Errors
    /// An invalid mesh or a failed analysis of the normal equations.
    pub fn new(
        kind: DeformerKind,
        rest: &TriMesh,
        decoder: DecoderKind,
        opts: DecodeOptions,
    ) -> Result<Self, DeformError> {
        Ok(match kind {
            DeformerKind::Mvc => FitDeformer::Mvc(Box::new(MvcDeformer::new(rest, decoder, opts)?)),
            DeformerKind::Laplacian => {
                FitDeformer::Laplacian(Box::new(LaplacianDeformer::new(rest, opts)?))
            }
        })
    }

    /// Sets the control vertices (targets of [`FitDeformer::solve`] come in this order).
    ///
    /// # Errors
    /// An index out of range or listed twice; a failed factorisation.
    pub fn set_controls(&mut self, controls: &[u32]) -> Result<(), DeformError> {
        match self {
            FitDeformer::Mvc(d) => d.set_controls(controls),
            FitDeformer::Laplacian(d) => d.set_controls(controls),
        }
    }

    /// Moves the controls to `targets` and the free vertices after them, in `positions`
    /// (the warm start of the mean value decoder; the Laplacian solve reads it only for
    /// anchors of uncontrolled parts).
    ///
    /// # Errors
    /// Wrong counts, non-finite targets, a diverging solve.
    pub fn solve(
        &mut self,
        targets: &[DVec3],
        positions: &mut [DVec3],
    ) -> Result<DecodeReport, DeformError> {
        match self {
            FitDeformer::Mvc(d) => d.solve(targets, positions),
            FitDeformer::Laplacian(d) => d.solve(targets, positions),
        }
    }
}
