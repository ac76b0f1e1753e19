//! Template deformation: mean value encoding and decoding (Zhong, method.md sections 2
//! and 3; Kraevoy and Sheffer's mean value encoding), Laplacian mesh editing as the
//! alternative deformer, and linear blend skinning on a template skeleton for large pose
//! differences before the fine fit (Kazmi et al. 2015, section 3.5).
//!
//! # Conventions
//! - Positions are `DVec3` in metres, in whatever frame the mesh lives in (the station
//!   frame for fitted templates: +Y up, +Z toward the front camera, +X the subject's
//!   left). Nothing here depends on the axes except the benchmark's slicing in y.
//! - Rings come from [`crate::mesh::OneRings`] (counter-clockwise seen from outside).
//! - Control vertices are mesh vertex indices; targets are given one per control, in the
//!   same order.
//!
//! # The two decoders and their common fixed point
//! A free vertex `v` is at rest when it equals its mean value decoding `v_mv` from its
//! current neighbours (method.md section 2). Writing `v_mv = sum_i w_i v_i + s n` (the
//! projections cancel because the weights sum to one), the decoding is an affine
//! combination of the neighbours plus a normal offset `s n` that turns and scales with the
//! ring. Both decoders look for positions where every free vertex equals its decoding
//! and every control vertex equals its target (hard constraints: control vertices are
//! eliminated from the unknowns):
//! - [`DecoderKind::PaperIterative`]: the paper's loop: control vertices jump to their
//!   targets, free vertices take `v_mv` from their neighbours (in place, Gauss-Seidel
//!   order), repeated.
//! - [`DecoderKind::FastGaussNewton`], by default with [`Linearisation::Coupled`]:
//!   Gauss-Newton on `F(x) = x - v_mv(x) = 0` over the free vertices with the full
//!   Jacobian, in which every normal offset `s n` turns and stretches with its ring (x, y
//!   and z coupled: a `3F x 3F` system for `F` free vertices, `newton.rs`). The Jacobian
//!   comes from forward differences of the decoding (each `v_mv` reads one ring); the
//!   square `J` is factored once per control set with a block LU on its one-ring
//!   pattern (`blocklu.rs`; faer's Cholesky of the normal equations as the fallback),
//!   linearised at the rest shape, and reused as chord steps frame after
//!   frame; a solve that needs more than `DecodeOptions::relinearise_after` steps (or a
//!   caller, [`MvcDeformer::relinearise`]) refactors it at the current shape. The first
//!   step of every solve is a predictor: the linear response of the current surface to
//!   the control moves (`F` taken to first order in the moved controls), instead of a
//!   step from a surface whose controls were torn away from their neighbours. Measured on
//!   the MakeHuman body (`fitstation bench deform`): two steps from rest (targets moved
//!   up to 24 mm) and two for a refit after 3 mm moves, where the frozen offsets needed
//!   12 and 15.
//! - The same decoder with [`Linearisation::FrozenOffsets`] (and always with weighted
//!   constraints): weights frozen, the normal offsets `s n` taken from the current
//!   positions, the sparse least-squares system `min |L x - s n|^2` (rows of the free
//!   vertices, `L = I - W`) solved with a Cholesky factor of `L^T L`, one scalar factor
//!   for x, y and z. Two ways to share its sparse analysis ([`SymbolicReuse`]):
//!   eliminate the control vertices (smaller factor, analysis per control set, the
//!   default: a template's control set stays while the targets move), or keep one
//!   analysis of the full-size pattern for every control set (controls become identity
//!   rows, their coupling moves to the right-hand side; `set_controls` is a numeric
//!   refactor only).
//!
//! Why Anderson acceleration (frozen offsets): the step `x -> G(x)` ignores how the
//! offsets turn and stretch with the surface. Where a thin part is held on one side
//! only (fingers, or a limb pinned along one line) that feedback has a gain above one
//! and the plain iteration diverges (measured on the MakeHuman body: moves growing 2.5x
//! per step at the fingers). The paper's local sweeps stay stable but need hundreds to
//! tens of thousands of sweeps. The frozen-offset decoder therefore mixes its last steps
//! (Anderson acceleration, `anderson.rs`); that converges in 12-15 steps on the body when
//! hands, feet and head are held (method.md: they move rigidly) and in 45-70 when they
//! are free (the fingers dominate). The coupled system sees that feedback in its
//! Jacobian; its chord steps from the second on are mixed the same way (nothing to mix
//! when a solve converges with the predictor and one chord step, the usual refit).
//! Cost of the coupled system: its block LU holds 1.66 M values on the body (the normal
//! equations' Cholesky factor 2.9 M, the scalar one 0.27 M); a solve with it (f32
//! values, row-oriented) takes 0.5 to 1.3 ms and a residual pass 0.55 to 0.7 ms on the
//! 2-core machine, depending on what else runs (`fitstation bench deform`, "fast step
//! parts", at load 2.5 to 5). A warm refit is therefore budgeted as a predictor solve, one
//! residual pass and one chord solve: the predictor from the result of a converged solve
//! takes the residual there as zero (it was certified by that solve's last step), and a
//! converged solve does not evaluate the residual again at its end (`newton.rs`,
//! `CachedResidual`). The convergence test is unchanged: it reads the chord step's
//! move, computed from a residual evaluated in `f64` at the predicted surface.
//!
//! Both decoders use hard constraints by default (control vertices eliminated), so they
//! share the exact fixed point. With a finite `DecodeOptions::constraint_weight` the fast
//! solver uses weighted (soft) constraints instead; its fixed point then differs from the
//! hard one by O(1/weight). A connected part of the mesh without any control vertex is
//! held by up to four anchor vertices at their current positions (they fix its affine
//! motion, which the frozen-offset system cannot see); `MvcDeformer::anchors` lists them.
//!
//! Conditioning: the fixed point is soft along the same thin-part modes. On the body a
//! largest residual `|v - v_mv|` of a few micrometres still leaves positions uncertain
//! by up to about 0.4 mm there, so two decoders stopped at 0.1 mm can differ by about
//! that much; the tests compare them at a tighter tolerance.
//!
//! # Convergence
//! The paper stops at `sum |v - v_mv| / sum |v| < 1%`, which on a body a metre from the
//! origin still allows centimetres. Here a decoder stops when no vertex moved more than
//! `max_move_m` in the last iteration AND the distance still to go, estimated from the
//! observed contraction rate `r` of the moves as `move * r / (1 - r)`, is below
//! `max_move_m` too. The second half matters for the paper-style loop, which contracts
//! slowly: per-sweep moves become tiny long before the surface has arrived.

