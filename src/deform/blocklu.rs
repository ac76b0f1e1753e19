//! Sparse LU factorisation of a square matrix of `3 x 3` blocks whose block pattern is
//! symmetric (a mesh adjacency), without pivoting: the engine behind the coupled
//! Gauss-Newton decoder (`newton.rs`), which solves `J d = -F` with the square Jacobian
//! `J` of the free vertices directly instead of the normal equations `J^T J d = -J^T F`.
//!
//! Why not the normal equations: `J^T J` couples every vertex with its two-ring, its
//! Cholesky factor on the body holds about 3.5 times the values of a factor with the
//! one-ring pattern of `J`, and a chord step is bound by reading the factor. Why no
//! pivoting: `J = I - W - D` (mean value weights `W` summing to one, and how the normal
//! offsets turn with the ring, `D`) has identity diagonal blocks and is close to a
//! graph Laplacian, so the block pivots stay well away from zero; a pivot block whose
//! determinant is tiny relative to its size is reported ([`BlockLuError`]) and the caller
//! falls back to the normal equations, which need no pivots.
//!
//! Steps (standard sparse direct method, no code from elsewhere):
//! 1. a fill-reducing order of the block graph (faer's approximate minimum degree);
//! 2. the pattern of `L` (rows of each column below the diagonal) and of `U` (its
//!    transpose: rows above the diagonal of each column) from the elimination tree,
//!    walking each row's subtree (`analyse`);
//! 3. numeric factorisation `P J P^T = L U` column by column, left-looking: the column of
//!    `J` is scattered into a dense block vector, the earlier columns of `L` named by
//!    the column's `U` pattern are subtracted in increasing order, the diagonal block is
//!    inverted and the rest scaled into `L` (`factor`);
//! 4. solves: forward substitution with the unit lower `L`, backward with `U`, both
//!    row-oriented (`solve_in_place`): each unknown is one dot product of a factor row
//!    with unknowns already computed, gathered into registers. The factorisation works
//!    by columns, so the `f32` copies for the solves are stored by rows (`L` rows follow
//!    the `U` column pattern and vice versa: the pattern is symmetric). Why: the
//!    column-oriented solve scatters every block product into the solution vector
//!    (a read-modify-write per block). On the body the gather form solves in 0.5 to
//!    1.3 ms depending on what else runs on the 2-core machine (`fitstation bench
//!    deform`, "fast step parts", load 2.5 to 6); the scatter form's solve had been
//!    measured at about 1.3 ms. Side by side at load 3 (with the other changes of this
//!    file, `newton.rs` and `mvc.rs`), the bench's warm refit went from 3.1-4.8 ms to
//!    2.35-2.5 ms.
//!
//! Unitless (whatever the matrix holds); indices are the caller's "reduced" indices.
//! Factor values are stored as `f32` blocks for the solves (half the memory traffic of a
//! solve, which is what a chord step costs); the factorisation itself runs in `f64`. The
//! solve is therefore accurate to about `cond(J) * 6e-8` relative, which only perturbs a
//! chord step (the fixed point `F = 0` is evaluated in `f64` and does not move).

use faer::dyn_stack::{MemBuffer, MemStack};
use faer::sparse::linalg::amd;
use faer::sparse::SymbolicSparseColMatRef;
use glam::{DMat3, DVec3, Mat3, Vec3};

/// A pivot block counts as singular when `|det| <= PIVOT_REL_DET * |block|_F^3`.
const PIVOT_REL_DET: f64 = 1e-12;

/// Default of the drop tolerance of [`BlockLu::analyse`] (the coupled decoder's): a block
/// of the factor whose largest entry is below this fraction of the largest entry
/// of its row's diagonal block (for the unit lower `L`: below this fraction, in absolute
/// terms) is left out of the solves. Why: a solve streams the whole factor and is bound
/// by memory (measured: its hot loop waits on the loads of the blocks), and on the body
/// 9% of the blocks are below 1e-4 (47% below 1e-2). What it costs: the solves
/// use a factor that differs from `J` by those blocks, i.e. the chord steps see a
/// slightly different Jacobian; the fixed point `F = 0` (evaluated in `f64`) and the
/// convergence test on the steps do not change. Measured on the body: the refit and the
/// decode from rest still converge in two steps at 1e-4 (last moves 30 and 80 um); at
/// 1e-3 they need three.
pub(crate) const DROP_REL: f64 = 1e-4;

