//! Sparse least-squares engine shared by the fast mean value decoder and the Laplacian
//! deformer: rows `x_v - sum_i w_i x_i = delta_v` (one per free vertex, weights from a
//! one-ring), control vertices as hard constraints (eliminated: identity rows in a system
//! of fixed size) or weighted ones. Normal equations `A = L^T L` are factored with faer's
//! sparse Cholesky, single-threaded (`Par::Seq`).
//!
//! The sparsity pattern of `A` is the one with every row present, so the symbolic
//! analysis (ordering, elimination tree) is done once per mesh and reused for any
//! control set; only the numeric factor is recomputed by `set_controls`. Each solve is
//! then one forward/backward substitution with three right-hand-side columns (x, y, z).
//! Positions are metres; the system is dimensionless in its weights.

use super::DeformError;
use crate::mesh::OneRings;
use faer::dyn_stack::{MemBuffer, MemStack, StackReq};
use faer::sparse::linalg::cholesky::{factorize_symbolic_cholesky, LltRef, SymbolicCholesky};
use faer::sparse::{SparseColMatRef, SymbolicSparseColMatRef};
use faer::{Conj, MatMut, Par, Side};
use glam::DVec3;

/// Sparse rows `x_v - sum_i w_i x_i` in compressed form: the first entry of each row is
/// the vertex itself with coefficient 1.
#[derive(Debug, Clone)]
pub(crate) struct RowSystem {
    pub(crate) row_ptr: Vec<u32>,
    pub(crate) col: Vec<u32>,
    pub(crate) coef: Vec<f64>,
}

impl RowSystem {
    /// Rows from per-vertex weights over the one-rings (`weight(v)` in ring order).
    pub(crate) fn from_rings<'a>(rings: &OneRings, weight: impl Fn(usize) -> &'a [f64]) -> Self {
        let n = rings.vertex_count();
        let mut row_ptr = Vec::with_capacity(n + 1);
        let mut col = Vec::with_capacity(rings.entry_count() + n);
        let mut coef = Vec::with_capacity(rings.entry_count() + n);
        row_ptr.push(0);
        for v in 0..n {
            col.push(v as u32);
            coef.push(1.0);
            for (&i, &w) in rings.neighbours(v).iter().zip(weight(v)) {
                col.push(i);
                coef.push(-w);
            }
            row_ptr.push(col.len() as u32);
        }
        RowSystem { row_ptr, col, coef }
    }

    #[inline]
    pub(crate) fn row(&self, v: usize) -> (&[u32], &[f64]) {
        let (a, b) = (self.row_ptr[v] as usize, self.row_ptr[v + 1] as usize);
        (&self.col[a..b], &self.coef[a..b])
    }

    pub(crate) fn len(&self) -> usize {
        self.row_ptr.len() - 1
    }
}

/// Constraint mode of the engine.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) enum Constraints {
    Hard,
    Weighted(f64),
}

/// Cholesky-factored normal equations with a fixed pattern; see the module docs.
pub(crate) struct NormalEquations {
    n: usize,
    rows: RowSystem,
    /// Upper triangle of `A` in CSC form.
    col_ptr: Vec<usize>,
    row_idx: Vec<usize>,
    values: Vec<f64>,
    /// For each row, the slots of its entry pairs (a <= b in entry order), row-major.
    pair_ptr: Vec<u32>,
    pair_slot: Vec<u32>,
    diag_slot: Vec<u32>,
    symbolic: SymbolicCholesky<usize>,
    factor: Vec<f64>,
    factored: bool,
    scratch: MemBuffer,
    /// Fixed vertices of the current factor (controls + anchors) and the mode.
    pub(crate) fixed: Vec<bool>,
    pub(crate) mode: Constraints,
    /// Right-hand side, column-major n x 3.
    rhs: Vec<f64>,
}

const RHS_COLUMNS: usize = 3;

