//! Levenberg-Marquardt refinement of intrinsics (fx fy cx cy, OpenCV's k1 k2 p1 p2 k3)
//! and every view's pose, minimising the summed squared reprojection error in pixels
//! (Zhang 2000, sec. 3.2-3.3, eq. (10) with eq. (11)'s radial terms extended to
//! OpenCV's five coefficients; Marquardt's damping `A + λ diag(A)`).
//!
//! Parameters: intrinsics first (9), then per view a Rodrigues vector (radians) and a
//! translation (metres), `x_cam = R(r) x_board + t`. The Jacobian is by central
//! differences; it is block sparse (a view's residuals depend on the intrinsics and on
//! that view's pose only), so the normal equations are accumulated block by block and
//! solved densely (at most a few hundred unknowns).

use super::linalg::{cholesky, cholesky_solve, rodrigues_from_rotation, rotation_from_rodrigues};
use crate::camera::{Intrinsics, Rigid};
use glam::{DVec2, DVec3};

/// Number of intrinsic parameters (fx fy cx cy k1 k2 p1 p2 k3).
pub const N_INTRINSIC: usize = 9;
/// Names of the intrinsic parameters, in order.
pub const INTRINSIC_NAMES: [&str; N_INTRINSIC] =
    ["fx", "fy", "cx", "cy", "k1", "k2", "p1", "p2", "k3"];
/// Parameters per view pose.
const N_POSE: usize = 6;
/// Largest number of LM iterations.
pub const MAX_ITERATIONS: usize = 100;
/// Stop when an iteration lowers the cost by less than this fraction.
pub const MIN_RELATIVE_DECREASE: f64 = 1e-12;
/// Initial and extreme Marquardt damping.
const LAMBDA_START: f64 = 1e-3;
const LAMBDA_MAX: f64 = 1e12;
/// Relative step of the numerical derivatives.
const DIFF_STEP: f64 = 1e-6;

/// Which intrinsic parameters move.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum IntrinsicsMode {
    /// All nine (OpenCV `calibrateCamera` with flags = 0).
    AllFree,
    /// None: only the poses move (pose estimation with a calibrated camera).
    Fixed,
}

/// The corners of one view: board points (metres) and their pixels.
#[derive(Debug, Clone, PartialEq)]
pub struct ViewObservations {
    pub object: Vec<DVec3>,
    pub image: Vec<DVec2>,
}

/// Result of a refinement.
#[derive(Debug, Clone, PartialEq)]
pub struct BundleResult {
    pub intrinsics: Intrinsics,
    /// `camera_from_board` of each view.
    pub poses: Vec<Rigid>,
    /// sqrt(sum of squared pixel errors / number of points), as OpenCV reports.
    pub rms_px: f64,
    pub per_view_rms_px: Vec<f64>,
    /// One standard deviation of each intrinsic parameter (0 when fixed), from the
    /// inverse normal matrix scaled by the residual variance.
    pub std_dev: [f64; N_INTRINSIC],
    pub iterations: usize,
}

fn intrinsics_to_vec(i: &Intrinsics) -> [f64; N_INTRINSIC] {
    [
        i.fx, i.fy, i.cx, i.cy, i.dist[0], i.dist[1], i.dist[2], i.dist[3], i.dist[4],
    ]
}

fn intrinsics_from(x: &[f64], like: &Intrinsics) -> Intrinsics {
    Intrinsics {
        width: like.width,
        height: like.height,
        fx: x[0],
        fy: x[1],
        cx: x[2],
        cy: x[3],
        dist: [x[4], x[5], x[6], x[7], x[8]],
    }
}

fn pose_from(x: &[f64]) -> Rigid {
    Rigid {
        rotation: rotation_from_rodrigues(DVec3::new(x[0], x[1], x[2])),
        translation: DVec3::new(x[3], x[4], x[5]),
    }
}

/// Residuals (projection - observation, pixels) of one view into `out` (2 per point).
/// Points behind the camera get a large residual.
fn view_residuals(intr: &[f64], pose: &[f64], view: &ViewObservations, out: &mut Vec<f64>) {
    const BEHIND_PX: f64 = 1e4;
    let i = intrinsics_from(
        intr,
        &Intrinsics {
            width: 0,
            height: 0,
            fx: 0.0,
            fy: 0.0,
            cx: 0.0,
            cy: 0.0,
            dist: [0.0; 5],
        },
    );
    let p = pose_from(pose);
    out.clear();
    for (o, m) in view.object.iter().zip(&view.image) {
        match i.project_camera_point(p.apply(*o)) {
            Some(q) => {
                out.push(q.x - m.x);
                out.push(q.y - m.y);
            }
            None => {
                out.push(BEHIND_PX);
                out.push(BEHIND_PX);
            }
        }
    }
}

