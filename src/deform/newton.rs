//! Coupled Gauss-Newton engine of the fast mean value decoder: the free vertices solve
//! `F(x) = 0` with `F_v(x) = x_v - v_mv(x)` (method.md section 2 decoding, section 3
//! fitting; Kazmi et al. 2015 section 3.5.2 solve the same least squares with
//! Gauss-Newton). Unlike the frozen-offset step, the Jacobian here includes how the normal
//! offset `s n` of every vertex turns and stretches with its neighbours, so x, y and z
//! are coupled: `J` is `3F x 3F` for `F` free vertices, with one `3 x 3` block per
//! (vertex, free ring member) pair.
//!
//! `J` is built by forward differences of the decoding (each `v_mv` reads only its own
//! one-ring, so a block costs three local decodes). `J` is square (hard constraints: as
//! many equations as free unknowns), so a Newton step is `J d = -F`: `J` is factored once
//! with a block LU on its own one-ring pattern (`blocklu.rs`) and the factor is reused as
//! long as it stays a good model: a chord (simplified Newton) iteration
//! `x <- x - J0^-1 F(x)`. Its fixed point is `F = 0` whatever the linearisation point
//! `J0` is; only the contraction rate depends on it, so the factor is refreshed when a
//! solve needs many steps. Should a pivot block of the LU be singular, the engine falls
//! back to the normal equations `J^T J d = -J^T F` (plus a tiny ridge), factored with
//! faer's sparse Cholesky (`Par::Seq`): no pivots, but the two-ring pattern of `J^T J`
//! gives a factor about eleven times larger on the body, and a solve about four times
//! slower (measured with `fitstation bench deform`).
//! Positions in metres; the finite-difference step is relative to the mean edge length.

use super::blocklu::BlockLu;
use super::encoding::MeanValueEncoding;
use super::DeformError;
use faer::dyn_stack::{MemBuffer, MemStack, StackReq};
use faer::sparse::linalg::cholesky::{factorize_symbolic_cholesky, LltRef, SymbolicCholesky};
use faer::sparse::{SparseColMatRef, SymbolicSparseColMatRef};
use faer::{Conj, MatMut, Par, Side};
use glam::{DMat3, DVec3};

/// Forward-difference step of the Jacobian, relative to the mean edge length of the rest
/// mesh (truncation error of the same relative order on an edge-sized ring; rounding
/// about 1e-16 / 1e-6 relative, far below what a chord iteration needs).
const FD_REL_STEP: f64 = 1e-6;
/// Ridge added to the diagonal of `J^T J`, relative to its mean diagonal: keeps the
/// factorisation definite on soft modes; the fixed point does not depend on it.
const NEWTON_RIDGE: f64 = 1e-10;
/// Marks a vertex that is not free.
const NOT_FREE: u32 = u32::MAX;

/// Which factorisation a [`CoupledSystem`] solves with.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum CoupledEngine {
    /// Block LU of `J` itself (one-ring pattern). The default.
    BlockLu,
    /// Cholesky of the normal equations `J^T J` (two-ring pattern): the fallback.
    NormalEquations,
}

/// What a [`CoupledSystem`] knows of the residual `F` at its remembered positions.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum CachedResidual {
    /// Nothing.
    Unknown,
    /// `cached_f` holds `F` there.
    Evaluated,
    /// A solve converged there: its last chord step moved no vertex more than the
    /// tolerance, so `F` is below what the tolerance resolves. The predictor of the next
    /// solve takes it as zero instead of paying a residual pass; the chord steps after
    /// it evaluate `F` as always, so the fixed point and the convergence test do not
    /// depend on this (the predictor is only off by the size of that last step).
    Converged,
}