impl NormalEquations {
    /// Builds the pattern and its symbolic factorisation.
    pub(crate) fn new(rows: RowSystem) -> Result<Self, DeformError> {
        let n = rows.len();
        // Pattern: every pair (min, max) of columns met in one row, plus the diagonal.
        let mut pairs: Vec<(u32, u32)> = Vec::with_capacity(rows.col.len() * 8);
        for v in 0..n {
            let (cols, _) = rows.row(v);
            for a in 0..cols.len() {
                for b in a..cols.len() {
                    let (i, j) = (cols[a].min(cols[b]), cols[a].max(cols[b]));
                    pairs.push((j, i)); // (column, row) for CSC order
                }
            }
        }
        for v in 0..n as u32 {
            pairs.push((v, v));
        }
        pairs.sort_unstable();
        pairs.dedup();
        let mut col_ptr = vec![0usize; n + 1];
        let mut row_idx = Vec::with_capacity(pairs.len());
        for &(c, r) in &pairs {
            col_ptr[c as usize + 1] += 1;
            row_idx.push(r as usize);
        }
        for c in 0..n {
            col_ptr[c + 1] += col_ptr[c];
        }
        let slot_of = |r: u32, c: u32| -> u32 {
            let (lo, hi) = (col_ptr[c as usize], col_ptr[c as usize + 1]);
            let k = row_idx[lo..hi].partition_point(|&x| x < r as usize);
            (lo + k) as u32
        };
        let mut pair_ptr = Vec::with_capacity(n + 1);
        let mut pair_slot = Vec::new();
        pair_ptr.push(0u32);
        for v in 0..n {
            let (cols, _) = rows.row(v);
            for a in 0..cols.len() {
                for b in a..cols.len() {
                    let (i, j) = (cols[a].min(cols[b]), cols[a].max(cols[b]));
                    pair_slot.push(slot_of(i, j));
                }
            }
            pair_ptr.push(pair_slot.len() as u32);
        }
        let diag_slot: Vec<u32> = (0..n as u32).map(|v| slot_of(v, v)).collect();
        let symbolic_view = SymbolicSparseColMatRef::new_checked(n, n, &col_ptr, None, &row_idx);
        let symbolic = factorize_symbolic_cholesky(
            symbolic_view,
            Side::Upper,
            Default::default(),
            Default::default(),
        )
        .map_err(|e| DeformError::Factorisation(format!("symbolic: {e:?}")))?;
        let req = StackReq::any_of(&[
            symbolic.factorize_numeric_llt_scratch::<f64>(Par::Seq, Default::default()),
            symbolic.solve_in_place_scratch::<f64>(RHS_COLUMNS, Par::Seq),
        ]);
        let scratch = MemBuffer::try_new(req)
            .map_err(|_| DeformError::Factorisation("out of memory for scratch".into()))?;
        let factor = vec![0.0; symbolic.len_val()];
        let values = vec![0.0; row_idx.len()];
        Ok(NormalEquations {
            n,
            rows,
            col_ptr,
            row_idx,
            values,
            pair_ptr,
            pair_slot,
            diag_slot,
            symbolic,
            factor,
            factored: false,
            scratch,
            fixed: vec![false; n],
            mode: Constraints::Hard,
            rhs: vec![0.0; RHS_COLUMNS * n],
        })
    }

    /// Assembles and factors `A` for the fixed set `fixed` (controls and anchors) under
    /// `mode`. Rows of fixed vertices are left out (their vertices are not free).
    // Index arithmetic over several arrays reads better with indices.
    #[allow(clippy::needless_range_loop)]
    pub(crate) fn factor(&mut self, fixed: &[bool], mode: Constraints) -> Result<(), DeformError> {
        self.fixed.clear();
        self.fixed.extend_from_slice(fixed);
        self.mode = mode;
        self.values.iter_mut().for_each(|x| *x = 0.0);
        for v in 0..self.n {
            if fixed[v] {
                continue;
            }
            let (cols, coefs) = self.rows.row(v);
            let slots = &self.pair_slot[self.pair_ptr[v] as usize..self.pair_ptr[v + 1] as usize];
            let mut k = 0;
            for a in 0..cols.len() {
                for b in a..cols.len() {
                    let both_free = !fixed[cols[a] as usize] && !fixed[cols[b] as usize];
                    if mode != Constraints::Hard || both_free {
                        self.values[slots[k] as usize] += coefs[a] * coefs[b];
                    }
                    k += 1;
                }
            }
        }
        for v in 0..self.n {
            if fixed[v] {
                let d = &mut self.values[self.diag_slot[v] as usize];
                match mode {
                    Constraints::Hard => *d = 1.0,
                    Constraints::Weighted(w) => *d += w,
                }
            }
        }
        let a = SparseColMatRef::new(
            SymbolicSparseColMatRef::new_checked(
                self.n,
                self.n,
                &self.col_ptr,
                None,
                &self.row_idx,
            ),
            &self.values,
        );
        let stack = MemStack::new(&mut self.scratch);
        self.factored = false;
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
            .map_err(|e| DeformError::Factorisation(format!("numeric: {e:?} (a free part of the mesh without control vertex, or degenerate weights)")))?;
        self.factored = true;
        Ok(())
    }