mod anderson;
mod blocklu;
mod encoding;
mod laplacian;
pub(crate) use laplacian::cotangent;
mod mvc;
mod newton;
mod skinning;
mod solver;

pub mod bench;

pub use encoding::{MeanValueEncoding, RingEncodingKind};
pub use laplacian::LaplacianDeformer;
pub use mvc::MvcDeformer;
pub use skinning::{
    linear_blend, pose_bone_transforms, skin_weights, Joint, Skeleton, SkeletonError, SkinWeights,
    MAX_INFLUENCES,
};

/// Which decoder an [`MvcDeformer`] runs.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DecoderKind {
    /// The paper's iteration (method.md section 3, "Decoding loop"); the reference.
    PaperIterative,
    /// Frozen-weight Gauss-Newton with one sparse Cholesky factor per control set.
    FastGaussNewton,
}

/// Options of a decode.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DecodeOptions {
    /// Convergence: largest vertex move of an iteration, and largest estimated distance
    /// still to go, metres. Default 1e-4 (0.1 mm).
    pub max_move_m: f64,
    /// Iteration cap (sweeps for the paper-style loop, Gauss-Newton steps for the fast one).
    pub max_iterations: usize,
    /// Weight of the control terms relative to the unit-weight mean value rows of the fast
    /// solver. `f64::INFINITY` (the default) means hard constraints: control vertices
    /// are eliminated from the unknowns, like the paper-style loop does. The paper-style
    /// loop always uses hard constraints.
    pub constraint_weight: f64,
    /// How the fast decoder's sparse analysis is shared (see [`SymbolicReuse`]).
    pub symbolic: SymbolicReuse,
    /// How the fast decoder linearises the normal offsets (see [`Linearisation`]).
    pub linearisation: Linearisation,
    /// Coupled linearisation only: a solve that needs more steps than this re-linearises
    /// at its result (a numeric refactor; the analysis is kept), so the next frames start
    /// from an up-to-date model. `usize::MAX` never does. Default
    /// [`DEFAULT_RELINEARISE_AFTER`].
    pub relinearise_after: usize,
}