/// The coupled system of one fixed set (controls + anchors).
pub(crate) struct CoupledSystem {
    /// Reduced index -> vertex, and vertex -> reduced index (or [`NOT_FREE`]).
    free: Vec<u32>,
    reduced_of: Vec<u32>,
    /// Per free row: its entries (the vertex itself first, then its free ring members).
    ent_ptr: Vec<u32>,
    ent_col: Vec<u32>,
    /// `J` blocks, one per entry: `dF_v / dx_u`.
    jac: Vec<DMat3>,
    /// `J` by block columns: rows and `jac` slots of each free column.
    jcol_ptr: Vec<u32>,
    jcol_row: Vec<u32>,
    jcol_slot: Vec<u32>,
    /// Per free row: its fixed ring members and the blocks `dF_v / dx_u` for them (the
    /// predictor's linear response to moved targets).
    fix_ptr: Vec<u32>,
    fix_vtx: Vec<u32>,
    fix_jac: Vec<DMat3>,
    /// The block LU of `J` (None if its analysis failed), the normal equations (built
    /// only when the LU cannot be used), and which of them holds the current factor.
    lu: Option<BlockLu>,
    normal: Option<NormalEquations>,
    engine: CoupledEngine,
    /// Tests only: skip the LU.
    force_normal: bool,
    factored: bool,
    /// Residuals per row (then the right-hand side and step), and a position scratch.
    residual: Vec<DVec3>,
    delta: Vec<DVec3>,
    work: Vec<DVec3>,
    /// What is known of `F` at `cached_at` (the end of the last solve, or the last
    /// linearisation point): a solve that starts there skips one evaluation.
    cached_f: Vec<DVec3>,
    cached_at: Vec<DVec3>,
    cache: CachedResidual,
    fd_step: f64,
}

impl CoupledSystem {
    /// Lays out `J` for the free vertices (`!fixed`) and analyses its block LU. No numbers
    /// yet: call [`Self::linearise`].
    // Index arithmetic over several arrays reads better with indices.
    #[allow(clippy::needless_range_loop)]
    pub(crate) fn new(
        enc: &MeanValueEncoding,
        fixed: &[bool],
        mean_edge_m: f64,
    ) -> Result<Self, DeformError> {
        let n = enc.vertex_count();
        let rings = enc.rings();
        let mut reduced_of = vec![NOT_FREE; n];
        let mut free = Vec::new();
        for v in 0..n {
            if !fixed[v] {
                reduced_of[v] = free.len() as u32;
                free.push(v as u32);
            }
        }
        let nf = free.len();
        let mut ent_ptr = Vec::with_capacity(nf + 1);
        let mut ent_col = Vec::with_capacity(rings.entry_count() + nf);
        ent_ptr.push(0u32);
        for &v in &free {
            let start = ent_col.len();
            ent_col.push(reduced_of[v as usize]);
            for &u in rings.neighbours(v as usize) {
                let r = reduced_of[u as usize];
                if r != NOT_FREE && !ent_col[start..].contains(&r) {
                    ent_col.push(r);
                }
            }
            ent_ptr.push(ent_col.len() as u32);
        }
        let mut fix_ptr = Vec::with_capacity(nf + 1);
        let mut fix_vtx: Vec<u32> = Vec::new();
        fix_ptr.push(0u32);
        for &v in &free {
            let start = fix_vtx.len();
            for &u in rings.neighbours(v as usize) {
                if reduced_of[u as usize] == NOT_FREE && !fix_vtx[start..].contains(&u) {
                    fix_vtx.push(u);
                }
            }
            fix_ptr.push(fix_vtx.len() as u32);
        }
        // Columns of J (transpose of the entry lists).
        let jcol_ptr = super::blocklu::column_offsets(&ent_col, nf);
        let mut fill: Vec<u32> = jcol_ptr[..nf].to_vec();
        let mut jcol_row = vec![0u32; ent_col.len()];
        let mut jcol_slot = vec![0u32; ent_col.len()];
        for r in 0..nf {
            for j in ent_ptr[r] as usize..ent_ptr[r + 1] as usize {
                let c = ent_col[j] as usize;
                let at = fill[c] as usize;
                jcol_row[at] = r as u32;
                jcol_slot[at] = j as u32;
                fill[c] += 1;
            }
        }
        // The block graph of J made symmetric (rings are symmetric on a manifold mesh,
        // not necessarily at a non-manifold spot), without the diagonal.
        let mut adj_ptr = Vec::with_capacity(nf + 1);
        let mut adj: Vec<u32> = Vec::with_capacity(2 * ent_col.len());
        adj_ptr.push(0u32);
        for c in 0..nf {
            let start = adj.len();
            let rows = jcol_row[jcol_ptr[c] as usize..jcol_ptr[c + 1] as usize].iter();
            let cols = ent_col[ent_ptr[c] as usize..ent_ptr[c + 1] as usize].iter();
            for &x in rows.chain(cols) {
                if x as usize != c && !adj[start..].contains(&x) {
                    adj.push(x);
                }
            }
            adj_ptr.push(adj.len() as u32);
        }
        let lu = BlockLu::analyse(&adj_ptr, &adj, super::blocklu::DROP_REL).ok();
        Ok(CoupledSystem {
            free,
            reduced_of,
            jac: vec![DMat3::ZERO; ent_col.len()],
            fix_jac: vec![DMat3::ZERO; fix_vtx.len()],
            fix_ptr,
            fix_vtx,
            ent_ptr,
            ent_col,
            jcol_ptr,
            jcol_row,
            jcol_slot,
            lu,
            normal: None,
            engine: CoupledEngine::BlockLu,
            force_normal: false,
            factored: false,
            residual: vec![DVec3::ZERO; nf],
            delta: vec![DVec3::ZERO; nf],
            cached_f: vec![DVec3::ZERO; nf],
            cached_at: Vec::new(),
            cache: CachedResidual::Unknown,
            work: Vec::new(),
            fd_step: FD_REL_STEP * mean_edge_m.max(f64::MIN_POSITIVE),
        })
    }

