//! The mean value deformer: control vertices pulled to targets, the rest of the surface
//! following by mean value decoding (method.md section 3, "Decoding loop"), with the
//! paper's iteration and a fast Gauss-Newton solver behind one interface (see the
//! parent module docs for the fixed point both reach). Metres.

use super::anderson::Anderson;
use super::encoding::MeanValueEncoding;
use super::newton::CoupledSystem;
use super::solver::{
    component_anchor_candidates, components, fixed_with_anchors, Constraints, Engine,
    NormalEquations, ReducedSystem, RowSystem,
};
use super::{
    check_solve_inputs, control_mask, ConvergenceMonitor, DecodeOptions, DecodeReport, DecoderKind,
    DeformError, Linearisation, SymbolicReuse,
};
use crate::mesh::TriMesh;
use glam::DVec3;

/// A decode step that moves a vertex further than this (metres; a body is two metres
/// tall) has diverged: the solve stops with [`DeformError::Diverged`] instead of iterating
/// on towards infinity.
const DIVERGED_MOVE_M: f64 = 5.0;

/// Owns the encoding, the factorisation and the scratch buffers; reused frame after frame.
pub struct MvcDeformer {
    encoding: MeanValueEncoding,
    kind: DecoderKind,
    opts: DecodeOptions,
    controls: Vec<u32>,
    is_control: Vec<bool>,
    component: Vec<u32>,
    anchor_candidates: Vec<Vec<u32>>,
    /// Fixed vertices (controls + anchors of uncontrolled components) and the anchors.
    fixed: Vec<bool>,
    anchors: Vec<u32>,
    /// Fast solver only.
    system: Option<Engine>,
    /// Per-vertex right-hand side (normal offsets), scratch.
    delta: Vec<DVec3>,
    /// Vertices the solve moves (the free ones; all with weighted constraints), for the
    /// acceleration.
    free: Vec<u32>,
    /// The engine has not been factored yet (no control set given so far).
    needs_factor: bool,
    /// Fast solver: the plain step's result, and the acceleration history.
    step_out: Vec<DVec3>,
    anderson: Anderson,
    /// Fast solver, coupled linearisation: the `3F x 3F` Gauss-Newton system of the
    /// current fixed set, and whether it is in use (else the frozen-offset engine).
    coupled: Option<CoupledSystem>,
    coupled_active: bool,
    /// Coupled system: largest `|v - v_mv|` at the start of the last step of the current
    /// solve (NaN when that step did not evaluate it).
    last_step_residual: f64,
    /// Coupled system: chord steps taken so far in the current solve.
    chord_steps: usize,
    /// The scalar engine has been factored for the current fixed set.
    engine_factored: bool,
    /// Rest positions (the first linearisation point) and mean edge length, metres.
    rest: Vec<DVec3>,
    mean_edge_m: f64,
}

impl MvcDeformer {
    /// Encodes `rest` and, for the fast decoder, analyses the sparsity pattern of its
    /// normal equations once (symbolic Cholesky). No control vertices yet.
    ///
    /// # Errors
    /// An empty or invalid mesh, a non-positive constraint weight, a failed analysis.
    pub fn new(
        rest: &TriMesh,
        kind: DecoderKind,
        opts: DecodeOptions,
    ) -> Result<Self, DeformError> {
        if rest.positions.is_empty() {
            return Err(DeformError::EmptyMesh(0));
        }
        rest.validate().map_err(DeformError::InvalidMesh)?;
        if !(opts.constraint_weight > 0.0) {
            return Err(DeformError::BadConstraintWeight(opts.constraint_weight));
        }
        let rings = rest.one_rings();
        let encoding = MeanValueEncoding::encode(rest, &rings);
        Self::from_encoding(rest, encoding, kind, opts)
    }