/// Column index of a solve row: 16 bits while the matrix has fewer than 65536 block rows
/// (the body has about 6,000 free vertices), which shortens the stream a solve reads.
trait ColIndex: Copy {
    fn at(self) -> usize;
}

impl ColIndex for u16 {
    #[inline]
    fn at(self) -> usize {
        self as usize
    }
}

impl ColIndex for u32 {
    #[inline]
    fn at(self) -> usize {
        self as usize
    }
}

/// Column indices of [`SolveRows`], in the narrowest type that holds them.
enum Cols {
    Narrow(Vec<u16>),
    Wide(Vec<u32>),
}

/// Rows of a triangular factor for the solves: row `r` holds the blocks
/// `val[ptr[r]..ptr[r + 1]]` at the columns `cols[..]` (same range).
struct SolveRows {
    ptr: Vec<u32>,
    cols: Cols,
    val: Vec<Mat3>,
}

impl SolveRows {
    /// Empty rows for an `n x n` block matrix, with room for `nnz` blocks (all of the
    /// pattern: a refactorisation never allocates).
    fn new(n: usize, nnz: usize) -> Self {
        SolveRows {
            ptr: vec![0; n + 1],
            cols: if n <= u16::MAX as usize + 1 {
                Cols::Narrow(Vec::with_capacity(nnz))
            } else {
                Cols::Wide(Vec::with_capacity(nnz))
            },
            val: Vec::with_capacity(nnz),
        }
    }

    fn clear(&mut self) {
        self.ptr.clear();
        self.ptr.push(0);
        match &mut self.cols {
            Cols::Narrow(c) => c.clear(),
            Cols::Wide(c) => c.clear(),
        }
        self.val.clear();
    }

    fn push(&mut self, col: u32, val: &DMat3) {
        self.push_col(col);
        self.val.push(val.as_mat3());
    }

    /// The column of a block whose value is already in place.
    fn push_col(&mut self, col: u32) {
        match &mut self.cols {
            // `new` chose the narrow type only when every column fits it.
            Cols::Narrow(c) => c.push(col as u16),
            Cols::Wide(c) => c.push(col),
        }
    }

    fn end_row(&mut self) {
        self.ptr.push(self.val.len() as u32);
    }

    /// `sum_e val[e] * x[col[e]]` over row `r`.
    #[inline]
    fn row_dot(&self, r: usize, x: &[Vec3]) -> Vec3 {
        let (a, b) = (self.ptr[r] as usize, self.ptr[r + 1] as usize);
        match &self.cols {
            Cols::Narrow(c) => row_dot(&c[a..b], &self.val[a..b], x),
            Cols::Wide(c) => row_dot(&c[a..b], &self.val[a..b], x),
        }
    }

    fn len(&self) -> usize {
        self.val.len()
    }

    fn heap_bytes(&self) -> usize {
        let cols = match &self.cols {
            Cols::Narrow(c) => c.capacity() * 2,
            Cols::Wide(c) => c.capacity() * 4,
        };
        self.ptr.capacity() * 4 + cols + self.val.capacity() * 36
    }
}

/// Largest absolute entry of a block.
fn max_abs(m: &DMat3) -> f64 {
    m.abs().to_cols_array().iter().fold(0.0, |a, &x| a.max(x))
}

/// Failures of the block LU.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub(crate) enum BlockLuError {
    #[error("block ordering failed: {0}")]
    Ordering(String),
    #[error("pivot block {0} is singular")]
    SingularPivot(usize),
    #[error("the matrix has an entry outside the analysed pattern (block {row}, {col})")]
    Pattern { row: usize, col: usize },
}