/// Refines intrinsics and poses from a start by Levenberg-Marquardt over the views'
/// reprojection errors, then the intrinsics' standard deviations from the normal
/// equations at the solution and each view's RMS.
///
/// `poses` are the starting `camera_from_board` of each view (same length as `views`).
pub fn refine(
    start: &Intrinsics,
    poses: &[Rigid],
    views: &[ViewObservations],
    mode: IntrinsicsMode,
) -> BundleResult {
    let nv = views.len().min(poses.len());
    let np = N_INTRINSIC + N_POSE * nv;
    let mut x = pack_parameters(start, poses, nv);
    let free: Vec<bool> = (0..np)
        .map(|k| k >= N_INTRINSIC || mode == IntrinsicsMode::AllFree)
        .collect();
    let mut ne = NormalEquations::new(np);
    let (cost, iterations) = levenberg_marquardt(&mut x, views, nv, &free, &mut ne);
    // Covariance of the intrinsics at the solution.
    ne.build(&x, views, nv, &free);
    let n_points: usize = views.iter().take(nv).map(|v| v.object.len()).sum();
    let n_free = free.iter().filter(|f| **f).count();
    let dof = (2 * n_points).saturating_sub(n_free).max(1) as f64;
    let std_dev = intrinsic_std_dev(&ne.a, np, cost / dof, mode);
    let intrinsics = intrinsics_from(&x[..N_INTRINSIC], start);
    let poses: Vec<Rigid> = (0..nv)
        .map(|v| pose_from(&x[N_INTRINSIC + N_POSE * v..]))
        .collect();
    let mut per_view = Vec::with_capacity(nv);
    for v in 0..nv {
        view_residuals(
            &x[..N_INTRINSIC],
            &x[N_INTRINSIC + N_POSE * v..N_INTRINSIC + N_POSE * (v + 1)],
            &views[v],
            &mut ne.buf,
        );
        let n = (ne.buf.len() / 2).max(1) as f64;
        per_view.push((ne.buf.iter().map(|r| r * r).sum::<f64>() / n).sqrt());
    }
    BundleResult {
        intrinsics,
        poses,
        rms_px: (cost / n_points.max(1) as f64).sqrt(),
        per_view_rms_px: per_view,
        std_dev,
        iterations,
    }
}

/// The parameter vector: the intrinsics, then per view its rotation (Rodrigues vector)
/// and translation.
fn pack_parameters(start: &Intrinsics, poses: &[Rigid], nv: usize) -> Vec<f64> {
    let mut x = Vec::with_capacity(N_INTRINSIC + N_POSE * nv);
    x.extend_from_slice(&intrinsics_to_vec(start));
    for p in poses.iter().take(nv) {
        let r = rodrigues_from_rotation(&p.rotation);
        x.extend_from_slice(&[
            r.x,
            r.y,
            r.z,
            p.translation.x,
            p.translation.y,
            p.translation.z,
        ]);
    }
    x
}

/// Sum of squared reprojection errors (pixels squared) of the first `nv` views.
fn total_cost(x: &[f64], views: &[ViewObservations], nv: usize, buf: &mut Vec<f64>) -> f64 {
    let mut c = 0.0;
    for v in 0..nv {
        view_residuals(
            &x[..N_INTRINSIC],
            &x[N_INTRINSIC + N_POSE * v..N_INTRINSIC + N_POSE * (v + 1)],
            &views[v],
            buf,
        );
        c += buf.iter().map(|r| r * r).sum::<f64>();
    }
    c
}

/// The Gauss-Newton normal equations `A dx = -g` and their scratch.
struct NormalEquations {
    a: Vec<f64>,
    g: Vec<f64>,
    jac: Vec<Vec<f64>>,
    buf: Vec<f64>,
    plus: Vec<f64>,
    minus: Vec<f64>,
}

impl NormalEquations {
    fn new(np: usize) -> NormalEquations {
        NormalEquations {
            a: vec![0.0; np * np],
            g: vec![0.0; np],
            jac: Vec::new(),
            buf: Vec::new(),
            plus: Vec::new(),
            minus: Vec::new(),
        }
    }