    /// Tests: solve with the normal equations even where the LU works.
    #[cfg(test)]
    pub(crate) fn force_normal_equations(&mut self) {
        self.force_normal = true;
    }

    /// The factorisation in use.
    #[cfg(test)]
    pub(crate) fn engine(&self) -> CoupledEngine {
        self.engine
    }

    /// Whether a linearisation has been factored.
    pub(crate) fn is_factored(&self) -> bool {
        self.factored
    }

    /// Builds `J` at `positions` (fixed vertices at their current values) by forward
    /// differences and factors it (block LU; the normal equations if that fails).
    pub(crate) fn linearise(
        &mut self,
        enc: &MeanValueEncoding,
        positions: &[DVec3],
    ) -> Result<(), DeformError> {
        self.factored = false;
        self.cache = CachedResidual::Unknown;
        self.work.clear();
        self.work.extend_from_slice(positions);
        let h = self.fd_step;
        let work = &mut self.work;
        // dF_v/dx_u = [u == v] I - d v_mv / dx_u, by forward differences.
        let mut block = |v: usize, u: usize, base: Option<DVec3>| -> (DMat3, DVec3) {
            let base = base.unwrap_or_else(|| enc.decode_vertex(v, work));
            let keep = work[u];
            let mut cols = [DVec3::ZERO; 3];
            for (k, col) in cols.iter_mut().enumerate() {
                let mut p = keep;
                p[k] += h;
                work[u] = p;
                *col = -(enc.decode_vertex(v, work) - base) / h;
                if u == v {
                    col[k] += 1.0;
                }
            }
            work[u] = keep;
            (DMat3::from_cols(cols[0], cols[1], cols[2]), base)
        };
        for r in 0..self.free.len() {
            let v = self.free[r] as usize;
            // The first entry is the vertex itself: its call evaluates the base decode.
            let mut base = None;
            for j in self.ent_ptr[r] as usize..self.ent_ptr[r + 1] as usize {
                let u = self.free[self.ent_col[j] as usize] as usize;
                let (m, b) = block(v, u, base);
                self.jac[j] = m;
                base = Some(b);
            }
            for j in self.fix_ptr[r] as usize..self.fix_ptr[r + 1] as usize {
                let (m, b) = block(v, self.fix_vtx[j] as usize, base);
                self.fix_jac[j] = m;
                base = Some(b);
            }
            // The vertex's own entry always comes first, so its decode is known here.
            if let Some(b) = base {
                self.cached_f[r] = positions[v] - b;
            }
        }
        let lu_ok = match (&mut self.lu, self.force_normal) {
            (Some(lu), false) => lu
                .factor(&self.jcol_ptr, &self.jcol_row, &self.jcol_slot, &self.jac)
                .is_ok(),
            _ => false,
        };
        if lu_ok {
            self.engine = CoupledEngine::BlockLu;
        } else {
            if self.normal.is_none() {
                self.normal = Some(NormalEquations::new(&self.ent_ptr, &self.ent_col)?);
            }
            if let Some(ne) = &mut self.normal {
                ne.factor(&self.ent_ptr, &self.ent_col, &self.jac)?;
            }
            self.engine = CoupledEngine::NormalEquations;
        }
        self.factored = true;
        self.cached_at.clear();
        self.cached_at.extend_from_slice(positions);
        self.cache = CachedResidual::Evaluated;
        Ok(())
    }

