//! Closed-form start of the calibration: plane-to-image homographies and Zhang's
//! intrinsics (Z. Zhang, "A flexible new technique for camera calibration", IEEE PAMI
//! 22(11), 2000), then each view's pose from its homography.
//!
//! Units: board points in metres (z = 0), pixels as OpenCV. Lens distortion is ignored
//! here; the Levenberg-Marquardt step ([`super::bundle`]) adds it.

use super::linalg::{nearest_rotation, null_vector};
use crate::camera::Rigid;
use glam::{DMat3, DVec2, DVec3};

/// Fewest point pairs for a homography.
pub const MIN_HOMOGRAPHY_POINTS: usize = 4;
/// Zhang's solution is rejected (fall back to a centred principal point) when the focal
/// lengths differ by more than this ratio or the principal point leaves the image.
pub const MAX_FOCAL_RATIO: f64 = 1.5;

/// Row-major 3x3 homography mapping board (x, y, 1) to pixels.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Homography(pub DMat3);

impl Homography {
    pub fn apply(&self, p: DVec2) -> DVec2 {
        let q = self.0 * DVec3::new(p.x, p.y, 1.0);
        DVec2::new(q.x / q.z, q.y / q.z)
    }
}

/// Similarity that moves points to zero mean and mean distance sqrt 2 (Hartley).
fn normaliser(pts: &[DVec2]) -> DMat3 {
    let n = pts.len().max(1) as f64;
    let mean = pts.iter().copied().sum::<DVec2>() / n;
    let spread = pts.iter().map(|p| (*p - mean).length()).sum::<f64>() / n;
    let s = if spread > 1e-12 {
        std::f64::consts::SQRT_2 / spread
    } else {
        1.0
    };
    DMat3::from_cols(
        DVec3::new(s, 0.0, 0.0),
        DVec3::new(0.0, s, 0.0),
        DVec3::new(-s * mean.x, -s * mean.y, 1.0),
    )
}

/// Normalised DLT homography from board points (metres, z ignored) to pixels.
/// None with fewer than four points or a degenerate configuration.
pub fn homography(board: &[DVec2], image: &[DVec2]) -> Option<Homography> {
    if board.len() < MIN_HOMOGRAPHY_POINTS || board.len() != image.len() {
        return None;
    }
    let tb = normaliser(board);
    let ti = normaliser(image);
    let mut a = Vec::with_capacity(board.len() * 18);
    for (b, i) in board.iter().zip(image) {
        let p = tb * DVec3::new(b.x, b.y, 1.0);
        let q = ti * DVec3::new(i.x, i.y, 1.0);
        a.extend_from_slice(&[p.x, p.y, 1.0, 0.0, 0.0, 0.0, -q.x * p.x, -q.x * p.y, -q.x]);
        a.extend_from_slice(&[0.0, 0.0, 0.0, p.x, p.y, 1.0, -q.y * p.x, -q.y * p.y, -q.y]);
    }
    let h = null_vector(&a, 9).x;
    if h.len() != 9 {
        return None;
    }
    let hn = DMat3::from_cols(
        DVec3::new(h[0], h[3], h[6]),
        DVec3::new(h[1], h[4], h[7]),
        DVec3::new(h[2], h[5], h[8]),
    );
    let full = ti.inverse() * hn * tb;
    let scale = full.z_axis.z;
    if !full.is_finite() || scale.abs() < 1e-300 {
        return None;
    }
    Some(Homography(full * (1.0 / scale)))
}

/// Pinhole intrinsics without distortion.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Pinhole {
    pub fx: f64,
    pub fy: f64,
    pub cx: f64,
    pub cy: f64,
}

impl Pinhole {
    pub fn k(&self) -> DMat3 {
        DMat3::from_cols(
            DVec3::new(self.fx, 0.0, 0.0),
            DVec3::new(0.0, self.fy, 0.0),
            DVec3::new(self.cx, self.cy, 1.0),
        )
    }
}

/// How the start was obtained.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum StartMethod {
    /// Zhang's closed form (all of fx, fy, cx, cy from the views).
    Zhang,
    /// Zhang's solution was implausible: principal point at the image centre, focal
    /// lengths from the orthogonality constraints alone.
    CentredPrincipalPoint,
}

/// Closed-form start from the homographies.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ClosedForm {
    pub pinhole: Pinhole,
    pub method: StartMethod,
}