    /// Like [`Self::new`] with an encoding of `rest` computed beforehand.
    ///
    /// # Errors
    /// As [`Self::new`]; also an encoding of another vertex count.
    pub fn from_encoding(
        rest: &TriMesh,
        encoding: MeanValueEncoding,
        kind: DecoderKind,
        opts: DecodeOptions,
    ) -> Result<Self, DeformError> {
        let n = encoding.vertex_count();
        if rest.vertex_count() != n {
            return Err(DeformError::PositionCount {
                got: rest.vertex_count(),
                expected: n,
            });
        }
        if !(opts.constraint_weight > 0.0) {
            return Err(DeformError::BadConstraintWeight(opts.constraint_weight));
        }
        let component = components(encoding.rings());
        let anchor_candidates = component_anchor_candidates(&component, &rest.positions);
        let system = match kind {
            DecoderKind::FastGaussNewton => {
                let rows = RowSystem::from_rings(encoding.rings(), |v| encoding.weights(v));
                let hard = !opts.constraint_weight.is_finite();
                Some(match opts.symbolic {
                    SymbolicReuse::PerControlSet if hard => {
                        Engine::Reduced(ReducedSystem::new(rows))
                    }
                    _ => Engine::Full(NormalEquations::new(rows)?),
                })
            }
            DecoderKind::PaperIterative => None,
        };
        let mut d = MvcDeformer {
            encoding,
            kind,
            opts,
            controls: Vec::new(),
            is_control: vec![false; n],
            component,
            anchor_candidates,
            fixed: Vec::new(),
            anchors: Vec::new(),
            system,
            delta: vec![DVec3::ZERO; n],
            free: Vec::new(),
            needs_factor: false,
            step_out: vec![
                DVec3::ZERO;
                if kind == DecoderKind::FastGaussNewton {
                    n
                } else {
                    0
                }
            ],
            anderson: Anderson::new(if kind == DecoderKind::FastGaussNewton {
                n
            } else {
                0
            }),
            coupled: None,
            coupled_active: false,
            last_step_residual: f64::NAN,
            chord_steps: 0,
            engine_factored: false,
            rest: rest.positions.clone(),
            mean_edge_m: rest.mean_edge_length(),
        };
        match d.system {
            // Analysed when the first control set arrives (or at the first solve).
            Some(Engine::Reduced(_)) => d.needs_factor = true,
            _ => d.set_controls(&[])?,
        }
        Ok(d)
    }

    /// Sets or replaces the control vertices (indices). For the fast decoder with the
    /// coupled linearisation this analyses and factors the coupled system of the new
    /// fixed set, linearised at the rest shape (nothing is redone for the same set); with
    /// frozen offsets it refactors the scalar system.
    ///
    /// # Errors
    /// An index out of range or listed twice; a failed factorisation.
    pub fn set_controls(&mut self, controls: &[u32]) -> Result<(), DeformError> {
        let mask = control_mask(controls, self.encoding.vertex_count())?;
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
        let soft = self.opts.constraint_weight.is_finite();
        self.free.clear();
        self.free
            .extend((0..self.fixed.len() as u32).filter(|&v| soft || !self.fixed[v as usize]));
        if self.kind == DecoderKind::FastGaussNewton {
            self.anderson.resize(self.free.len());
        }
        let coupled_wanted = self.kind == DecoderKind::FastGaussNewton
            && !soft
            && self.opts.linearisation == Linearisation::Coupled
            && self.fixed.iter().any(|&f| !f);
        self.coupled_active = false;
        self.engine_factored = false;
        if coupled_wanted {
            let reuse = self
                .coupled
                .as_ref()
                .is_some_and(|c| c.is_factored() && c.matches(&self.fixed));
            if reuse {
                self.coupled_active = true;
            } else {
                self.coupled = None;
                // A failed coupled factorisation falls back to the frozen offsets.
                if let Ok(mut c) = CoupledSystem::new(&self.encoding, &self.fixed, self.mean_edge_m)
                {
                    if c.linearise(&self.encoding, &self.rest).is_ok() {
                        self.coupled = Some(c);
                        self.coupled_active = true;
                    }
                }
            }
        }
        if !self.coupled_active {
            self.factor_engine()?;
        }
        self.needs_factor = false;
        Ok(())
    }

    /// Factors the scalar (frozen-offset) engine for the current fixed set.
    fn factor_engine(&mut self) -> Result<(), DeformError> {
        if let Some(sys) = &mut self.system {
            let mode = if self.opts.constraint_weight.is_finite() {
                Constraints::Weighted(self.opts.constraint_weight)
            } else {
                Constraints::Hard
            };
            sys.factor(&self.fixed, mode)?;
        }
        self.engine_factored = true;
        Ok(())
    }

    /// Re-linearises the coupled system at `positions` (controls at their targets, e.g.
    /// the result of the last solve) and refactors it numerically; the next solves take
    /// chord steps from there. A no-op for the other decoders. If the factorisation
    /// fails the deformer falls back to the frozen offsets.
    ///
    /// # Errors
    /// Wrong position count; a failed fallback factorisation.
    pub fn relinearise(&mut self, positions: &[DVec3]) -> Result<(), DeformError> {
        let n = self.encoding.vertex_count();
        if positions.len() != n {
            return Err(DeformError::PositionCount {
                got: positions.len(),
                expected: n,
            });
        }
        if !self.coupled_active {
            return Ok(());
        }
        let ok = match &mut self.coupled {
            Some(c) => c.linearise(&self.encoding, positions).is_ok(),
            None => false,
        };
        if !ok {
            self.coupled = None;
            self.coupled_active = false;
            if !self.engine_factored {
                self.factor_engine()?;
            }
        }
        Ok(())
    }