    /// Solves for positions given per-vertex right-hand sides `delta` (used for free rows)
    /// and the values of the fixed vertices, read from `positions` (targets already
    /// written there). Writes the solution into `positions`; returns the largest move.
    // Index arithmetic over several arrays reads better with indices.
    #[allow(clippy::needless_range_loop)]
    pub(crate) fn solve(&mut self, delta: &[DVec3], positions: &mut [DVec3]) -> f64 {
        debug_assert!(self.factored);
        let n = self.n;
        self.rhs.iter_mut().for_each(|x| *x = 0.0);
        let hard = self.mode == Constraints::Hard;
        for v in 0..n {
            if self.fixed[v] {
                continue;
            }
            let (cols, coefs) = self.rows.row(v);
            let mut g = delta[v];
            if hard {
                for (&c, &k) in cols.iter().zip(coefs) {
                    if self.fixed[c as usize] {
                        g -= k * positions[c as usize];
                    }
                }
            }
            for (&c, &k) in cols.iter().zip(coefs) {
                let c = c as usize;
                if hard && self.fixed[c] {
                    continue;
                }
                self.rhs[c] += k * g.x;
                self.rhs[n + c] += k * g.y;
                self.rhs[2 * n + c] += k * g.z;
            }
        }
        for v in 0..n {
            if self.fixed[v] {
                let t = positions[v];
                let w = match self.mode {
                    Constraints::Hard => {
                        self.rhs[v] = 0.0;
                        self.rhs[n + v] = 0.0;
                        self.rhs[2 * n + v] = 0.0;
                        1.0
                    }
                    Constraints::Weighted(w) => w,
                };
                self.rhs[v] += w * t.x;
                self.rhs[n + v] += w * t.y;
                self.rhs[2 * n + v] += w * t.z;
            }
        }
        let stack = MemStack::new(&mut self.scratch);
        let rhs = MatMut::from_column_major_slice_mut(&mut self.rhs, n, RHS_COLUMNS);
        LltRef::<usize, f64>::new(&self.symbolic, &self.factor).solve_in_place_with_conj(
            Conj::No,
            rhs,
            Par::Seq,
            stack,
        );
        let mut max_move = 0.0f64;
        for v in 0..n {
            let x = DVec3::new(self.rhs[v], self.rhs[n + v], self.rhs[2 * n + v]);
            let mv = (x - positions[v]).length_squared();
            if !(mv <= max_move) {
                max_move = mv; // also propagates NaN
            }
            positions[v] = x;
        }
        max_move.sqrt()
    }

    /// Heap bytes held (pattern, values, factor, scratch estimate).
    pub(crate) fn heap_bytes(&self) -> usize {
        self.rows.col.len() * 12
            + self.row_idx.len() * 16
            + self.pair_slot.len() * 4
            + self.factor.len() * 8
            + self.rhs.len() * 8
            + self.n * 32
    }

    /// Number of stored values of the Cholesky factor.
    pub(crate) fn factor_len(&self) -> usize {
        self.factor.len()
    }
}