/// Pattern and values of `P J P^T = L U` for an `n x n` block matrix.
pub(crate) struct BlockLu {
    /// Elimination position of each reduced index, and the reduced index at each position.
    pos_of: Vec<u32>,
    at_pos: Vec<u32>,
    /// Strict lower `L` by columns (rows ascending) and strict upper `U` by columns (rows
    /// ascending), positions in elimination order.
    l_ptr: Vec<u32>,
    l_row: Vec<u32>,
    u_ptr: Vec<u32>,
    u_row: Vec<u32>,
    /// `f64` values of `L` (the factorisation reads the earlier columns). `U` is only
    /// written, so it goes straight into its `f32` solve rows: that halves the memory a
    /// factorisation dirties, whose write-back otherwise slows the first solves after a
    /// re-linearisation (measured: the first refit's block solves took about twice as
    /// long as in the frames after it).
    l_val: Vec<DMat3>,
    /// For each slot `e` of the `U` pattern (column `k`, row `j`), the slot of the `L`
    /// pattern at the transposed place (column `j`, row `k`).
    u_to_l: Vec<u32>,
    /// Largest entry of each diagonal block of `U` (the scale its row is dropped against).
    diag_scale: Vec<f64>,
    /// `f32` copies for the solves, by rows, without the negligible blocks (see
    /// `drop_rel`, [`DROP_REL`]): the rows of `L` (strictly left of the diagonal) and of `U` (strictly
    /// right); and the inverted diagonal blocks of `U`.
    l_rows: SolveRows,
    u_rows: SolveRows,
    diag_inv32: Vec<Mat3>,
    /// Drop tolerance of the solve copies (0: exact).
    drop_rel: f64,
    /// Dense block column (factorisation) and solution vector (solves).
    work: Vec<DMat3>,
    touched: Vec<bool>,
    sol: Vec<Vec3>,
    factored: bool,
}

impl BlockLu {
    /// Orders the block graph given by `adj_ptr` / `adj` (for each reduced index its
    /// neighbours, symmetric, without itself) and computes the patterns of `L` and `U`.
    /// The solves will leave out the factor blocks below `drop_rel` (see [`DROP_REL`];
    /// 0 keeps every block: exact solves up to `f32` rounding).
    pub(crate) fn analyse(
        adj_ptr: &[u32],
        adj: &[u32],
        drop_rel: f64,
    ) -> Result<Self, BlockLuError> {
        let n = adj_ptr.len().saturating_sub(1);
        // Step 1: approximate minimum degree on the block graph.
        let mut at_pos = vec![0u32; n];
        let mut pos_of = vec![0u32; n];
        if n > 0 {
            let col_ptr: Vec<u32> = adj_ptr.to_vec();
            let mut row_idx: Vec<u32> = adj.to_vec();
            for c in 0..n {
                row_idx[adj_ptr[c] as usize..adj_ptr[c + 1] as usize].sort_unstable();
            }
            let view = SymbolicSparseColMatRef::new_checked(n, n, &col_ptr, None, &row_idx);
            let req = amd::order_scratch::<u32>(n, row_idx.len());
            let mut mem = MemBuffer::try_new(req)
                .map_err(|_| BlockLuError::Ordering("out of memory".into()))?;
            amd::order(
                &mut at_pos,
                &mut pos_of,
                view,
                amd::Control::default(),
                MemStack::new(&mut mem),
            )
            .map_err(|e| BlockLuError::Ordering(format!("{e:?}")))?;
        }
        // Step 2: elimination tree and row patterns of L (= column patterns of U).
        const NONE: u32 = u32::MAX;
        let mut parent = vec![NONE; n];
        let mut flag = vec![NONE; n];
        let mut u_ptr = Vec::with_capacity(n + 1);
        let mut u_row: Vec<u32> = Vec::with_capacity(adj.len() * 4);
        u_ptr.push(0u32);
        for k in 0..n {
            flag[k] = k as u32;
            let start = u_row.len();
            let r = at_pos[k] as usize;
            for &a in &adj[adj_ptr[r] as usize..adj_ptr[r + 1] as usize] {
                let mut j = pos_of[a as usize] as usize;
                if j >= k {
                    continue;
                }
                while flag[j] != k as u32 {
                    if parent[j] == NONE {
                        parent[j] = k as u32;
                    }
                    u_row.push(j as u32);
                    flag[j] = k as u32;
                    j = parent[j] as usize;
                }
            }
            u_row[start..].sort_unstable();
            u_ptr.push(u_row.len() as u32);
        }
        // Columns of L: k is in column j for every j in the U pattern of column k.
        let l_ptr = column_offsets(&u_row, n);
        let mut fill = l_ptr.clone();
        let mut l_row = vec![0u32; u_row.len()];
        let mut u_to_l = vec![0u32; u_row.len()];
        for k in 0..n {
            for e in u_ptr[k] as usize..u_ptr[k + 1] as usize {
                let j = u_row[e] as usize;
                l_row[fill[j] as usize] = k as u32;
                u_to_l[e] = fill[j];
                fill[j] += 1;
            }
        }
        let nnz = u_row.len();
        Ok(BlockLu {
            pos_of,
            at_pos,
            l_ptr,
            l_row,
            u_ptr,
            u_row,
            l_val: vec![DMat3::ZERO; nnz],
            u_to_l,
            diag_scale: vec![0.0; n],
            drop_rel: drop_rel.max(0.0),
            l_rows: SolveRows::new(n, nnz),
            u_rows: SolveRows::new(n, nnz),
            diag_inv32: vec![Mat3::ZERO; n],
            work: vec![DMat3::ZERO; n],
            touched: vec![false; n],
            sol: vec![Vec3::ZERO; n],
            factored: false,
        })
    }