/// `v_ij` of Zhang's eq. (8) for homography columns i, j (0-based).
fn v_ij(h: &DMat3, i: usize, j: usize) -> [f64; 6] {
    let hi = h.col(i);
    let hj = h.col(j);
    [
        hi.x * hj.x,
        hi.x * hj.y + hi.y * hj.x,
        hi.y * hj.y,
        hi.z * hj.x + hi.x * hj.z,
        hi.z * hj.y + hi.y * hj.z,
        hi.z * hj.z,
    ]
}

/// Zhang's closed-form intrinsics (sec. 3.1, eqs. (8)-(9) and Appendix B), with zero
/// skew imposed as an extra row (sec. 3.1, "if gamma = 0"). Falls back to a principal
/// point at the image centre when the solution is implausible (too few or too similar
/// views). None when even that fails (all views parallel to the image).
pub fn closed_form(homographies: &[Homography], width: u32, height: u32) -> Option<ClosedForm> {
    let (w, h) = (width as f64, height as f64);
    // Work on pixel coordinates scaled to ~1 for conditioning.
    let s = 1.0 / w.max(h);
    let scale = DMat3::from_diagonal(DVec3::new(s, s, 1.0));
    let hs: Vec<DMat3> = homographies.iter().map(|hm| scale * hm.0).collect();
    let mut rows = Vec::with_capacity(hs.len() * 12 + 6);
    for hm in &hs {
        let v12 = v_ij(hm, 0, 1);
        let v11 = v_ij(hm, 0, 0);
        let v22 = v_ij(hm, 1, 1);
        rows.extend_from_slice(&v12);
        rows.extend((0..6).map(|k| v11[k] - v22[k]));
    }
    rows.extend_from_slice(&[0.0, 1.0, 0.0, 0.0, 0.0, 0.0]);
    let plausible = |p: &Pinhole| {
        p.fx.is_finite()
            && p.fy.is_finite()
            && p.fx > 0.0
            && p.fy > 0.0
            && p.fx / p.fy < MAX_FOCAL_RATIO
            && p.fy / p.fx < MAX_FOCAL_RATIO
            && p.cx > 0.0
            && p.cy > 0.0
            && p.cx < w
            && p.cy < h
    };
    if hs.len() >= 3 {
        let b = null_vector(&rows, 6).x;
        if let Some(p) = zhang_appendix_b(&b) {
            let p = Pinhole {
                fx: p.fx / s,
                fy: p.fy / s,
                cx: p.cx / s,
                cy: p.cy / s,
            };
            if plausible(&p) {
                return Some(ClosedForm {
                    pinhole: p,
                    method: StartMethod::Zhang,
                });
            }
        }
    }
    let p = centred_focal(&hs, 0.5 * (w - 1.0) * s, 0.5 * (h - 1.0) * s)?;
    let p = Pinhole {
        fx: p.fx / s,
        fy: p.fy / s,
        cx: p.cx / s,
        cy: p.cy / s,
    };
    plausible(&p).then_some(ClosedForm {
        pinhole: p,
        method: StartMethod::CentredPrincipalPoint,
    })
}

/// Zhang's Appendix B: intrinsics from b = (B11, B12, B22, B13, B23, B33).
fn zhang_appendix_b(b: &[f64]) -> Option<Pinhole> {
    if b.len() != 6 {
        return None;
    }
    let mut b = b.to_vec();
    if b[0] < 0.0 {
        b.iter_mut().for_each(|x| *x = -*x);
    }
    let (b11, b12, b22, b13, b23, b33) = (b[0], b[1], b[2], b[3], b[4], b[5]);
    let den = b11 * b22 - b12 * b12;
    if den.abs() < 1e-300 || b11.abs() < 1e-300 {
        return None;
    }
    let v0 = (b12 * b13 - b11 * b23) / den;
    let lambda = b33 - (b13 * b13 + v0 * (b12 * b13 - b11 * b23)) / b11;
    let alpha2 = lambda / b11;
    let beta2 = lambda * b11 / den;
    if alpha2 <= 0.0 || beta2 <= 0.0 {
        return None;
    }
    let alpha = alpha2.sqrt();
    let beta = beta2.sqrt();
    let gamma = -b12 * alpha2 * beta / lambda;
    let u0 = gamma * v0 / beta - b13 * alpha2 / lambda;
    Some(Pinhole {
        fx: alpha,
        fy: beta,
        cx: u0,
        cy: v0,
    })
}

