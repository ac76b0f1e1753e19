//! The silhouette stage on a real body shape: the MakeHuman base mesh (CC0; 13k
//! triangles, scaled 0.1, soles on y = 0, facing +Z) rasterised with shading through the
//! distorting station over the textured backdrop, with sensor noise. Checks the mask IoU
//! and compares the landmark heights with the same definitions applied to the mesh's
//! exact orthographic front silhouette (rasterised at 0.5 mm).
//! Skipped (with a SKIPPED line) when the mesh is not on this machine.

use crate::silhouette_common;

use fitstation::camera::Camera;
use fitstation::imgproc::Mask;
use fitstation::landmarks::phantom::SceneParams;
use fitstation::landmarks::LandmarkName;
use fitstation::mesh::io::read_obj;
use fitstation::mesh::TriMesh;
use glam::{DVec2, DVec3};
use image::RgbImage;
use silhouette_common::*;

/// Decimetres to metres.
const MESH_SCALE: f64 = 0.1;
/// Supersampling per pixel side (odd, so one sample sits on the pixel centre).
const SS: usize = 3;
const SKIN: [f64; 3] = [205.0, 158.0, 136.0];
/// Required IoU on the mesh frames (issue 4 target).
const MIN_IOU: f64 = 0.98;
/// Landmark heights against the orthographic definition: perspective and orthographic
/// silhouettes of a real body differ near concave places (the camera at 1 m looks into
/// the armpit from below), so a little looser than the phantom's 10 mm.
const MAX_HEIGHT_ERR_M: f64 = 0.015;
/// Height of the hips as a fraction of the stature (for centring the mesh on the mark).
const HIP_HEIGHT_FRACTION: f64 = 0.52;
/// Resolution of the orthographic ground-truth raster, metres.
const ORTHO_CELL_M: f64 = 0.0005;

fn load_body() -> Option<TriMesh> {
    let mesh_path = fitstation::io::cache::makehuman_base_obj();
    if !mesh_path.exists() {
        println!(
            "SKIPPED: {} not found (MakeHuman base mesh); mesh silhouette test not run",
            mesh_path.display()
        );
        assert!(
            std::env::var_os("CI").is_none(),
            "{} missing in CI (.ci/run installs it)",
            mesh_path.display()
        );
        return None;
    }
    let mut m = read_obj(&mesh_path, Some("body")).expect("read the MakeHuman mesh");
    for p in &mut m.positions {
        *p *= MESH_SCALE;
    }
    let (lo, hi) = m.positions.iter().fold(
        (DVec3::splat(f64::MAX), DVec3::splat(f64::MIN)),
        |(lo, hi), p| (lo.min(*p), hi.max(*p)),
    );
    // Centre the hips on the mark: the middle of the trunk's depth at hip height.
    let hip_y = lo.y + HIP_HEIGHT_FRACTION * (hi.y - lo.y);
    let (zlo, zhi) = m
        .positions
        .iter()
        .filter(|p| (p.y - hip_y).abs() < 0.02 && (p.x - (lo.x + hi.x) / 2.0).abs() < 0.15)
        .fold((f64::MAX, f64::MIN), |(a, b), p| (a.min(p.z), b.max(p.z)));
    let shift = DVec3::new(-(lo.x + hi.x) / 2.0, -lo.y, -(zlo + zhi) / 2.0);
    for p in &mut m.positions {
        *p += shift;
    }
    Some(m)
}

fn edge(a: DVec2, b: DVec2, p: DVec2) -> f64 {
    (b - a).perp_dot(p - a)
}