/// How the fast decoder models the normal offsets `s n` of the decoding.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Linearisation {
    /// Gauss-Newton on the coupled system: the Jacobian includes how each offset turns and
    /// stretches with its ring (x, y, z coupled, one `3F x 3F` factor for `F` free
    /// vertices), linearised at the rest shape when the control set is given and reused
    /// (chord steps) until a solve needs more than `relinearise_after` steps. Hard
    /// constraints only (with weighted ones the frozen offsets are used). The default.
    #[default]
    Coupled,
    /// Offsets frozen at the current positions, one scalar factor for x, y and z, steps
    /// mixed by Anderson acceleration.
    FrozenOffsets,
}

/// Sharing of the frozen-offset engine's symbolic Cholesky analysis (the coupled system
/// is always analysed per control set).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum SymbolicReuse {
    /// Control vertices are eliminated from the unknowns: a smaller factor and faster
    /// solves; the analysis is redone only when the control set changes (it does not
    /// from frame to frame: only the targets move). The default.
    #[default]
    PerControlSet,
    /// One analysis of the full-size system per mesh, kept for every control set
    /// (controls become identity rows): `set_controls` is a numeric refactor only, each
    /// solve pays for the full-size factor. Always used with weighted constraints.
    AcrossControlSets,
}

/// Default convergence tolerance, metres (0.1 mm).
pub const DEFAULT_MAX_MOVE_M: f64 = 1e-4;
/// Default iteration cap.
pub const DEFAULT_MAX_ITERATIONS: usize = 50;
/// Default of [`DecodeOptions::relinearise_after`]: a predictor and a chord step suffice
/// while the linearisation is a few centimetres from the shape (measured on the body), so
/// a solve of more than this many steps means the shape has drifted from it.
pub const DEFAULT_RELINEARISE_AFTER: usize = 3;

impl Default for DecodeOptions {
    fn default() -> Self {
        DecodeOptions {
            max_move_m: DEFAULT_MAX_MOVE_M,
            max_iterations: DEFAULT_MAX_ITERATIONS,
            constraint_weight: f64::INFINITY,
            symbolic: SymbolicReuse::default(),
            linearisation: Linearisation::default(),
            relinearise_after: DEFAULT_RELINEARISE_AFTER,
        }
    }
}

/// What a decode did.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct DecodeReport {
    /// Iterations run (sweeps or Gauss-Newton steps; each one linear solve for the fast
    /// decoder).
    pub iterations: usize,
    /// Largest vertex move of the last iteration, metres.
    pub max_move_m: f64,
    /// Largest `|v - v_mv|` over free vertices, metres: at the end, except after a
    /// converged solve of the coupled fast decoder, where it is the value its last step
    /// started from (that step moved no vertex more than the tolerance; evaluating the
    /// residual again at the end would cost another pass over the mesh per frame). For
    /// the Laplacian deformer: largest Laplacian-coordinate residual.
    pub residual_m: f64,
    /// Largest `|v - target|` over control vertices at the end, metres.
    pub constraint_residual_m: f64,
    /// Whether the convergence test passed before the iteration cap.
    pub converged: bool,
    /// Whether the fast decoder re-linearised its coupled system at the end of this solve.
    pub relinearised: bool,
}

/// Errors of the deformers.
#[derive(Debug, thiserror::Error)]
pub enum DeformError {
    #[error("mesh has {0} vertices: nothing to deform")]
    EmptyMesh(usize),
    #[error("invalid mesh: {0}")]
    InvalidMesh(String),
    #[error("control vertex {index} is out of range (mesh has {vertex_count} vertices)")]
    ControlOutOfRange { index: u32, vertex_count: usize },
    #[error("control vertex {0} is listed twice")]
    DuplicateControl(u32),
    #[error("{targets} targets for {controls} control vertices")]
    TargetCount { targets: usize, controls: usize },
    #[error("positions hold {got} vertices, the mesh has {expected}")]
    PositionCount { got: usize, expected: usize },
    #[error("target {0} is not finite")]
    NonFiniteTarget(usize),
    #[error("constraint weight must be positive (or infinite for hard constraints), got {0}")]
    BadConstraintWeight(f64),
    #[error("sparse factorisation failed: {0}")]
    Factorisation(String),
    #[error("the solution became non-finite at iteration {0}")]
    Diverged(usize),
}