    /// Solves with `targets` (one per control, same order), starting from `positions`
    /// (warm start) and writing the result into it.
    ///
    /// # Errors
    /// Wrong target or position counts, non-finite targets, a diverging solve.
    pub fn solve(
        &mut self,
        targets: &[DVec3],
        positions: &mut [DVec3],
    ) -> Result<DecodeReport, DeformError> {
        let n = self.encoding.vertex_count();
        check_solve_inputs(targets, self.controls.len(), positions.len(), n)?;
        if self.needs_factor {
            self.set_controls(&[])?;
        }
        let mut monitor = ConvergenceMonitor::new(self.opts.max_move_m);
        let mut report = DecodeReport::default();
        // A fresh history per solve: differences carried over from the previous targets
        // saved a few steps on the body with rigid extremities but tripled the refit
        // with free ones (measured), so they are not kept.
        self.anderson.reset();
        self.last_step_residual = f64::NAN;
        self.chord_steps = 0;
        let mut first = 0;
        if self.coupled_active && self.opts.max_iterations > 0 {
            // Predictor: the linear response of the current surface to the control moves
            // (see `CoupledSystem::step`), applied in place, then chord steps.
            if let Some(c) = &mut self.coupled {
                self.delta.iter_mut().for_each(|d| *d = DVec3::ZERO);
                for (&v, t) in self.controls.iter().zip(targets) {
                    self.delta[v as usize] = *t - positions[v as usize];
                }
                self.last_step_residual =
                    c.solve_step(&self.encoding, positions, Some(&self.delta));
                let moved = c.apply_step(positions);
                for (&v, t) in self.controls.iter().zip(targets) {
                    positions[v as usize] = *t;
                }
                report.iterations = 1;
                report.max_move_m = moved;
                if !(moved <= DIVERGED_MOVE_M) {
                    return Err(DeformError::Diverged(1));
                }
                report.converged = monitor.update(moved);
                first = 1;
            }
        }
        // Control vertices jump to their targets (both decoders start there).
        for (&c, t) in self.controls.iter().zip(targets) {
            positions[c as usize] = *t;
        }
        for it in first..self.opts.max_iterations {
            if report.converged {
                break;
            }
            let max_move = match self.kind {
                DecoderKind::PaperIterative => self.paper_sweep(positions),
                DecoderKind::FastGaussNewton => self.gauss_newton_step(targets, positions),
            };
            report.iterations = it + 1;
            report.max_move_m = max_move;
            if !(max_move <= DIVERGED_MOVE_M) {
                return Err(DeformError::Diverged(it + 1));
            }
            if monitor.update(max_move) {
                report.converged = true;
                break;
            }
        }
        if self.coupled_active && report.iterations > self.opts.relinearise_after {
            self.relinearise(positions)?;
            report.relinearised = self.coupled_active;
        }
        report.residual_m = match (&mut self.coupled, self.coupled_active) {
            // A converged coupled solve reports the residual its last step started from
            // instead of paying another pass over the mesh for the one at its end (the
            // last step moved no vertex more than the tolerance); the next solve's
            // predictor then starts without a residual pass.
            (Some(c), true)
                if report.converged
                    && !report.relinearised
                    && self.last_step_residual.is_finite() =>
            {
                c.mark_converged(positions);
                self.last_step_residual
            }
            (Some(c), true) => c.residual_at(&self.encoding, positions),
            _ => self.residual(positions),
        };
        report.constraint_residual_m = self
            .controls
            .iter()
            .zip(targets)
            .map(|(&c, t)| (positions[c as usize] - *t).length())
            .fold(0.0, f64::max);
        Ok(report)
    }

    /// One sweep of the paper's loop: every free vertex takes its decoded position from
    /// its neighbours, in place (method.md section 3). Returns the largest move.
    fn paper_sweep(&mut self, positions: &mut [DVec3]) -> f64 {
        let mut max_move = 0.0f64;
        for v in 0..positions.len() {
            if self.fixed[v] {
                continue;
            }
            let new = self.encoding.decode_vertex(v, positions);
            let mv = (new - positions[v]).length_squared();
            if !(mv <= max_move) {
                max_move = mv;
            }
            positions[v] = new;
        }
        max_move.sqrt()
    }