    /// One chord step from `positions`: writes `x - J0^-1 F(x)` for the free vertices
    /// into `out` (fixed ones copied). With `jump` (per vertex, zero except at fixed
    /// vertices about to move), a predictor step instead: `F` is taken to first order at
    /// the moved fixed vertices, `F(x) + J_fixed jump`, so the step is the linear
    /// response of the current smooth surface rather than a step from a surface with its
    /// controls torn away from their neighbours; fixed vertices are written moved.
    /// Returns (step length over free vertices, largest residual `|F_v(x)|`), metres; the
    /// residual is NaN when this step did not evaluate it (a predictor from the result
    /// of a converged solve, see [`CachedResidual::Converged`]).
    #[cfg(test)]
    pub(crate) fn step(
        &mut self,
        enc: &MeanValueEncoding,
        positions: &[DVec3],
        jump: Option<&[DVec3]>,
        out: &mut [DVec3],
    ) -> (f64, f64) {
        let fmax = self.solve_step(enc, positions, jump);
        out.copy_from_slice(positions);
        if let Some(jump) = jump {
            for (o, d) in out.iter_mut().zip(jump) {
                *o += *d;
            }
        }
        (self.apply_step(out), fmax)
    }

    /// The linear half of [`Self::step`]: evaluates `F` at `positions` (or takes it from
    /// what is remembered there), adds `J_fixed jump` for a predictor, and solves for the
    /// step, kept for [`Self::apply_step`] (split so the deformer can apply it in place or
    /// hand it to its acceleration without copying the mesh). Returns the largest
    /// residual `|F_v(x)|`, metres (NaN when not evaluated, see [`Self::step`]); a failed
    /// solve leaves a NaN step.
    pub(crate) fn solve_step(
        &mut self,
        enc: &MeanValueEncoding,
        positions: &[DVec3],
        jump: Option<&[DVec3]>,
    ) -> f64 {
        let mut fmax = 0.0f64;
        let cache = match self.cache {
            CachedResidual::Unknown => CachedResidual::Unknown,
            c if self.cached_at.as_slice() == positions => c,
            _ => CachedResidual::Unknown,
        };
        self.cache = CachedResidual::Unknown;
        // Only a predictor may take the residual of a converged start as zero: a chord
        // step from there must evaluate it (it is the certificate).
        let assume_zero = cache == CachedResidual::Converged && jump.is_some();
        for (r, &v) in self.free.iter().enumerate() {
            let mut f = if assume_zero {
                DVec3::ZERO
            } else if cache == CachedResidual::Evaluated {
                self.cached_f[r]
            } else {
                positions[v as usize] - enc.decode_vertex(v as usize, positions)
            };
            fmax = fmax.max(f.length_squared());
            if let Some(jump) = jump {
                for j in self.fix_ptr[r] as usize..self.fix_ptr[r + 1] as usize {
                    f += self.fix_jac[j] * jump[self.fix_vtx[j] as usize];
                }
            }
            self.residual[r] = f;
        }
        if assume_zero {
            fmax = f64::NAN;
        }
        match (self.engine, &mut self.lu, &mut self.normal) {
            (CoupledEngine::BlockLu, Some(lu), _) => {
                for (d, f) in self.delta.iter_mut().zip(&self.residual) {
                    *d = -*f;
                }
                lu.solve_in_place(&mut self.delta);
            }
            (CoupledEngine::NormalEquations, _, Some(ne)) => ne.solve(
                &self.ent_ptr,
                &self.ent_col,
                &self.jac,
                &self.residual,
                &mut self.delta,
            ),
            _ => self.delta.iter_mut().for_each(|d| *d = DVec3::NAN),
        }
        fmax.sqrt()
    }