/// Connected components of the one-ring graph: returns each vertex's component id.
pub(crate) fn components(rings: &OneRings) -> Vec<u32> {
    let n = rings.vertex_count();
    let mut comp = vec![u32::MAX; n];
    let mut stack = Vec::new();
    let mut next = 0u32;
    for s in 0..n {
        if comp[s] != u32::MAX {
            continue;
        }
        comp[s] = next;
        stack.push(s);
        while let Some(v) = stack.pop() {
            for &u in rings.neighbours(v) {
                if comp[u as usize] == u32::MAX {
                    comp[u as usize] = next;
                    stack.push(u as usize);
                }
            }
        }
        next += 1;
    }
    comp
}

/// Up to four anchor vertices per connected component, spread out so that they fix every
/// affine motion of the component: the first vertex, the one farthest from it, the one
/// farthest from their line, the one farthest from the plane of those three.
pub(crate) fn component_anchor_candidates(comp: &[u32], positions: &[DVec3]) -> Vec<Vec<u32>> {
    let ncomp = comp.iter().map(|&c| c as usize + 1).max().unwrap_or(0);
    let mut members: Vec<Vec<u32>> = vec![Vec::new(); ncomp];
    for (v, &c) in comp.iter().enumerate() {
        members[c as usize].push(v as u32);
    }
    members
        .into_iter()
        .map(|vs| {
            let mut out = vec![vs[0]];
            let p = |v: u32| positions[v as usize];
            let a = p(vs[0]);
            let far = |score: &dyn Fn(DVec3) -> f64| {
                vs.iter()
                    .copied()
                    .max_by(|&x, &y| score(p(x)).total_cmp(&score(p(y))))
            };
            if let Some(b) = far(&|q| (q - a).length()).filter(|&b| p(b) != a) {
                out.push(b);
                let ab = (p(b) - a).normalize();
                if let Some(c) = far(&|q| (q - a).reject_from_normalized(ab).length()) {
                    let n = ab.cross(p(c) - a);
                    if n.length() > 0.0 {
                        out.push(c);
                        let n = n.normalize();
                        if let Some(d) = far(&|q| (q - a).dot(n).abs()) {
                            if (p(d) - a).dot(n).abs() > 0.0 {
                                out.push(d);
                            }
                        }
                    }
                }
            }
            out
        })
        .collect()
}

/// Fixed set for a control mask: the controls plus the anchor candidates of each
/// component without a control, so the system stays definite (the anchors pin the free
/// affine motion of that component at its current position).
pub(crate) fn fixed_with_anchors(
    is_control: &[bool],
    comp: &[u32],
    candidates: &[Vec<u32>],
    fixed: &mut Vec<bool>,
    anchors: &mut Vec<u32>,
) {
    fixed.clear();
    fixed.extend_from_slice(is_control);
    anchors.clear();
    let mut has = vec![false; candidates.len()];
    for (v, &c) in comp.iter().enumerate() {
        if is_control[v] {
            has[c as usize] = true;
        }
    }
    for (c, cand) in candidates.iter().enumerate() {
        if !has[c] {
            for &v in cand {
                fixed[v as usize] = true;
                anchors.push(v);
            }
        }
    }
}

/// The same least squares with the fixed vertices removed from the unknowns (hard
/// constraints only): smaller factor, faster solves, but the symbolic analysis is redone
/// whenever the set of fixed vertices changes (a template's control set usually does
/// not change from frame to frame, only the targets do).
pub(crate) struct ReducedSystem {
    full_rows: RowSystem,
    fixed_mask: Vec<bool>,
    free: Vec<u32>,
    eq: Option<NormalEquations>,
    delta_r: Vec<DVec3>,
    pos_r: Vec<DVec3>,
}

impl ReducedSystem {
    pub(crate) fn new(full_rows: RowSystem) -> Self {
        ReducedSystem {
            full_rows,
            fixed_mask: Vec::new(),
            free: Vec::new(),
            eq: None,
            delta_r: Vec::new(),
            pos_r: Vec::new(),
        }
    }