/// Convergence test shared by the decoders (see the module docs).
#[derive(Debug, Clone)]
pub(crate) struct ConvergenceMonitor {
    tol_m: f64,
    history: [f64; RATE_WINDOW + 1],
    count: usize,
}

/// Number of past iterations the contraction rate is averaged over.
const RATE_WINDOW: usize = 8;

impl ConvergenceMonitor {
    pub(crate) fn new(tol_m: f64) -> Self {
        ConvergenceMonitor {
            tol_m,
            history: [0.0; RATE_WINDOW + 1],
            count: 0,
        }
    }

    /// Records the largest move of one iteration; returns whether the decode has converged.
    pub(crate) fn update(&mut self, max_move_m: f64) -> bool {
        let slot = self.count % (RATE_WINDOW + 1);
        self.history[slot] = max_move_m;
        self.count += 1;
        if !(max_move_m <= self.tol_m) {
            return false;
        }
        if max_move_m == 0.0 {
            return true;
        }
        let span = (self.count - 1).min(RATE_WINDOW);
        if span == 0 {
            return false;
        }
        let old = self.history[(self.count - 1 - span) % (RATE_WINDOW + 1)];
        if old <= 0.0 {
            return true;
        }
        let rate = (max_move_m / old).powf(1.0 / span as f64);
        if rate >= 1.0 {
            return false;
        }
        max_move_m * rate / (1.0 - rate) <= self.tol_m
    }
}

/// Checks a control list against a vertex count; returns the control mask.
pub(crate) fn control_mask(
    controls: &[u32],
    vertex_count: usize,
) -> Result<Vec<bool>, DeformError> {
    let mut mask = vec![false; vertex_count];
    for &c in controls {
        let slot = mask
            .get_mut(c as usize)
            .ok_or(DeformError::ControlOutOfRange {
                index: c,
                vertex_count,
            })?;
        if *slot {
            return Err(DeformError::DuplicateControl(c));
        }
        *slot = true;
    }
    Ok(mask)
}

/// Checks the inputs of a `solve` call.
pub(crate) fn check_solve_inputs(
    targets: &[glam::DVec3],
    controls: usize,
    positions: usize,
    vertex_count: usize,
) -> Result<(), DeformError> {
    if targets.len() != controls {
        return Err(DeformError::TargetCount {
            targets: targets.len(),
            controls,
        });
    }
    if positions != vertex_count {
        return Err(DeformError::PositionCount {
            got: positions,
            expected: vertex_count,
        });
    }
    if let Some(i) = targets.iter().position(|t| !t.is_finite()) {
        return Err(DeformError::NonFiniteTarget(i));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn monitor_needs_small_moves_and_fast_contraction() {
        // A geometric sequence with rate 0.5 from 1 cm: converges once the tail is small.
        let mut m = ConvergenceMonitor::new(1e-4);
        let mut mv = 1e-2;
        let mut k = 0;
        while !m.update(mv) {
            mv *= 0.5;
            k += 1;
            assert!(k < 100);
        }
        // The tail sum mv * 0.5 / 0.5 = mv must be under the tolerance.
        assert!(mv <= 1e-4);
        // A slowly contracting sequence (rate 0.999) must not stop at the first small move.
        let mut m = ConvergenceMonitor::new(1e-4);
        let mut mv = 5e-5;
        for _ in 0..20 {
            assert!(!m.update(mv));
            mv *= 0.999;
        }
    }

    #[test]
    fn control_mask_rejects_bad_lists() {
        assert!(control_mask(&[0, 2], 3).is_ok());
        assert!(matches!(
            control_mask(&[3], 3),
            Err(DeformError::ControlOutOfRange { .. })
        ));
        assert!(matches!(
            control_mask(&[1, 1], 3),
            Err(DeformError::DuplicateControl(1))
        ));
    }
}