/// Focal lengths with a known principal point (cx, cy): with H' = T H (T moves the
/// principal point to the origin), `h1ᵀ B h2 = 0` and `h1ᵀ B h1 = h2ᵀ B h2` with
/// B = diag(1/fx², 1/fy², 1) are linear in (1/fx², 1/fy²); least squares over views.
fn centred_focal(hs: &[DMat3], cx: f64, cy: f64) -> Option<Pinhole> {
    let t = DMat3::from_cols(DVec3::X, DVec3::Y, DVec3::new(-cx, -cy, 1.0));
    let (mut a11, mut a12, mut a22, mut r1, mut r2) = (0.0, 0.0, 0.0, 0.0, 0.0);
    for hm in hs {
        let m = t * *hm;
        let (h1, h2) = (m.col(0), m.col(1));
        // Normalise each view's equations so that views weigh alike.
        let n = (h1.length() * h2.length()).max(1e-300);
        let eqs = [
            (h1.x * h2.x / n, h1.y * h2.y / n, -(h1.z * h2.z) / n),
            (
                (h1.x * h1.x - h2.x * h2.x) / n,
                (h1.y * h1.y - h2.y * h2.y) / n,
                -(h1.z * h1.z - h2.z * h2.z) / n,
            ),
        ];
        for (a, b, r) in eqs {
            a11 += a * a;
            a12 += a * b;
            a22 += b * b;
            r1 += a * r;
            r2 += b * r;
        }
    }
    let det = a11 * a22 - a12 * a12;
    if det.abs() < 1e-300 {
        return None;
    }
    let ifx2 = (a22 * r1 - a12 * r2) / det;
    let ify2 = (a11 * r2 - a12 * r1) / det;
    if ifx2 <= 0.0 || ify2 <= 0.0 {
        return None;
    }
    Some(Pinhole {
        fx: 1.0 / ifx2.sqrt(),
        fy: 1.0 / ify2.sqrt(),
        cx,
        cy,
    })
}

/// A view's pose from its homography and K (Zhang sec. 3.1, eq. (2)): r1 = λ K⁻¹h1,
/// r2 = λ K⁻¹h2, r3 = r1 × r2, t = λ K⁻¹h3, then the nearest rotation. The sign is
/// chosen so the board lies in front of the camera.
pub fn pose_from_homography(h: &Homography, k: &DMat3) -> Option<Rigid> {
    let a = k.inverse() * h.0;
    let (a1, a2, a3) = (a.col(0), a.col(1), a.col(2));
    let norm = 0.5 * (a1.length() + a2.length());
    if norm < 1e-300 || !norm.is_finite() {
        return None;
    }
    let mut lambda = 1.0 / norm;
    if a3.z * lambda < 0.0 {
        lambda = -lambda;
    }
    let r1 = a1 * lambda;
    let r2 = a2 * lambda;
    let r3 = r1.cross(r2);
    let rotation = nearest_rotation(&DMat3::from_cols(r1, r2, r3));
    if !rotation.is_finite() || rotation.determinant() <= 0.0 {
        return None;
    }
    Some(Rigid {
        rotation,
        translation: a3 * lambda,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::camera::Intrinsics;

    #[test]
    fn zhang_recovers_a_pinhole_from_exact_views() {
        let intr = Intrinsics {
            width: 1280,
            height: 720,
            fx: 1000.0,
            fy: 990.0,
            cx: 650.0,
            cy: 350.0,
            dist: [0.0; 5],
        };
        let board: Vec<DVec2> = (0..6)
            .flat_map(|r| (0..9).map(move |c| DVec2::new(c as f64 * 0.03, r as f64 * 0.03)))
            .collect();
        let poses = [(0.3, 0.1), (-0.25, 0.2), (0.1, -0.35), (-0.2, -0.2)];
        let hs: Vec<Homography> = poses
            .iter()
            .map(|&(ax, ay)| {
                let rot = DMat3::from_rotation_x(ax) * DMat3::from_rotation_y(ay);
                let t = DVec3::new(-0.12, -0.08, 0.8);
                let img: Vec<DVec2> = board
                    .iter()
                    .map(|p| {
                        intr.project_camera_point(rot * DVec3::new(p.x, p.y, 0.0) + t)
                            .unwrap()
                    })
                    .collect();
                homography(&board, &img).unwrap()
            })
            .collect();
        let cf = closed_form(&hs, 1280, 720).unwrap();
        assert_eq!(cf.method, StartMethod::Zhang);
        let p = cf.pinhole;
        assert!(
            (p.fx - 1000.0).abs() < 1e-3 && (p.fy - 990.0).abs() < 1e-3,
            "{p:?}"
        );
        assert!(
            (p.cx - 650.0).abs() < 1e-3 && (p.cy - 350.0).abs() < 1e-3,
            "{p:?}"
        );
        let pose = pose_from_homography(&hs[0], &p.k()).unwrap();
        assert!((pose.translation - DVec3::new(-0.12, -0.08, 0.8)).length() < 1e-6);
    }
}