/// Renders the mesh over an empty-scene frame: (frame, ground-truth mask).
// Index arithmetic over several arrays reads better with indices.
#[allow(clippy::needless_range_loop)]
fn render_mesh(mesh: &TriMesh, cam: &Camera, background: &RgbImage, seed: u64) -> (RgbImage, Mask) {
    let (w, h) = (
        cam.intrinsics.width as usize,
        cam.intrinsics.height as usize,
    );
    let (sw, sh) = (w * SS, h * SS);
    let mut depth = vec![f64::INFINITY; sw * sh];
    let mut shade = vec![0f32; sw * sh];
    let center = cam.center_in_station();
    let proj: Vec<Option<(DVec2, f64)>> = mesh
        .positions
        .iter()
        .map(|&p| {
            let z = cam.camera_from_station.apply(p).z;
            cam.project(p)
                .map(|px| (px * SS as f64 + DVec2::splat((SS / 2) as f64), z))
        })
        .collect();
    for t in &mesh.triangles {
        let [a, b, c] = t.map(|i| proj[i as usize]);
        let (Some((pa, za)), Some((pb, zb)), Some((pc, zc))) = (a, b, c) else {
            continue;
        };
        let area = edge(pa, pb, pc);
        if area.abs() < 1e-12 {
            continue;
        }
        let [va, vb, vc] = t.map(|i| mesh.positions[i as usize]);
        let n = (vb - va).cross(vc - va).normalize_or_zero();
        let view = (center - (va + vb + vc) / 3.0).normalize_or_zero();
        let s = (0.55 + 0.45 * n.dot(view).abs()) as f32;
        let lo = pa.min(pb).min(pc).max(DVec2::ZERO);
        let hi = pa
            .max(pb)
            .max(pc)
            .min(DVec2::new((sw - 1) as f64, (sh - 1) as f64));
        for y in lo.y.ceil() as usize..=hi.y.floor().max(0.0) as usize {
            for x in lo.x.ceil() as usize..=hi.x.floor().max(0.0) as usize {
                let p = DVec2::new(x as f64, y as f64);
                let (w0, w1, w2) = (
                    edge(pb, pc, p) / area,
                    edge(pc, pa, p) / area,
                    edge(pa, pb, p) / area,
                );
                if w0 < 0.0 || w1 < 0.0 || w2 < 0.0 {
                    continue;
                }
                let z = w0 * za + w1 * zb + w2 * zc;
                let k = y * sw + x;
                if z < depth[k] {
                    depth[k] = z;
                    shade[k] = s;
                }
            }
        }
    }
    let mut img = background.clone();
    let mut mask = Mask::new(w as u32, h as u32);
    let mut rng = seed.wrapping_mul(0x9E3779B97F4A7C15) | 1;
    for y in 0..h {
        for x in 0..w {
            let (mut cov, mut col) = (0.0, [0f64; 3]);
            for sy in 0..SS {
                for sx in 0..SS {
                    let k = (y * SS + sy) * sw + x * SS + sx;
                    if depth[k].is_finite() {
                        cov += 1.0;
                        for (c, base) in col.iter_mut().zip(SKIN) {
                            *c += base * shade[k] as f64;
                        }
                    }
                }
            }
            let centre = (y * SS + SS / 2) * sw + x * SS + SS / 2;
            mask.data[y * w + x] = if depth[centre].is_finite() { 255 } else { 0 };
            if cov == 0.0 {
                continue;
            }
            let f = cov / (SS * SS) as f64;
            let px = img.get_pixel_mut(x as u32, y as u32);
            for ch in 0..3 {
                rng ^= rng << 13;
                rng ^= rng >> 7;
                rng ^= rng << 17;
                let noise = ((rng >> 40) as f64 / (1u64 << 24) as f64 - 0.5) * 6.0 * f;
                // A sensor pixel integrates light: body and backdrop mix in linear light,
                // then the camera encodes the level (sRGB).
                let lin = (1.0 - f) * to_linear(px.0[ch] as f64) + f * to_linear(col[ch] / cov);
                let v = to_srgb(lin) + noise;
                px.0[ch] = v.round().clamp(0.0, 255.0) as u8;
            }
        }
    }
    (img, mask)
}

/// sRGB level (0..255) to linear light (0..1).
fn to_linear(v: f64) -> f64 {
    let e = (v / 255.0).clamp(0.0, 1.0);
    if e <= 0.04045 {
        e / 12.92
    } else {
        ((e + 0.055) / 1.055).powf(2.4)
    }
}

/// Linear light (0..1) to an sRGB level (0..255).
fn to_srgb(l: f64) -> f64 {
    let l = l.clamp(0.0, 1.0);
    255.0
        * if l <= 0.0031308 {
            12.92 * l
        } else {
            1.055 * l.powf(1.0 / 2.4) - 0.055
        }
}

/// The orthographic front silhouette (x, y) of the mesh on a fine grid.
struct Ortho {
    x0: f64,
    cols: usize,
    rows: usize,
    on: Vec<bool>,
}

impl Ortho {
    fn new(mesh: &TriMesh) -> Self {
        let x0 = -0.7;
        let cols = (1.4 / ORTHO_CELL_M) as usize;
        let rows = (2.0 / ORTHO_CELL_M) as usize;
        let mut on = vec![false; cols * rows];
        let to = |p: DVec3| DVec2::new((p.x - x0) / ORTHO_CELL_M, p.y / ORTHO_CELL_M);
        for t in &mesh.triangles {
            let [a, b, c] = t.map(|i| to(mesh.positions[i as usize]));
            let area = edge(a, b, c);
            if area.abs() < 1e-12 {
                continue;
            }
            let lo = a.min(b).min(c).max(DVec2::ZERO);
            let hi = a
                .max(b)
                .max(c)
                .min(DVec2::new((cols - 1) as f64, (rows - 1) as f64));
            for y in lo.y.ceil() as usize..=hi.y.floor().max(0.0) as usize {
                for x in lo.x.ceil() as usize..=hi.x.floor().max(0.0) as usize {
                    let p = DVec2::new(x as f64, y as f64);
                    let s = area.signum();
                    if s * edge(b, c, p) >= 0.0
                        && s * edge(c, a, p) >= 0.0
                        && s * edge(a, b, p) >= 0.0
                    {
                        on[y * cols + x] = true;
                    }
                }
            }
        }
        Ortho { x0, cols, rows, on }
    }
    fn at(&self, x: f64, y: f64) -> bool {
        let (c, r) = (
            ((x - self.x0) / ORTHO_CELL_M).round(),
            (y / ORTHO_CELL_M).round(),
        );
        c >= 0.0
            && r >= 0.0
            && (c as usize) < self.cols
            && (r as usize) < self.rows
            && self.on[r as usize * self.cols + c as usize]
    }
    fn stature(&self) -> f64 {
        (0..self.rows)
            .rev()
            .find(|&r| (0..self.cols).any(|c| self.on[r * self.cols + c]))
            .map_or(0.0, |r| r as f64 * ORTHO_CELL_M)
    }
    fn centre_x(&self) -> f64 {
        let (mut s, mut n) = (0.0, 0.0);
        for r in 0..self.rows {
            for c in 0..self.cols {
                if self.on[r * self.cols + c] {
                    s += self.x0 + c as f64 * ORTHO_CELL_M;
                    n += 1.0;
                }
            }
        }
        s / n
    }
    /// Highest y of the gap on the centre line (crotch).
    fn crotch(&self, xc: f64, stature: f64) -> Option<f64> {
        let mut y = 0.3 * stature;
        while y < 0.7 * stature {
            if self.at(xc, y) {
                return Some(y);
            }
            y += ORTHO_CELL_M;
        }
        None
    }
    /// Highest line with a torso-arm gap on one side.
    fn armpit(&self, xc: f64, side: f64, from: f64, to: f64) -> Option<f64> {
        let mut y = from;
        while y > to {
            let mut state = 0;
            let mut x = 0.0;
            while x < 0.7 {
                let inside = self.at(xc + side * x, y);
                state = match (state, inside) {
                    (0, false) => 1,
                    (1, true) => return Some(y),
                    (s, _) => s,
                };
                x += ORTHO_CELL_M;
            }
            y -= ORTHO_CELL_M;
        }
        None
    }
}