    /// Number of block rows.
    pub(crate) fn dim(&self) -> usize {
        self.pos_of.len()
    }

    /// Stored blocks of `L` and `U` (strict parts; the diagonal adds `dim`).
    pub(crate) fn block_count(&self) -> usize {
        self.l_row.len() + self.u_row.len() + self.dim()
    }

    /// Blocks the solves read (the strict parts without the dropped blocks, plus the
    /// diagonal).
    pub(crate) fn solve_block_count(&self) -> usize {
        self.l_rows.len() + self.u_rows.len() + self.dim()
    }

    /// Step 3: factors the matrix given by columns (reduced indices): column `c` holds
    /// the blocks `value[slot]` at rows `col_row[e]`, `slot = col_slot[e]`, for `e` in
    /// `col_ptr[c]..col_ptr[c + 1]`.
    pub(crate) fn factor(
        &mut self,
        col_ptr: &[u32],
        col_row: &[u32],
        col_slot: &[u32],
        value: &[DMat3],
    ) -> Result<(), BlockLuError> {
        self.factored = false;
        let n = self.dim();
        // U goes by rows into its solve rows, every block first (at the L slot of the
        // transposed place: row j's blocks are l_ptr[j]..l_ptr[j + 1]), compacted below.
        let nnz = self.l_row.len();
        self.u_rows.val.clear();
        self.u_rows.val.resize(nnz, Mat3::ZERO);
        for k in 0..n {
            let c = self.at_pos[k] as usize;
            // Scatter column c of J (rows in elimination positions).
            for e in col_ptr[c] as usize..col_ptr[c + 1] as usize {
                let i = self.pos_of[col_row[e] as usize] as usize;
                self.work[i] = value[col_slot[e] as usize];
                self.touched[i] = true;
            }
            // Left-looking updates from the earlier columns of L, in increasing order.
            for e in self.u_ptr[k] as usize..self.u_ptr[k + 1] as usize {
                let j = self.u_row[e] as usize;
                let ujk = self.work[j];
                self.work[j] = DMat3::ZERO;
                self.touched[j] = false;
                self.u_rows.val[self.u_to_l[e] as usize] = ujk.as_mat3();
                for f in self.l_ptr[j] as usize..self.l_ptr[j + 1] as usize {
                    let i = self.l_row[f] as usize;
                    self.work[i] -= self.l_val[f] * ujk;
                }
            }
            let d = self.work[k];
            self.work[k] = DMat3::ZERO;
            self.touched[k] = false;
            let size =
                d.x_axis.length_squared() + d.y_axis.length_squared() + d.z_axis.length_squared();
            let det = d.determinant();
            if !(det.abs() > PIVOT_REL_DET * size * size.sqrt()) {
                self.clear_work();
                return Err(BlockLuError::SingularPivot(k));
            }
            let dinv = d.inverse();
            self.diag_inv32[k] = dinv.as_mat3();
            self.diag_scale[k] = max_abs(&d);
            for f in self.l_ptr[k] as usize..self.l_ptr[k + 1] as usize {
                let i = self.l_row[f] as usize;
                self.l_val[f] = self.work[i] * dinv;
                self.work[i] = DMat3::ZERO;
                self.touched[i] = false;
            }
            // Anything left in the work vector lies outside the pattern.
            if let Some(e) = (col_ptr[c] as usize..col_ptr[c + 1] as usize)
                .find(|&e| self.touched[self.pos_of[col_row[e] as usize] as usize])
            {
                let row = col_row[e] as usize;
                self.clear_work();
                return Err(BlockLuError::Pattern { row, col: c });
            }
        }
        // Row-major f32 copies without the negligible blocks: row k of L is read through
        // the U pattern of column k (U slot e, column k, row j, is L slot u_to_l[e]
        // transposed), row j of U through the L pattern of column j. The diagonal block
        // of row j is its pivot: `diag_inv32[j]` holds its inverse.
        self.l_rows.clear();
        for k in 0..n {
            for e in self.u_ptr[k] as usize..self.u_ptr[k + 1] as usize {
                let l = &self.l_val[self.u_to_l[e] as usize];
                if max_abs(l) >= self.drop_rel {
                    self.l_rows.push(self.u_row[e], l);
                }
            }
            self.l_rows.end_row();
        }
        // U: compacted in place (a kept block only ever moves to a lower slot).
        let vals = std::mem::take(&mut self.u_rows.val);
        self.u_rows.clear();
        self.u_rows.val = vals;
        let mut kept = 0usize;
        for j in 0..n {
            let keep = self.drop_rel * self.diag_scale[j];
            for f in self.l_ptr[j] as usize..self.l_ptr[j + 1] as usize {
                let u = self.u_rows.val[f];
                if max_abs(&u.as_dmat3()) >= keep {
                    self.u_rows.val[kept] = u;
                    self.u_rows.push_col(self.l_row[f]);
                    kept += 1;
                }
            }
            self.u_rows.ptr.push(kept as u32);
        }
        self.u_rows.val.truncate(kept);
        self.factored = true;
        Ok(())
    }