    /// Adds the step of the last [`Self::solve_step`] to the free vertices of
    /// `positions`; returns its length, metres (NaN propagates).
    pub(crate) fn apply_step(&self, positions: &mut [DVec3]) -> f64 {
        let mut max_move = 0.0f64;
        for (&v, d) in self.free.iter().zip(&self.delta) {
            let m = d.length_squared();
            if !(m <= max_move) {
                max_move = m; // also propagates NaN
            }
            positions[v as usize] += *d;
        }
        max_move.sqrt()
    }

    /// Largest `|F_v|` over the free vertices at `positions`, metres; remembered for a
    /// solve that starts from there (the next frame's warm start).
    pub(crate) fn residual_at(&mut self, enc: &MeanValueEncoding, positions: &[DVec3]) -> f64 {
        let mut fmax = 0.0f64;
        for (r, &v) in self.free.iter().enumerate() {
            let f = positions[v as usize] - enc.decode_vertex(v as usize, positions);
            fmax = fmax.max(f.length_squared());
            self.cached_f[r] = f;
        }
        self.cached_at.clear();
        self.cached_at.extend_from_slice(positions);
        self.cache = CachedResidual::Evaluated;
        fmax.sqrt()
    }

    /// Remembers `positions` as the result of a converged solve (see
    /// [`CachedResidual::Converged`]); no evaluation.
    pub(crate) fn mark_converged(&mut self, positions: &[DVec3]) {
        self.cached_at.clear();
        self.cached_at.extend_from_slice(positions);
        self.cache = CachedResidual::Converged;
    }

    /// Bench only: one solve of the factored system with the residual last evaluated by
    /// [`Self::residual_at`] as right-hand side (the linear-algebra half of a chord step).
    pub(crate) fn solve_cached_residual(&mut self) {
        for (d, f) in self.delta.iter_mut().zip(&self.cached_f) {
            *d = -*f;
        }
        match (self.engine, &mut self.lu, &mut self.normal) {
            (CoupledEngine::BlockLu, Some(lu), _) => lu.solve_in_place(&mut self.delta),
            (CoupledEngine::NormalEquations, _, Some(ne)) => ne.solve(
                &self.ent_ptr,
                &self.ent_col,
                &self.jac,
                &self.cached_f,
                &mut self.delta,
            ),
            _ => {}
        }
    }

    /// Whether `fixed` is the fixed set this system was built for.
    pub(crate) fn matches(&self, fixed: &[bool]) -> bool {
        fixed.len() == self.reduced_of.len()
            && fixed
                .iter()
                .zip(&self.reduced_of)
                .all(|(&f, &r)| f == (r == NOT_FREE))
    }

