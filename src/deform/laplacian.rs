//! Laplacian mesh editing, the alternative deformer (Kazmi et al. 2015, section 3.5.3;
//! Sorkine et al.'s Laplacian surface editing without the rotation fit): each free vertex
//! keeps its rest Laplacian coordinate `delta_v = v - sum_i w_i v_i` with row-normalised
//! cotangent weights (negative cotangents clamped), control vertices go to their targets.
//! One linear solve per frame with the same factored normal equations as the fast mean
//! value decoder. The coordinates are not rotated, so large rotations flatten detail: use
//! it after skinning has matched the pose, for the small remaining corrections. Metres.

use super::solver::{
    component_anchor_candidates, components, fixed_with_anchors, Constraints, Engine,
    NormalEquations, ReducedSystem, RowSystem,
};
use super::{
    check_solve_inputs, control_mask, DecodeOptions, DecodeReport, DeformError, SymbolicReuse,
};
use crate::mesh::{OneRings, TriMesh};
use glam::DVec3;

/// Smallest cotangent kept (obtuse angles give negative ones, which break positivity).
const MIN_COTANGENT: f64 = 1e-3;

/// Laplacian deformer; same `new` / `set_controls` / `solve` shape as [`super::MvcDeformer`].
pub struct LaplacianDeformer {
    opts: DecodeOptions,
    rest_delta: Vec<DVec3>,
    controls: Vec<u32>,
    is_control: Vec<bool>,
    component: Vec<u32>,
    anchor_candidates: Vec<Vec<u32>>,
    fixed: Vec<bool>,
    anchors: Vec<u32>,
    /// The linear engine, chosen as the fast mean value decoder chooses it: with hard
    /// constraints and per-control-set analysis, the system of the free vertices only
    /// (the fit fixes most of the trunk, so it is small).
    system: Engine,
    /// The cotangent rows (for the residual of a solve).
    rows: RowSystem,
    /// The engine is factored for the current controls.
    factored: bool,
    delta: Vec<DVec3>,
}

/// Cotangent of the angle at `a` in triangle (a, b, c); 0 for a degenerate one.
pub(crate) fn cotangent(a: DVec3, b: DVec3, c: DVec3) -> f64 {
    let (u, w) = (b - a, c - a);
    let s = u.cross(w).length();
    if s > 0.0 {
        u.dot(w) / s
    } else {
        0.0
    }
}

/// Row-normalised, clamped cotangent weights of every ring, in ring order.
fn cotangent_weights(mesh: &TriMesh, rings: &OneRings) -> Vec<f64> {
    let mut out = vec![0.0; rings.entry_count()];
    for v in 0..rings.vertex_count() {
        let nb = rings.neighbours(v);
        let m = nb.len();
        if m == 0 {
            continue;
        }
        let closed = !rings.is_boundary(v);
        let p = mesh.positions[v];
        let at = |k: usize| mesh.positions[nb[k] as usize];
        let off = rings.offset(v);
        let mut sum = 0.0;
        for k in 0..m {
            let mut c = 0.0;
            if closed || k > 0 {
                let prev = (k + m - 1) % m;
                c += cotangent(at(prev), p, at(k));
            }
            if closed || k + 1 < m {
                let next = (k + 1) % m;
                c += cotangent(at(next), p, at(k));
            }
            let c = (0.5 * c).max(MIN_COTANGENT);
            out[off + k] = c;
            sum += c;
        }
        for w in &mut out[off..off + m] {
            *w /= sum;
        }
    }
    out
}

