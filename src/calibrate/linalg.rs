//! Small dense linear algebra for calibration: symmetric eigen-decomposition (cyclic
//! Jacobi), Cholesky solves of damped normal equations, Rodrigues rotation vectors and
//! the nearest rotation to a 3x3 matrix. Sizes here are tiny (at most a few hundred
//! unknowns), so plain row-major `Vec<f64>` matrices are enough.

use glam::{DMat3, DVec3};

/// Eigen-decomposition of a symmetric `n x n` row-major matrix by cyclic Jacobi sweeps.
/// Returns eigenvalues (ascending) and the matching unit eigenvectors.
pub fn symmetric_eigen(a: &[f64], n: usize) -> (Vec<f64>, Vec<Vec<f64>>) {
    const MAX_SWEEPS: usize = 100;
    let mut m = a.to_vec();
    let mut v = vec![0.0; n * n];
    for i in 0..n {
        v[i * n + i] = 1.0;
    }
    for _ in 0..MAX_SWEEPS {
        let mut off = 0.0;
        let mut diag = 0.0;
        for i in 0..n {
            diag += m[i * n + i] * m[i * n + i];
            for j in (i + 1)..n {
                off += m[i * n + j] * m[i * n + j];
            }
        }
        if off <= 1e-30 * diag.max(1e-300) {
            break;
        }
        for p in 0..n {
            for q in (p + 1)..n {
                let apq = m[p * n + q];
                if apq.abs() < 1e-300 {
                    continue;
                }
                let app = m[p * n + p];
                let aqq = m[q * n + q];
                let theta = (aqq - app) / (2.0 * apq);
                let t = theta.signum() / (theta.abs() + (theta * theta + 1.0).sqrt());
                let t = if theta == 0.0 { 1.0 } else { t };
                let c = 1.0 / (t * t + 1.0).sqrt();
                let s = t * c;
                for k in 0..n {
                    let mkp = m[k * n + p];
                    let mkq = m[k * n + q];
                    m[k * n + p] = c * mkp - s * mkq;
                    m[k * n + q] = s * mkp + c * mkq;
                }
                for k in 0..n {
                    let mpk = m[p * n + k];
                    let mqk = m[q * n + k];
                    m[p * n + k] = c * mpk - s * mqk;
                    m[q * n + k] = s * mpk + c * mqk;
                }
                for k in 0..n {
                    let vkp = v[k * n + p];
                    let vkq = v[k * n + q];
                    v[k * n + p] = c * vkp - s * vkq;
                    v[k * n + q] = s * vkp + c * vkq;
                }
            }
        }
    }
    let mut order: Vec<usize> = (0..n).collect();
    order.sort_by(|&x, &y| m[x * n + x].total_cmp(&m[y * n + y]));
    let values = order.iter().map(|&i| m[i * n + i]).collect();
    let vectors = order
        .iter()
        .map(|&i| (0..n).map(|k| v[k * n + i]).collect())
        .collect();
    (values, vectors)
}

/// Unit vector `x` minimising `|A x|` for a row-major `rows x n` matrix `A` (the
/// eigenvector of `AᵀA` with the smallest eigenvalue), with the ratio of the two
/// smallest eigenvalues (small means well determined).
pub struct NullVector {
    pub x: Vec<f64>,
    /// smallest / second-smallest eigenvalue of AᵀA.
    pub conditioning: f64,
}

pub fn null_vector(a: &[f64], n: usize) -> NullVector {
    let rows = a.len() / n;
    let mut ata = vec![0.0; n * n];
    for r in 0..rows {
        let row = &a[r * n..(r + 1) * n];
        for i in 0..n {
            for j in i..n {
                ata[i * n + j] += row[i] * row[j];
            }
        }
    }
    for i in 0..n {
        for j in 0..i {
            ata[i * n + j] = ata[j * n + i];
        }
    }
    let (vals, vecs) = symmetric_eigen(&ata, n);
    let conditioning = if n > 1 && vals[1].abs() > 0.0 {
        vals[0].abs() / vals[1].abs()
    } else {
        1.0
    };
    NullVector {
        x: vecs.into_iter().next().unwrap_or_default(),
        conditioning,
    }
}

/// In-place Cholesky factorisation of a symmetric positive definite row-major matrix
/// (lower triangle). Returns false when the matrix is not positive definite.
pub fn cholesky(a: &mut [f64], n: usize) -> bool {
    for j in 0..n {
        let mut d = a[j * n + j];
        for k in 0..j {
            d -= a[j * n + k] * a[j * n + k];
        }
        if d <= 0.0 || !d.is_finite() {
            return false;
        }
        let d = d.sqrt();
        a[j * n + j] = d;
        for i in (j + 1)..n {
            let mut s = a[i * n + j];
            for k in 0..j {
                s -= a[i * n + k] * a[j * n + k];
            }
            a[i * n + j] = s / d;
        }
    }
    true
}

/// Solves `L Lᵀ x = b` in place with the factor from [`cholesky`].
pub fn cholesky_solve(l: &[f64], n: usize, b: &mut [f64]) {
    for i in 0..n {
        let mut s = b[i];
        for k in 0..i {
            s -= l[i * n + k] * b[k];
        }
        b[i] = s / l[i * n + i];
    }
    for i in (0..n).rev() {
        let mut s = b[i];
        for k in (i + 1)..n {
            s -= l[k * n + i] * b[k];
        }
        b[i] = s / l[i * n + i];
    }
}