    /// One Gauss-Newton step with frozen weights: normal offsets from the current
    /// positions, then the factored least-squares solve (Kazmi et al. 2015, section 3.5.2;
    /// method.md section 3), mixed with the previous steps by Anderson acceleration.
    /// Returns the larger of the move and the plain step's length.
    fn gauss_newton_step(&mut self, targets: &[DVec3], positions: &mut [DVec3]) -> f64 {
        if self.coupled_active {
            if let Some(c) = &mut self.coupled {
                self.last_step_residual = c.solve_step(&self.encoding, positions, None);
                self.chord_steps += 1;
                if self.chord_steps == 1 {
                    // Nothing to mix yet, and usually the last step (a refit converges
                    // with the predictor and one chord step): applied in place, without
                    // handing a copy of the mesh to the acceleration. The mixing starts
                    // with the second chord step.
                    return c.apply_step(positions);
                }
                self.step_out.copy_from_slice(positions);
                let plain = c.apply_step(&mut self.step_out);
                if !plain.is_finite() {
                    return plain;
                }
                let (moved, fixed_point_residual) =
                    self.anderson.step(positions, &self.step_out, &self.free);
                return moved.max(fixed_point_residual);
            }
        }
        for v in 0..positions.len() {
            self.delta[v] = if self.fixed[v] {
                DVec3::ZERO
            } else {
                self.encoding.decode_parts(v, positions).normal_offset
            };
        }
        let Some(sys) = &mut self.system else {
            return f64::NAN;
        };
        if sys.is_soft() {
            // Weighted constraints read their targets from the positions.
            for (&c, t) in self.controls.iter().zip(targets) {
                positions[c as usize] = *t;
            }
        }
        self.step_out.copy_from_slice(positions);
        let plain = sys.solve(&self.delta, &mut self.step_out);
        if !plain.is_finite() {
            return plain;
        }
        let (moved, fixed_point_residual) =
            self.anderson.step(positions, &self.step_out, &self.free);
        moved.max(fixed_point_residual)
    }

    /// Largest `|v - v_mv|` over free vertices, metres.
    pub fn residual(&self, positions: &[DVec3]) -> f64 {
        let mut r = 0.0f64;
        for v in 0..positions.len() {
            if !self.fixed[v] {
                r = r.max((self.encoding.decode_vertex(v, positions) - positions[v]).length());
            }
        }
        r
    }

    /// Bench only: times of the two halves of a coupled chord step at `positions`, one
    /// residual pass (all free vertices decoded) and one solve of the factored system,
    /// milliseconds, medians of `repeats`, and the blocks the solve reads and the factor
    /// holds (zero without the block LU); None without the coupled system.
    pub(crate) fn step_part_times(
        &mut self,
        positions: &[DVec3],
        repeats: usize,
    ) -> Option<(f64, f64, usize, usize)> {
        let c = self.coupled.as_mut().filter(|_| self.coupled_active)?;
        let mut residual = Vec::with_capacity(repeats);
        let mut solve = Vec::with_capacity(repeats);
        for _ in 0..repeats.max(1) {
            let t = std::time::Instant::now();
            std::hint::black_box(c.residual_at(&self.encoding, positions));
            residual.push(t.elapsed().as_secs_f64() * 1e3);
            let t = std::time::Instant::now();
            c.solve_cached_residual();
            solve.push(t.elapsed().as_secs_f64() * 1e3);
        }
        let median = |mut v: Vec<f64>| {
            v.sort_by(f64::total_cmp);
            v[v.len() / 2]
        };
        let (read, held) = c.lu_block_counts().unwrap_or((0, 0));
        Some((median(residual), median(solve), read, held))
    }

    /// Forgets the fast decoder's acceleration history (each solve starts afresh anyway;
    /// kept for callers that interleave their own steps).
    pub fn reset_history(&mut self) {
        self.anderson.reset();
    }

    /// The encoding of the rest mesh.
    pub fn encoding(&self) -> &MeanValueEncoding {
        &self.encoding
    }

    /// The decoder this deformer runs.
    pub fn kind(&self) -> DecoderKind {
        self.kind
    }

    /// The current control vertices.
    pub fn controls(&self) -> &[u32] {
        &self.controls
    }

    /// Vertices pinned at their current position because their connected part of the
    /// mesh has no control vertex.
    pub fn anchors(&self) -> &[u32] {
        &self.anchors
    }

    /// Heap bytes held by the deformer (encoding, pattern, factor, scratch): the engine
    /// memory.
    pub fn heap_bytes(&self) -> usize {
        self.encoding.heap_bytes()
            + self.system.as_ref().map_or(0, |s| s.heap_bytes())
            + self.coupled.as_ref().map_or(0, |c| c.heap_bytes())
            + self.rest.len() * 24
            + self.delta.len() * 24
            + self.fixed.len() * 6
            + self.step_out.len() * 24
            + self.anderson.heap_bytes()
    }

    /// Number of stored values of the Cholesky factor (0 for the paper-style decoder).
    pub fn factor_len(&self) -> usize {
        match (&self.coupled, self.coupled_active) {
            (Some(c), true) => c.factor_len(),
            _ => self.system.as_ref().map_or(0, |s| s.factor_len()),
        }
    }

    /// Whether the fast decoder runs the coupled Gauss-Newton system (false: frozen
    /// offsets, by option or after a failed coupled factorisation).
    pub fn uses_coupled_system(&self) -> bool {
        self.coupled_active
    }
}