    pub(crate) fn heap_bytes(&self) -> usize {
        self.free.len() * 4
            + self.reduced_of.len() * 4
            + self.ent_col.len() * (4 + 72 + 8)
            + self.fix_vtx.len() * (4 + 72)
            + self.residual.len() * 24 * 3
            + self.cached_at.len() * 24
            + self.work.len() * 24
            + self.lu.as_ref().map_or(0, |l| l.heap_bytes())
            + self.normal.as_ref().map_or(0, |n| n.heap_bytes())
    }

    /// Block-LU engine: blocks its solves read and blocks its factor holds.
    pub(crate) fn lu_block_counts(&self) -> Option<(usize, usize)> {
        match (self.engine, &self.lu) {
            (CoupledEngine::BlockLu, Some(lu)) => Some((lu.solve_block_count(), lu.block_count())),
            _ => None,
        }
    }

    /// Stored scalar values of the factor in use.
    pub(crate) fn factor_len(&self) -> usize {
        match (self.engine, &self.lu, &self.normal) {
            (CoupledEngine::BlockLu, Some(lu), _) => 9 * lu.block_count(),
            (CoupledEngine::NormalEquations, _, Some(ne)) => ne.factor.len(),
            _ => 0,
        }
    }
}

/// The fallback: `H = J^T J` (upper triangle, `3F x 3F`, unknown `3r + k`) and its
/// sparse Cholesky factor.
struct NormalEquations {
    /// Per row, per entry pair (p <= q): slots of the block's first row in the three
    /// scalar columns of the block (upper CSC).
    pair_ptr: Vec<u32>,
    pair_base: Vec<[u32; 3]>,
    col_ptr: Vec<usize>,
    row_idx: Vec<usize>,
    values: Vec<f64>,
    symbolic: SymbolicCholesky<usize>,
    factor: Vec<f64>,
    scratch: MemBuffer,
    scratch_bytes: usize,
    rhs: Vec<f64>,
}