    /// Analyses and factors the system of the free vertices; a no-op when the fixed set
    /// is the one already factored (the matrix depends on nothing else).
    pub(crate) fn factor(&mut self, fixed: &[bool]) -> Result<(), DeformError> {
        if self.eq.is_some() && self.fixed_mask == fixed {
            return Ok(());
        }
        self.eq = None;
        let n = self.full_rows.len();
        let mut free_of = vec![u32::MAX; n];
        self.free.clear();
        for v in 0..n {
            if !fixed[v] {
                free_of[v] = self.free.len() as u32;
                self.free.push(v as u32);
            }
        }
        let mut row_ptr = Vec::with_capacity(self.free.len() + 1);
        let mut col = Vec::new();
        let mut coef = Vec::new();
        row_ptr.push(0);
        for &v in &self.free {
            let (cols, coefs) = self.full_rows.row(v as usize);
            for (&c, &k) in cols.iter().zip(coefs) {
                let r = free_of[c as usize];
                if r != u32::MAX {
                    col.push(r);
                    coef.push(k);
                }
            }
            row_ptr.push(col.len() as u32);
        }
        let nfree = self.free.len();
        self.delta_r = vec![DVec3::ZERO; nfree];
        self.pos_r = vec![DVec3::ZERO; nfree];
        if nfree > 0 {
            let mut eq = NormalEquations::new(RowSystem { row_ptr, col, coef })?;
            eq.factor(&vec![false; nfree], Constraints::Hard)?;
            self.eq = Some(eq);
        }
        self.fixed_mask.clear();
        self.fixed_mask.extend_from_slice(fixed);
        Ok(())
    }

    /// As [`NormalEquations::solve`]: fixed vertices are read from `positions`.
    pub(crate) fn solve(&mut self, delta: &[DVec3], positions: &mut [DVec3]) -> f64 {
        let Some(eq) = &mut self.eq else { return 0.0 };
        for (r, &v) in self.free.iter().enumerate() {
            let (cols, coefs) = self.full_rows.row(v as usize);
            let mut g = delta[v as usize];
            for (&c, &k) in cols.iter().zip(coefs) {
                if self.fixed_mask[c as usize] {
                    g -= k * positions[c as usize];
                }
            }
            self.delta_r[r] = g;
            self.pos_r[r] = positions[v as usize];
        }
        let moved = eq.solve(&self.delta_r, &mut self.pos_r);
        for (r, &v) in self.free.iter().enumerate() {
            positions[v as usize] = self.pos_r[r];
        }
        moved
    }

    pub(crate) fn heap_bytes(&self) -> usize {
        self.full_rows.col.len() * 12
            + self.fixed_mask.len()
            + self.free.len() * 52
            + self.eq.as_ref().map_or(0, |e| e.heap_bytes())
    }

    pub(crate) fn factor_len(&self) -> usize {
        self.eq.as_ref().map_or(0, |e| e.factor_len())
    }
}

/// The fast decoder's linear engine.
pub(crate) enum Engine {
    /// Full-size system, symbolic analysis once per mesh (any control set).
    Full(NormalEquations),
    /// Free vertices only, analysis per control set (hard constraints).
    Reduced(ReducedSystem),
}

impl Engine {
    pub(crate) fn factor(&mut self, fixed: &[bool], mode: Constraints) -> Result<(), DeformError> {
        match self {
            Engine::Full(e) => e.factor(fixed, mode),
            Engine::Reduced(e) => e.factor(fixed),
        }
    }
    pub(crate) fn solve(&mut self, delta: &[DVec3], positions: &mut [DVec3]) -> f64 {
        match self {
            Engine::Full(e) => e.solve(delta, positions),
            Engine::Reduced(e) => e.solve(delta, positions),
        }
    }
    pub(crate) fn is_soft(&self) -> bool {
        matches!(self, Engine::Full(e) if e.mode != Constraints::Hard)
    }
    pub(crate) fn heap_bytes(&self) -> usize {
        match self {
            Engine::Full(e) => e.heap_bytes(),
            Engine::Reduced(e) => e.heap_bytes(),
        }
    }
    pub(crate) fn factor_len(&self) -> usize {
        match self {
            Engine::Full(e) => e.factor_len(),
            Engine::Reduced(e) => e.factor_len(),
        }
    }
}