    /// Builds them at `x` (see [`build_normal_equations`]).
    fn build(&mut self, x: &[f64], views: &[ViewObservations], nv: usize, free: &[bool]) {
        build_normal_equations(
            x,
            views,
            nv,
            free,
            &mut self.a,
            &mut self.g,
            &mut self.jac,
            &mut self.buf,
            &mut self.plus,
            &mut self.minus,
        );
    }
}

/// Levenberg-Marquardt from `x` (updated in place) until a step no longer lowers the
/// cost by [`MIN_RELATIVE_DECREASE`]; returns the final cost and the iterations.
fn levenberg_marquardt(
    x: &mut Vec<f64>,
    views: &[ViewObservations],
    nv: usize,
    free: &[bool],
    ne: &mut NormalEquations,
) -> (f64, usize) {
    let np = x.len();
    let mut cost = total_cost(x, views, nv, &mut ne.buf);
    let mut lambda = LAMBDA_START;
    let mut iterations = 0;
    for it in 0..MAX_ITERATIONS {
        iterations = it + 1;
        ne.build(x, views, nv, free);
        let (a, g) = (&ne.a, &ne.g);
        let mut improved = false;
        while lambda < LAMBDA_MAX {
            let mut m = a.clone();
            for k in 0..np {
                m[k * np + k] += lambda * a[k * np + k].max(1e-12);
            }
            if !cholesky(&mut m, np) {
                lambda *= 10.0;
                continue;
            }
            let mut step: Vec<f64> = g.iter().map(|v| -v).collect();
            cholesky_solve(&m, np, &mut step);
            let trial: Vec<f64> = x.iter().zip(&step).map(|(a, b)| a + b).collect();
            let c = total_cost(&trial, views, nv, &mut ne.buf);
            if c.is_finite() && c < cost {
                let decrease = (cost - c) / cost.max(1e-300);
                *x = trial;
                cost = c;
                lambda = (lambda * 0.1).max(1e-12);
                improved = decrease > MIN_RELATIVE_DECREASE;
                break;
            }
            lambda *= 10.0;
        }
        if !improved {
            break;
        }
    }
    (cost, iterations)
}

/// Standard deviations of the intrinsics from the inverse of the normal matrix `a`
/// (`np` x `np`) scaled by the residual variance; zero unless the intrinsics were free
/// and `a` factors.
fn intrinsic_std_dev(
    a: &[f64],
    np: usize,
    variance: f64,
    mode: IntrinsicsMode,
) -> [f64; N_INTRINSIC] {
    let mut std_dev = [0.0; N_INTRINSIC];
    let mut l = a.to_vec();
    if mode == IntrinsicsMode::AllFree && cholesky(&mut l, np) {
        for (k, sd) in std_dev.iter_mut().enumerate() {
            let mut e = vec![0.0; np];
            e[k] = 1.0;
            cholesky_solve(&l, np, &mut e);
            *sd = (variance * e[k]).max(0.0).sqrt();
        }
    }
    std_dev
}