    fn clear_work(&mut self) {
        self.work.iter_mut().for_each(|w| *w = DMat3::ZERO);
        self.touched.iter_mut().for_each(|t| *t = false);
    }

    /// Step 4: overwrites `rhs` (reduced indices) with the solution of `J x = rhs`.
    pub(crate) fn solve_in_place(&mut self, rhs: &mut [DVec3]) {
        let n = self.dim();
        for (r, b) in rhs.iter().enumerate().take(n) {
            self.sol[self.pos_of[r] as usize] = b.as_vec3();
        }
        // L y = b (unit lower, by rows: y_k = b_k - sum_j L_kj y_j over j < k).
        for k in 0..n {
            let acc = self.l_rows.row_dot(k, &self.sol);
            self.sol[k] -= acc;
        }
        // U x = y (by rows, from the last: x_j = D_j^-1 (y_j - sum_k U_jk x_k), k > j).
        for j in (0..n).rev() {
            let acc = self.u_rows.row_dot(j, &self.sol);
            self.sol[j] = self.diag_inv32[j] * (self.sol[j] - acc);
        }
        for (r, b) in rhs.iter_mut().enumerate().take(n) {
            *b = self.sol[self.pos_of[r] as usize].as_dvec3();
        }
    }

    pub(crate) fn heap_bytes(&self) -> usize {
        let nnz = self.l_row.len();
        let n = self.dim();
        n * 8
            + (self.l_ptr.len() + self.u_ptr.len()) * 4
            + nnz * (4 + 4 + 4 + 72)
            + n * 8
            + self.l_rows.heap_bytes()
            + self.u_rows.heap_bytes()
            + n * (36 + 72 + 1 + 12)
    }
}

/// `sum_e blocks[e] * x[cols[e]]` with two partial sums, so that consecutive block
/// products do not wait for each other's additions. (36-byte `Mat3` blocks rather than
/// 48-byte SIMD `Mat3A` ones: a solve streams the whole factor and is bound by memory,
/// not arithmetic; measured side by side on the body, the two layouts solved equally
/// fast, so the smaller one is kept.)
#[inline]
fn row_dot<C: ColIndex>(cols: &[C], blocks: &[Mat3], x: &[Vec3]) -> Vec3 {
    let mut acc = [Vec3::ZERO; 2];
    let mut pairs_c = cols.chunks_exact(2);
    let mut pairs_b = blocks.chunks_exact(2);
    for (c, m) in (&mut pairs_c).zip(&mut pairs_b) {
        acc[0] += m[0] * x[c[0].at()];
        acc[1] += m[1] * x[c[1].at()];
    }
    for (&c, m) in pairs_c.remainder().iter().zip(pairs_b.remainder()) {
        acc[0] += *m * x[c.at()];
    }
    acc[0] + acc[1]
}

