//! Anderson acceleration (type II, windowed) of a fixed-point map on vertex positions,
//! metres. The fast decoder's frozen-weight Gauss-Newton step `x -> G(x)` is a fixed-point
//! map whose linearisation can have a few local modes with gain above one (a pair of
//! almost coincident vertices on a steep step, e.g. between fingers, where the normal
//! term `|p - v_i'| b_i` reacts strongly to small in-plane moves). Plain iteration then
//! diverges there while the paper's local sweeps do not; Anderson mixing of the last
//! [`ANDERSON_DEPTH`] steps removes such modes (for a linear map it is GMRES) and costs a
//! few dot products per step. Walker and Ni, "Anderson acceleration for fixed-point
//! iterations", SIAM J. Numer. Anal. 2011.

use glam::DVec3;

/// Number of past steps mixed.
pub(crate) const ANDERSON_DEPTH: usize = 16;
/// Ridge on the mixing least squares, relative to its trace.
const MIXING_RIDGE: f64 = 1e-10;

/// Scratch and history of the acceleration; owned by the deformer, no per-step allocation.
pub(crate) struct Anderson {
    n: usize,
    dg: Vec<DVec3>,
    df: Vec<DVec3>,
    g_prev: Vec<DVec3>,
    f_prev: Vec<DVec3>,
    /// Dot products of the stored residual differences, by slot.
    gram: [[f64; ANDERSON_DEPTH]; ANDERSON_DEPTH],
    count: usize,
    head: usize,
    has_prev: bool,
    /// Largest fixed-point residual of the previous step (for the restart safeguard).
    last_residual: f64,
}

/// The history is dropped when the fixed-point residual grows by more than this factor
/// in one step (stale or misleading differences).
const RESTART_GROWTH: f64 = 2.0;

impl Anderson {
    pub(crate) fn new(n: usize) -> Self {
        Anderson {
            n,
            dg: vec![DVec3::ZERO; ANDERSON_DEPTH * n],
            df: vec![DVec3::ZERO; ANDERSON_DEPTH * n],
            g_prev: vec![DVec3::ZERO; n],
            f_prev: vec![DVec3::ZERO; n],
            gram: [[0.0; ANDERSON_DEPTH]; ANDERSON_DEPTH],
            count: 0,
            head: 0,
            has_prev: false,
            last_residual: f64::INFINITY,
        }
    }

    /// Forgets the history (start of a solve, new control set).
    pub(crate) fn reset(&mut self) {
        self.last_residual = f64::INFINITY;
        self.count = 0;
        self.head = 0;
        self.has_prev = false;
    }

    /// Sizes the history for `n` free vertices and forgets it.
    pub(crate) fn resize(&mut self, n: usize) {
        self.n = n;
        self.dg.resize(ANDERSON_DEPTH * n, DVec3::ZERO);
        self.df.resize(ANDERSON_DEPTH * n, DVec3::ZERO);
        self.g_prev.resize(n, DVec3::ZERO);
        self.f_prev.resize(n, DVec3::ZERO);
        self.reset();
    }