impl NormalEquations {
    /// Analyses the pattern of `J^T J` for rows with entries `ent_col[ent_ptr[r]..]`.
    fn new(ent_ptr: &[u32], ent_col: &[u32]) -> Result<Self, DeformError> {
        let nf = ent_ptr.len().saturating_sub(1);
        // Block pattern: every pair (min, max) of entries met in one row.
        let mut pairs: Vec<(u32, u32)> = Vec::with_capacity(ent_col.len() * 8);
        for r in 0..nf {
            let e = &ent_col[ent_ptr[r] as usize..ent_ptr[r + 1] as usize];
            for p in 0..e.len() {
                for q in p..e.len() {
                    pairs.push((e[p].max(e[q]), e[p].min(e[q]))); // (block column, block row)
                }
            }
        }
        pairs.sort_unstable();
        pairs.dedup();
        // Block rows of each block column, sorted (the diagonal block is last).
        let mut bcol_ptr = vec![0usize; nf + 1];
        for &(b, _) in &pairs {
            bcol_ptr[b as usize + 1] += 1;
        }
        for b in 0..nf {
            bcol_ptr[b + 1] += bcol_ptr[b];
        }
        let brow: Vec<u32> = pairs.iter().map(|&(_, a)| a).collect();
        // Scalar upper CSC: column 3b + l holds rows 3a..3a+2 of every block a < b, then
        // rows 3b..=3b+l.
        let dim = 3 * nf;
        let mut col_ptr = Vec::with_capacity(dim + 1);
        let mut row_idx = Vec::new();
        col_ptr.push(0usize);
        for b in 0..nf {
            let rows_b = &brow[bcol_ptr[b]..bcol_ptr[b + 1]];
            for l in 0..3 {
                for &a in rows_b {
                    let a = a as usize;
                    if a < b {
                        row_idx.extend_from_slice(&[3 * a, 3 * a + 1, 3 * a + 2]);
                    } else {
                        row_idx.extend((0..=l).map(|k| 3 * b + k));
                    }
                }
                col_ptr.push(row_idx.len());
            }
        }
        let block_base = |a: u32, b: u32| -> [u32; 3] {
            let rows_b = &brow[bcol_ptr[b as usize]..bcol_ptr[b as usize + 1]];
            let idx = rows_b.partition_point(|&x| x < a);
            let b = b as usize;
            [0, 1, 2].map(|l| (col_ptr[3 * b + l] + 3 * idx) as u32)
        };
        let mut pair_ptr = Vec::with_capacity(nf + 1);
        let mut pair_base = Vec::new();
        pair_ptr.push(0u32);
        for r in 0..nf {
            let e = &ent_col[ent_ptr[r] as usize..ent_ptr[r + 1] as usize];
            for p in 0..e.len() {
                for q in p..e.len() {
                    pair_base.push(block_base(e[p].min(e[q]), e[p].max(e[q])));
                }
            }
            pair_ptr.push(pair_base.len() as u32);
        }
        let view = SymbolicSparseColMatRef::new_checked(dim, dim, &col_ptr, None, &row_idx);
        let symbolic =
            factorize_symbolic_cholesky(view, Side::Upper, Default::default(), Default::default())
                .map_err(|e| DeformError::Factorisation(format!("coupled symbolic: {e:?}")))?;
        let req = StackReq::any_of(&[
            symbolic.factorize_numeric_llt_scratch::<f64>(Par::Seq, Default::default()),
            symbolic.solve_in_place_scratch::<f64>(1, Par::Seq),
        ]);
        let scratch_bytes = req.unaligned_bytes_required();
        let scratch = MemBuffer::try_new(req)
            .map_err(|_| DeformError::Factorisation("out of memory for scratch".into()))?;
        Ok(NormalEquations {
            pair_ptr,
            pair_base,
            values: vec![0.0; row_idx.len()],
            factor: vec![0.0; symbolic.len_val()],
            col_ptr,
            row_idx,
            symbolic,
            scratch,
            scratch_bytes,
            rhs: vec![0.0; dim],
        })
    }

    /// Assembles `J^T J` (plus the ridge) from the blocks and factors it.
    fn factor(
        &mut self,
        ent_ptr: &[u32],
        ent_col: &[u32],
        jac: &[DMat3],
    ) -> Result<(), DeformError> {
        let nf = ent_ptr.len().saturating_sub(1);
        self.values.iter_mut().for_each(|x| *x = 0.0);
        for r in 0..nf {
            let (e0, e1) = (ent_ptr[r] as usize, ent_ptr[r + 1] as usize);
            let mut slot = self.pair_ptr[r] as usize;
            for p in e0..e1 {
                for q in p..e1 {
                    let base = self.pair_base[slot];
                    slot += 1;
                    let (cp, cq) = (ent_col[p], ent_col[q]);
                    if cp == cq {
                        let m = jac[p].transpose() * jac[p];
                        for (l, &b) in base.iter().enumerate() {
                            let col = m.col(l);
                            for k in 0..=l {
                                self.values[b as usize + k] += col[k];
                            }
                        }
                    } else {
                        // Block (row min, column max) = J_min^T J_max.
                        let (a, b) = if cp < cq { (p, q) } else { (q, p) };
                        let m = jac[a].transpose() * jac[b];
                        for (l, &s) in base.iter().enumerate() {
                            let col = m.col(l);
                            for k in 0..3 {
                                self.values[s as usize + k] += col[k];
                            }
                        }
                    }
                }
            }
        }
        // Ridge on the diagonal (the last row of each scalar column is its diagonal).
        let dim = self.rhs.len();
        let trace: f64 = (0..dim).map(|c| self.values[self.col_ptr[c + 1] - 1]).sum();
        let mean_diag = trace / dim.max(1) as f64;
        if dim == 0 {
            return Ok(());
        }
        for c in 0..dim {
            self.values[self.col_ptr[c + 1] - 1] += NEWTON_RIDGE * mean_diag;
        }
        let a = SparseColMatRef::new(
            SymbolicSparseColMatRef::new_checked(dim, dim, &self.col_ptr, None, &self.row_idx),
            &self.values,
        );
        let stack = MemStack::new(&mut self.scratch);
        self.symbolic
            .factorize_numeric_llt::<f64>(
                &mut self.factor,
                a,
                Side::Upper,
                Default::default(),
                Par::Seq,
                stack,
                Default::default(),
            )
            .map_err(|e| DeformError::Factorisation(format!("coupled numeric: {e:?}")))?;
        Ok(())
    }