/// Start offsets (length `n + 1`) of the columns of a pattern given the column of each
/// entry (`keys`, each below `n`): a counting sort's prefix sums.
pub(super) fn column_offsets(keys: &[u32], n: usize) -> Vec<u32> {
    let mut ptr = vec![0u32; n + 1];
    for &k in keys {
        ptr[k as usize + 1] += 1;
    }
    for j in 0..n {
        ptr[j + 1] += ptr[j];
    }
    ptr
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A random-ish block matrix on a ring-of-rings graph, diagonally dominant.
    #[test]
    // Index arithmetic over several arrays reads better with indices.
    #[allow(clippy::needless_range_loop)]
    fn solves_a_block_system() {
        let n = 40usize;
        // Graph: cycle plus chords i -- i+7.
        let mut nb: Vec<Vec<u32>> = vec![Vec::new(); n];
        let mut link = |a: usize, b: usize| {
            if a != b && !nb[a].contains(&(b as u32)) {
                nb[a].push(b as u32);
                nb[b].push(a as u32);
            }
        };
        for i in 0..n {
            link(i, (i + 1) % n);
            link(i, (i + 7) % n);
        }
        let mut adj_ptr = vec![0u32];
        let mut adj = Vec::new();
        for l in &nb {
            adj.extend_from_slice(l);
            adj_ptr.push(adj.len() as u32);
        }
        // Column-wise blocks: diagonal 4 I + small skew, off-diagonal deterministic.
        let block = |r: usize, c: usize| -> DMat3 {
            if r == c {
                DMat3::from_diagonal(DVec3::splat(6.0))
                    + DMat3::from_cols_array(&[0.0, 0.3, 0.0, -0.3, 0.0, 0.1, 0.0, -0.1, 0.0])
            } else {
                let s = ((r * 31 + c * 17) % 11) as f64 / 11.0 - 0.5;
                DMat3::from_cols_array(&[s, 0.1, -0.2, 0.05, s * 0.5, 0.0, 0.3, -s, 0.2])
            }
        };
        let mut col_ptr = vec![0u32];
        let mut col_row = Vec::new();
        let mut col_slot = Vec::new();
        let mut vals = Vec::new();
        for c in 0..n {
            let mut rows: Vec<usize> = nb[c].iter().map(|&x| x as usize).collect();
            rows.push(c);
            for r in rows {
                col_row.push(r as u32);
                col_slot.push(vals.len() as u32);
                vals.push(block(r, c));
            }
            col_ptr.push(col_row.len() as u32);
        }
        let x_true: Vec<DVec3> = (0..n)
            .map(|i| DVec3::new(i as f64, (i * i % 7) as f64, 1.0 - i as f64 * 0.1))
            .collect();
        let mut rhs = vec![DVec3::ZERO; n];
        for c in 0..n {
            for e in col_ptr[c] as usize..col_ptr[c + 1] as usize {
                rhs[col_row[e] as usize] += vals[col_slot[e] as usize] * x_true[c];
            }
        }
        // Exact (every block kept): f32 rounding only. With the decoder's drop tolerance
        // the solve is an approximation of the same order as the dropped blocks, relative
        // to the largest unknown (the decoder only uses it for chord steps).
        for (drop, tol) in [(0.0, 1e-5), (DROP_REL, 1e-2)] {
            let mut lu = BlockLu::analyse(&adj_ptr, &adj, drop).unwrap();
            lu.factor(&col_ptr, &col_row, &col_slot, &vals).unwrap();
            let mut b = rhs.clone();
            lu.solve_in_place(&mut b);
            let largest = x_true.iter().map(|t| t.length()).fold(1.0, f64::max);
            let err = b
                .iter()
                .zip(&x_true)
                .map(|(a, t)| {
                    // Exact: relative to each unknown; dropped: to the largest one.
                    let scale = if drop == 0.0 {
                        t.length().max(1.0)
                    } else {
                        largest
                    };
                    (*a - *t).length() / scale
                })
                .fold(0.0, f64::max);
            assert!(err < tol, "drop {drop}: relative error {err}");
        }
    }

    #[test]
    fn singular_pivot_is_reported() {
        let adj_ptr = vec![0u32, 1, 2];
        let adj = vec![1u32, 0];
        let mut lu = BlockLu::analyse(&adj_ptr, &adj, 0.0).unwrap();
        let col_ptr = vec![0u32, 2, 4];
        let col_row = vec![0u32, 1, 0, 1];
        let col_slot = vec![0u32, 1, 2, 3];
        // [[I, I], [I, I]] is singular: the second pivot is zero.
        let vals = vec![DMat3::IDENTITY; 4];
        assert!(matches!(
            lu.factor(&col_ptr, &col_row, &col_slot, &vals),
            Err(BlockLuError::SingularPivot(_))
        ));
    }
}