/// Accumulates `A = JᵀJ` and `g = Jᵀr` at `x` (fixed parameters get identity rows).
#[allow(clippy::too_many_arguments)]
fn build_normal_equations(
    x: &[f64],
    views: &[ViewObservations],
    nv: usize,
    free: &[bool],
    a: &mut [f64],
    g: &mut [f64],
    jac: &mut Vec<Vec<f64>>,
    buf: &mut Vec<f64>,
    plus: &mut Vec<f64>,
    minus: &mut Vec<f64>,
) {
    let np = x.len();
    a.iter_mut().for_each(|v| *v = 0.0);
    g.iter_mut().for_each(|v| *v = 0.0);
    let mut xi = x[..N_INTRINSIC].to_vec();
    for (v, view) in views.iter().enumerate().take(nv) {
        let off = N_INTRINSIC + N_POSE * v;
        let mut xp = x[off..off + N_POSE].to_vec();
        view_residuals(&xi, &xp, view, buf);
        let m = buf.len();
        // Columns: 9 intrinsic then 6 pose, each of length m.
        jac.resize(N_INTRINSIC + N_POSE, Vec::new());
        let cols: Vec<usize> = (0..N_INTRINSIC).chain(off..off + N_POSE).collect();
        for (c, &pidx) in cols.iter().enumerate() {
            let col = &mut jac[c];
            col.clear();
            if !free[pidx] {
                col.resize(m, 0.0);
                continue;
            }
            let h = DIFF_STEP * x[pidx].abs().max(1.0);
            let target = if c < N_INTRINSIC {
                &mut xi[c]
            } else {
                &mut xp[c - N_INTRINSIC]
            };
            let orig = *target;
            *target = orig + h;
            let (pi, pp) = (xi.clone(), xp.clone());
            view_residuals(&pi, &pp, view, plus);
            let target = if c < N_INTRINSIC {
                &mut xi[c]
            } else {
                &mut xp[c - N_INTRINSIC]
            };
            *target = orig - h;
            let (mi, mp) = (xi.clone(), xp.clone());
            view_residuals(&mi, &mp, view, minus);
            let target = if c < N_INTRINSIC {
                &mut xi[c]
            } else {
                &mut xp[c - N_INTRINSIC]
            };
            *target = orig;
            col.extend(
                plus.iter()
                    .zip(minus.iter())
                    .map(|(p, q)| (p - q) / (2.0 * h)),
            );
        }
        for (ci, &pi) in cols.iter().enumerate() {
            let jc = &jac[ci];
            g[pi] += jc.iter().zip(buf.iter()).map(|(j, r)| j * r).sum::<f64>();
            for (cj, &pj) in cols.iter().enumerate().skip(ci) {
                let s: f64 = jc.iter().zip(&jac[cj]).map(|(p, q)| p * q).sum();
                a[pi * np + pj] += s;
                if pi != pj {
                    a[pj * np + pi] += s;
                }
            }
        }
    }
    for k in 0..np {
        if !free[k] {
            for j in 0..np {
                a[k * np + j] = 0.0;
                a[j * np + k] = 0.0;
            }
            a[k * np + k] = 1.0;
            g[k] = 0.0;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DMat3;

    #[test]
    fn refine_recovers_intrinsics_and_distortion_from_exact_corners() {
        let truth = Intrinsics {
            width: 1280,
            height: 720,
            fx: 1000.0,
            fy: 995.0,
            cx: 650.0,
            cy: 355.0,
            dist: [-0.1, 0.05, 0.001, -0.0005, -0.01],
        };
        let object: Vec<DVec3> = (0..6)
            .flat_map(|r| (0..9).map(move |c| DVec3::new(c as f64 * 0.04, r as f64 * 0.04, 0.0)))
            .collect();
        let mut views = Vec::new();
        let mut true_poses = Vec::new();
        for (k, &(ax, ay, tx, ty)) in [
            (0.4, 0.1, -0.3, -0.2),
            (-0.3, 0.3, 0.0, -0.1),
            (0.1, -0.4, -0.2, 0.05),
            (-0.25, -0.25, 0.1, -0.15),
            (0.2, 0.35, -0.35, 0.0),
        ]
        .iter()
        .enumerate()
        {
            let rot = DMat3::from_rotation_x(ax)
                * DMat3::from_rotation_y(ay)
                * DMat3::from_rotation_z(0.1 * k as f64);
            let pose = Rigid {
                rotation: rot,
                translation: DVec3::new(tx, ty, 1.0),
            };
            let image = object
                .iter()
                .map(|p| truth.project_camera_point(pose.apply(*p)).unwrap())
                .collect();
            views.push(ViewObservations {
                object: object.clone(),
                image,
            });
            true_poses.push(pose);
        }
        let mut start = truth;
        start.fx *= 1.03;
        start.fy *= 0.98;
        start.cx += 8.0;
        start.dist = [0.0; 5];
        let poses: Vec<Rigid> = true_poses
            .iter()
            .map(|p| Rigid {
                rotation: p.rotation * DMat3::from_rotation_y(0.02),
                translation: p.translation * 1.02,
            })
            .collect();
        let r = refine(&start, &poses, &views, IntrinsicsMode::AllFree);
        assert!(r.rms_px < 1e-6, "rms {}", r.rms_px);
        assert!(
            (r.intrinsics.fx - truth.fx).abs() < 1e-4 && (r.intrinsics.cy - truth.cy).abs() < 1e-4,
            "{:?}",
            r.intrinsics
        );
        assert!((r.intrinsics.dist[0] - truth.dist[0]).abs() < 1e-6);
    }
}