#[test]
fn the_makehuman_body_is_segmented_and_its_landmarks_found() {
    let Some(mesh) = load_body() else { return };
    let r = rig();
    let mut ex = learned_executor(4);
    let scene = SceneParams {
        shadow: false,
        seed: 71,
        ..Default::default()
    };
    let bg = render(&[], scene);
    let (front, front_truth) = render_mesh(&mesh, &r.calib.front, &bg.front, 1);
    let (side, side_truth) = render_mesh(&mesh, &r.calib.side, &bg.side, 2);
    let res = ex.process(&front, &side).expect("process");
    let (fi, si) = (
        res.masks.front.iou(&front_truth),
        res.masks.side.iou(&side_truth),
    );
    println!(
        "MakeHuman body: IoU front {fi:.4}, side {si:.4}; verdicts {:?}",
        res.landmarks.verdicts
    );
    assert!(fi > MIN_IOU && si > MIN_IOU);
    assert!(
        res.landmarks.verdicts.is_empty(),
        "{:?}",
        res.landmarks.verdicts
    );

    let o = Ortho::new(&mesh);
    let stature = o.stature();
    let (xc, h, yc) = (o.centre_x(), stature / 7.0, stature / 2.0);
    let lm = &res.landmarks;
    let ht = lm.get(LandmarkName::HeadTop).expect("head top").station;
    println!(
        "stature: ours {:.4} (front head top at {:.4}, z {:+.4}), orthographic {:.4}",
        lm.stature_m, ht.y, ht.z, stature
    );
    assert!(
        (lm.stature_m - stature).abs() < MAX_HEIGHT_ERR_M,
        "stature {}",
        lm.stature_m
    );
    let truth = [
        (LandmarkName::Crotch, o.crotch(xc, stature)),
        (
            LandmarkName::ArmpitLeft,
            o.armpit(xc, 1.0, yc + 2.0 * h, yc),
        ),
        (
            LandmarkName::ArmpitRight,
            o.armpit(xc, -1.0, yc + 2.0 * h, yc),
        ),
    ];
    for (name, t) in truth {
        let t = t.unwrap_or_else(|| panic!("no orthographic {}", name.as_str()));
        let got = lm
            .get(name)
            .unwrap_or_else(|| panic!("{} not found", name.as_str()))
            .station;
        println!(
            "{:<13} ours y {:.4} (x {:+.4}, z {:+.4}), orthographic {:.4}: {:+.1} mm",
            name.as_str(),
            got.y,
            got.x,
            got.z,
            t,
            (got.y - t) * 1e3
        );
        assert!(
            (got.y - t).abs() < MAX_HEIGHT_ERR_M,
            "{}: {:.1} mm",
            name.as_str(),
            (got.y - t) * 1e3
        );
    }
    for name in [
        LandmarkName::AcromionLeft,
        LandmarkName::AcromionRight,
        LandmarkName::KneeLeft,
        LandmarkName::ElbowRight,
    ] {
        let p = lm
            .get(name)
            .unwrap_or_else(|| panic!("{} not found", name.as_str()))
            .station;
        println!(
            "{:<13} ({:+.4}, {:.4}, {:+.4})",
            name.as_str(),
            p.x,
            p.y,
            p.z
        );
    }
    if let Some(path) = std::env::var_os("SILHOUETTE_MESH_OVERLAY_OUT") {
        fitstation::silhouette::cli::overlay(&front, &side, &res)
            .save(path)
            .expect("save overlay");
    }
}