    /// Writes `-(J^T J)^-1 J^T f` into `out` (per free row).
    fn solve(
        &mut self,
        ent_ptr: &[u32],
        ent_col: &[u32],
        jac: &[DMat3],
        f: &[DVec3],
        out: &mut [DVec3],
    ) {
        self.rhs.iter_mut().for_each(|x| *x = 0.0);
        for (r, f) in f.iter().enumerate() {
            for j in ent_ptr[r] as usize..ent_ptr[r + 1] as usize {
                let g = jac[j].transpose() * *f;
                let c = 3 * ent_col[j] as usize;
                self.rhs[c] -= g.x;
                self.rhs[c + 1] -= g.y;
                self.rhs[c + 2] -= g.z;
            }
        }
        let dim = self.rhs.len();
        let stack = MemStack::new(&mut self.scratch);
        let rhs = MatMut::from_column_major_slice_mut(&mut self.rhs, dim, 1);
        LltRef::<usize, f64>::new(&self.symbolic, &self.factor).solve_in_place_with_conj(
            Conj::No,
            rhs,
            Par::Seq,
            stack,
        );
        for (r, o) in out.iter_mut().enumerate() {
            *o = DVec3::new(self.rhs[3 * r], self.rhs[3 * r + 1], self.rhs[3 * r + 2]);
        }
    }

    fn heap_bytes(&self) -> usize {
        self.pair_base.len() * 12
            + self.pair_ptr.len() * 4
            + self.col_ptr.len() * 8
            + self.row_idx.len() * 16
            + self.factor.len() * 8
            + self.rhs.len() * 8
            + self.scratch_bytes
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::shapes::uv_sphere;

    /// The block LU and the normal equations take the same chord step.
    #[test]
    fn lu_and_normal_equations_agree() {
        let mesh = uv_sphere(1.0, 12, 16);
        let enc = MeanValueEncoding::encode(&mesh, &mesh.one_rings());
        let n = mesh.vertex_count();
        let fixed: Vec<bool> = (0..n).map(|v| v % 5 == 0).collect();
        let mut jump = vec![DVec3::ZERO; n];
        for v in (0..n).filter(|&v| fixed[v]) {
            let p = mesh.positions[v];
            jump[v] = DVec3::new(0.05 * p.y, 0.02 * p.x, 0.0);
        }
        let mut outs = Vec::new();
        for force in [false, true] {
            let mut sys = CoupledSystem::new(&enc, &fixed, mesh.mean_edge_length()).unwrap();
            if force {
                sys.force_normal_equations();
            }
            sys.linearise(&enc, &mesh.positions).unwrap();
            let want = if force {
                CoupledEngine::NormalEquations
            } else {
                CoupledEngine::BlockLu
            };
            assert_eq!(sys.engine(), want);
            let mut out = mesh.positions.clone();
            let (moved, _) = sys.step(&enc, &mesh.positions, Some(&jump), &mut out);
            assert!(moved > 1e-3 && moved.is_finite());
            outs.push(out);
        }
        let diff = outs[0]
            .iter()
            .zip(&outs[1])
            .map(|(a, b)| (*a - *b).length())
            .fold(0.0, f64::max);
        assert!(diff < 1e-5, "engines differ by {diff} m");
    }
}