    /// Given the iterate `x` and `g = G(x)`, writes the mixed next iterate into `x`; only
    /// the vertices listed in `free` take part (the others are fixed, equal in both).
    /// Returns (largest move, largest fixed-point residual `|G(x) - x|`).
    pub(crate) fn step(
        &mut self,
        x_all: &mut [DVec3],
        g_all: &[DVec3],
        free: &[u32],
    ) -> (f64, f64) {
        let n = self.n;
        debug_assert_eq!(n, free.len());
        let x = |k: usize, xs: &[DVec3]| xs[free[k] as usize];
        let mut fmax = 0.0f64;
        for v in 0..n {
            fmax = fmax.max((g_all[free[v] as usize] - x(v, x_all)).length_squared());
        }
        let fmax = fmax.sqrt();
        if fmax > RESTART_GROWTH * self.last_residual {
            self.count = 0;
            self.head = 0;
            self.has_prev = false;
        }
        self.last_residual = fmax;
        if self.has_prev {
            let col = self.head * n;
            for v in 0..n {
                let f = g_all[free[v] as usize] - x(v, x_all);
                self.df[col + v] = f - self.f_prev[v];
                self.dg[col + v] = g_all[free[v] as usize] - self.g_prev[v];
            }
            let slot = self.head;
            self.head = (self.head + 1) % ANDERSON_DEPTH;
            self.count = (self.count + 1).min(ANDERSON_DEPTH);
            let new = &self.df[col..col + n];
            for j in 0..self.count {
                let dj = &self.df[j * n..(j + 1) * n];
                let d: f64 = new.iter().zip(dj).map(|(p, q)| p.dot(*q)).sum();
                self.gram[slot][j] = d;
                self.gram[j][slot] = d;
            }
        }
        for v in 0..n {
            let f = g_all[free[v] as usize] - x(v, x_all);
            self.f_prev[v] = f;
            self.g_prev[v] = g_all[free[v] as usize];
        }
        self.has_prev = true;
        let k = self.count;
        let mut gamma = [0.0f64; ANDERSON_DEPTH];
        if k > 0 && self.solve_mixing(&mut gamma).is_none() {
            gamma = [0.0; ANDERSON_DEPTH];
        }
        let mut max_move = 0.0f64;
        for v in 0..n {
            let gv = g_all[free[v] as usize];
            let mut next = gv;
            for (j, gj) in gamma.iter().enumerate().take(k) {
                next -= *gj * self.dg[j * n + v];
            }
            if !next.is_finite() {
                next = gv;
            }
            let mv = (next - x(v, x_all)).length_squared();
            if !(mv <= max_move) {
                max_move = mv;
            }
            x_all[free[v] as usize] = next;
        }
        (max_move.sqrt(), fmax)
    }

    /// gamma = argmin |f - DF gamma| through the ridge-regularised normal equations.
    // Elimination over the rows of `a`, `df`, `gram` and `gamma`: index arithmetic reads
    // better with indices.
    #[allow(clippy::needless_range_loop)]
    fn solve_mixing(&self, gamma: &mut [f64; ANDERSON_DEPTH]) -> Option<()> {
        let (n, k) = (self.n, self.count);
        let mut a = [[0.0f64; ANDERSON_DEPTH + 1]; ANDERSON_DEPTH];
        for i in 0..k {
            let di = &self.df[i * n..(i + 1) * n];
            a[i][..k].copy_from_slice(&self.gram[i][..k]);
            a[i][k] = di.iter().zip(&self.f_prev).map(|(p, q)| p.dot(*q)).sum();
        }
        let trace: f64 = (0..k).map(|i| a[i][i]).sum();
        if !(trace > 0.0) {
            return None;
        }
        for (i, row) in a.iter_mut().enumerate().take(k) {
            row[i] += MIXING_RIDGE * trace;
        }
        // Gaussian elimination with partial pivoting on the k x (k+1) system.
        for c in 0..k {
            let p = (c..k).max_by(|&i, &j| a[i][c].abs().total_cmp(&a[j][c].abs()))?;
            a.swap(c, p);
            if a[c][c] == 0.0 {
                return None;
            }
            for r in c + 1..k {
                let f = a[r][c] / a[c][c];
                for cc in c..=k {
                    a[r][cc] -= f * a[c][cc];
                }
            }
        }
        for c in (0..k).rev() {
            let mut s = a[c][k];
            for cc in c + 1..k {
                s -= a[c][cc] * gamma[cc];
            }
            gamma[c] = s / a[c][c];
        }
        gamma[..k].iter().all(|g| g.is_finite()).then_some(())
    }

    pub(crate) fn heap_bytes(&self) -> usize {
        (2 * ANDERSON_DEPTH + 2) * self.n * 24
    }
}