impl LaplacianDeformer {
    /// Builds the cotangent rows of `rest` and analyses the normal equations once.
    ///
    /// # Errors
    /// An empty or invalid mesh, a non-positive constraint weight, a failed analysis.
    pub fn new(rest: &TriMesh, opts: DecodeOptions) -> Result<Self, DeformError> {
        if rest.positions.is_empty() {
            return Err(DeformError::EmptyMesh(0));
        }
        rest.validate().map_err(DeformError::InvalidMesh)?;
        if !(opts.constraint_weight > 0.0) {
            return Err(DeformError::BadConstraintWeight(opts.constraint_weight));
        }
        let rings = rest.one_rings();
        let weights = cotangent_weights(rest, &rings);
        let rows = RowSystem::from_rings(&rings, |v| {
            let off = rings.offset(v);
            &weights[off..off + rings.neighbours(v).len()]
        });
        let n = rest.vertex_count();
        let mut rest_delta = vec![DVec3::ZERO; n];
        for (v, d) in rest_delta.iter_mut().enumerate() {
            let (cols, coefs) = rows.row(v);
            *d = cols
                .iter()
                .zip(coefs)
                .map(|(&c, &k)| k * rest.positions[c as usize])
                .sum();
        }
        let hard = !opts.constraint_weight.is_finite();
        let system = match opts.symbolic {
            SymbolicReuse::PerControlSet if hard => {
                Engine::Reduced(ReducedSystem::new(rows.clone()))
            }
            _ => Engine::Full(NormalEquations::new(rows.clone())?),
        };
        let component = components(&rings);
        let anchor_candidates = component_anchor_candidates(&component, &rest.positions);
        let mut d = LaplacianDeformer {
            opts,
            rest_delta,
            controls: Vec::new(),
            is_control: vec![false; n],
            component,
            anchor_candidates,
            fixed: Vec::new(),
            anchors: Vec::new(),
            system,
            rows,
            factored: false,
            delta: vec![DVec3::ZERO; n],
        };
        // No controls yet: the anchors only; factored when first solved (a reduced
        // engine's analysis of the whole mesh would be wasted on the caller's controls).
        d.fix_controls(&[])?;
        Ok(d)
    }

    /// Sets or replaces the control vertices; refactors numerically, keeps the symbolic
    /// analysis.
    ///
    /// # Errors
    /// An index out of range or listed twice; a failed factorisation.
    pub fn set_controls(&mut self, controls: &[u32]) -> Result<(), DeformError> {
        self.fix_controls(controls)?;
        self.factor()
    }

    /// Takes the controls and the anchors of uncontrolled parts, unfactored.
    fn fix_controls(&mut self, controls: &[u32]) -> Result<(), DeformError> {
        let mask = control_mask(controls, self.rest_delta.len())?;
        self.controls.clear();
        self.controls.extend_from_slice(controls);
        self.is_control = mask;
        fixed_with_anchors(
            &self.is_control,
            &self.component,
            &self.anchor_candidates,
            &mut self.fixed,
            &mut self.anchors,
        );
        self.factored = false;
        Ok(())
    }

    /// Factors the engine for the current fixed vertices.
    fn factor(&mut self) -> Result<(), DeformError> {
        let mode = if self.opts.constraint_weight.is_finite() {
            Constraints::Weighted(self.opts.constraint_weight)
        } else {
            Constraints::Hard
        };
        self.system.factor(&self.fixed, mode)?;
        self.factored = true;
        Ok(())
    }

    /// Solves with `targets` (one per control), writing into `positions` (whose values
    /// are only read for anchors of uncontrolled parts). One linear solve.
    ///
    /// # Errors
    /// Wrong target or position counts, non-finite targets, a non-finite result.
    pub fn solve(
        &mut self,
        targets: &[DVec3],
        positions: &mut [DVec3],
    ) -> Result<DecodeReport, DeformError> {
        let n = self.rest_delta.len();
        check_solve_inputs(targets, self.controls.len(), positions.len(), n)?;
        if !self.factored {
            self.factor()?;
        }
        for (&c, t) in self.controls.iter().zip(targets) {
            positions[c as usize] = *t;
        }
        for v in 0..n {
            self.delta[v] = if self.fixed[v] {
                DVec3::ZERO
            } else {
                self.rest_delta[v]
            };
        }
        let max_move = self.system.solve(&self.delta, positions);
        if !max_move.is_finite() {
            return Err(DeformError::Diverged(1));
        }
        let rows = &self.rows;
        let mut residual = 0.0f64;
        for v in 0..n {
            if self.fixed[v] {
                continue;
            }
            let (cols, coefs) = rows.row(v);
            let lx: DVec3 = cols
                .iter()
                .zip(coefs)
                .map(|(&c, &k)| k * positions[c as usize])
                .sum();
            residual = residual.max((lx - self.rest_delta[v]).length());
        }
        let constraint_residual_m = self
            .controls
            .iter()
            .zip(targets)
            .map(|(&c, t)| (positions[c as usize] - *t).length())
            .fold(0.0, f64::max);
        Ok(DecodeReport {
            iterations: 1,
            max_move_m: max_move,
            residual_m: residual,
            constraint_residual_m,
            converged: true,
            relinearised: false,
        })
    }

    /// The current control vertices.
    pub fn controls(&self) -> &[u32] {
        &self.controls
    }
}