/// Skew-symmetric cross-product matrix of `v`.
fn skew(v: DVec3) -> DMat3 {
    DMat3::from_cols(
        DVec3::new(0.0, v.z, -v.y),
        DVec3::new(-v.z, 0.0, v.x),
        DVec3::new(v.y, -v.x, 0.0),
    )
}

/// Rotation matrix of a Rodrigues vector (axis times angle in radians).
pub fn rotation_from_rodrigues(r: DVec3) -> DMat3 {
    let theta = r.length();
    if theta < 1e-12 {
        return DMat3::IDENTITY + skew(r);
    }
    let k = r / theta;
    let (s, c) = theta.sin_cos();
    DMat3::IDENTITY * c + skew(k) * s + outer(k, k) * (1.0 - c)
}

fn outer(a: DVec3, b: DVec3) -> DMat3 {
    DMat3::from_cols(a * b.x, a * b.y, a * b.z)
}

/// Rodrigues vector of a rotation matrix.
pub fn rodrigues_from_rotation(r: &DMat3) -> DVec3 {
    let cos = ((r.x_axis.x + r.y_axis.y + r.z_axis.z - 1.0) * 0.5).clamp(-1.0, 1.0);
    let theta = cos.acos();
    // vee(R - Rᵀ) / 2 = sin(theta) k
    let w = DVec3::new(
        r.y_axis.z - r.z_axis.y,
        r.z_axis.x - r.x_axis.z,
        r.x_axis.y - r.y_axis.x,
    ) * 0.5;
    if theta < 1e-8 {
        return w;
    }
    if std::f64::consts::PI - theta > 1e-4 {
        return w * (theta / theta.sin());
    }
    // Near pi: R + I = 2 k kᵀ (approximately); take the largest column.
    let b = *r + DMat3::IDENTITY;
    let cols = [b.x_axis, b.y_axis, b.z_axis];
    let best = cols
        .iter()
        .copied()
        .max_by(|a, c| a.length_squared().total_cmp(&c.length_squared()))
        .unwrap_or(DVec3::X);
    let mut k = best.normalize_or(DVec3::X);
    if k.dot(w) < 0.0 {
        k = -k;
    }
    k * theta
}

/// The rotation nearest to `m` (polar factor), by Newton iteration `X <- (X + X⁻ᵀ)/2`.
pub fn nearest_rotation(m: &DMat3) -> DMat3 {
    let mut x = *m;
    for _ in 0..30 {
        let det = x.determinant();
        if det.abs() < 1e-300 {
            break;
        }
        let next = (x + x.inverse().transpose()) * 0.5;
        let change = (next - x)
            .to_cols_array()
            .iter()
            .map(|e| e.abs())
            .fold(0.0, f64::max);
        x = next;
        if change < 1e-15 {
            break;
        }
    }
    x
}

/// Angle in degrees of the rotation `a * bᵀ` (how far two rotations differ).
pub fn rotation_angle_deg(a: &DMat3, b: &DMat3) -> f64 {
    rodrigues_from_rotation(&(*a * b.transpose()))
        .length()
        .to_degrees()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn eigen_reconstructs_a_symmetric_matrix() {
        let a = [4.0, 1.0, 0.5, 1.0, 3.0, -0.2, 0.5, -0.2, 1.0];
        let (vals, vecs) = symmetric_eigen(&a, 3);
        assert!(vals[0] <= vals[1] && vals[1] <= vals[2]);
        for (l, v) in vals.iter().zip(&vecs) {
            for i in 0..3 {
                let av: f64 = (0..3).map(|k| a[i * 3 + k] * v[k]).sum();
                assert!((av - l * v[i]).abs() < 1e-10);
            }
        }
    }

    #[test]
    fn cholesky_solves() {
        let a = [4.0, 1.0, 0.5, 1.0, 3.0, -0.2, 0.5, -0.2, 1.0];
        let mut l = a;
        assert!(cholesky(&mut l, 3));
        let mut b = [1.0, 2.0, 3.0];
        cholesky_solve(&l, 3, &mut b);
        for i in 0..3 {
            let r: f64 = (0..3).map(|k| a[i * 3 + k] * b[k]).sum();
            assert!((r - [1.0, 2.0, 3.0][i]).abs() < 1e-12);
        }
    }

    #[test]
    fn rodrigues_round_trips() {
        for r in [
            DVec3::new(0.1, -0.2, 0.3),
            DVec3::new(0.0, 3.1, 0.0),
            DVec3::new(1e-10, 0.0, 0.0),
            DVec3::new(2.0, 1.0, -1.5),
        ] {
            let m = rotation_from_rodrigues(r);
            assert!((m * m.transpose() - DMat3::IDENTITY)
                .to_cols_array()
                .iter()
                .all(|e| e.abs() < 1e-12));
            let back = rodrigues_from_rotation(&m);
            assert!(
                rotation_angle_deg(&rotation_from_rodrigues(back), &m) < 1e-6,
                "{r} -> {back}"
            );
        }
    }

    #[test]
    fn nearest_rotation_fixes_a_perturbed_rotation() {
        let r = rotation_from_rodrigues(DVec3::new(0.3, 0.2, -0.1));
        let m =
            r * 1.0 + DMat3::from_cols_array(&[1e-3, 0.0, 2e-3, 0.0, -1e-3, 0.0, 0.0, 1e-3, 0.0]);
        let q = nearest_rotation(&m);
        assert!((q * q.transpose() - DMat3::IDENTITY)
            .to_cols_array()
            .iter()
            .all(|e| e.abs() < 1e-12));
        assert!(rotation_angle_deg(&q, &r) < 0.3);
    }
}
