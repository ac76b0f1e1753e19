//! `fitstation landmarks`: landmarks, joints and verdicts of one still image per view
//! (the paper's case), as text or JSON, with an optional overlay PNG of both views side
//! by side (mask edge, contour parts in colour, landmarks, skeleton).
//!
//! Station points are printed in metres, pixels in each frame's distorted pixels.

use super::{SilhouetteExecutor, SilhouetteOptions, SilhouetteResult, ViewAnalysis};
use crate::camera::StationCalibration;
use crate::imgproc::Mask;
use crate::landmarks::graze::TemplateProfiles;
use crate::landmarks::{ContourPart, LandmarkName, Status};
use crate::segment;
use anyhow::Context;
use glam::DVec2;
use image::{Rgb, RgbImage};
use serde_json::{json, Map, Value};
use std::path::{Path, PathBuf};

/// Arguments of `fitstation landmarks`.
#[derive(Debug, clap::Args)]
pub struct LandmarksArgs {
    /// Front camera image (PNG or JPEG).
    #[arg(long)]
    pub front: PathBuf,
    /// Side camera image.
    #[arg(long)]
    pub side: PathBuf,
    /// Station calibration (station.yaml).
    #[arg(long)]
    pub calib: PathBuf,
    /// Empty-scene image of the front camera (else the backdrop is keyed from the border).
    #[arg(long)]
    pub front_bg: Option<PathBuf>,
    /// Empty-scene image of the side camera.
    #[arg(long)]
    pub side_bg: Option<PathBuf>,
    /// Print JSON instead of text.
    #[arg(long)]
    pub json: bool,
    /// Write an overlay PNG of both views side by side.
    #[arg(long)]
    pub overlay: Option<PathBuf>,
}

/// Reads an image file as RGB, naming the file in the error.
pub fn load_rgb(path: &Path) -> anyhow::Result<RgbImage> {
    Ok(image::open(path)
        .with_context(|| format!("cannot read image {}", path.display()))?
        .to_rgb8())
}

/// Runs the command.
pub fn run(args: LandmarksArgs) -> anyhow::Result<()> {
    let calib = StationCalibration::load(&args.calib)?;
    let front = load_rgb(&args.front)?;
    let side = load_rgb(&args.side)?;
    let front_bg = match &args.front_bg {
        Some(p) => load_rgb(p)?,
        None => segment::backdrop_from_border(&front),
    };
    let side_bg = match &args.side_bg {
        Some(p) => load_rgb(p)?,
        None => segment::backdrop_from_border(&side),
    };
    let mut opts = SilhouetteOptions::default();
    opts.segment.adapt_rate = 0.0;
    match TemplateProfiles::of_shape_library() {
        Ok(p) => opts.template_profiles = Some(p),
        Err(e) => eprintln!(
            "warning: no shape library ({e}): the crotch, head top and acromions are lifted onto the body axis as seen"
        ),
    }
    let mut ex = SilhouetteExecutor::new(&calib, opts);
    ex.learn_background(&front_bg, &side_bg)?;
    let res = ex.process(&front, &side)?;
    if args.json {
        println!("{}", serde_json::to_string_pretty(&to_json(&res))?);
    } else {
        print_text(&res);
    }
    if let Some(path) = &args.overlay {
        let img = overlay(&front, &side, &res);
        crate::io::atomic::save_image(path, &img)
            .with_context(|| format!("cannot write overlay {}", path.display()))?;
    }
    Ok(())
}

fn xyz(p: glam::DVec3) -> Value {
    json!({"x": p.x, "y": p.y, "z": p.z})
}

fn uv(p: Option<DVec2>) -> Value {
    match p {
        Some(p) => json!({"u": p.x, "v": p.y}),
        None => Value::Null,
    }
}

/// The JSON document of a result: landmarks and joints by name (station metres, pixels of
/// both views), verdicts with messages, stage timings.
pub fn to_json(res: &SilhouetteResult) -> Value {
    let (mut lms, mut joints) = (Map::new(), Map::new());
    for p in &res.landmarks.points {
        let v = json!({"station": xyz(p.station), "front_px": uv(p.front_px), "side_px": uv(p.side_px)});
        if p.landmark.is_joint() {
            joints.insert(p.name.clone(), v);
        } else {
            lms.insert(p.name.clone(), v);
        }
    }
    let verdicts: Vec<Value> = res
        .landmarks
        .verdicts
        .iter()
        .map(|v| {
            let mut j = serde_json::to_value(v).unwrap_or(Value::Null);
            if let Value::Object(m) = &mut j {
                m.insert("message".into(), Value::String(v.message()));
            }
            j
        })
        .collect();
    let parts = |a: &ViewAnalysis| -> Vec<Value> {
        a.parts.iter().map(|p| json!({"name": p.name, "status": p.status, "start": p.range.start, "len": p.range.len})).collect()
    };
    json!({
        "stature_m": res.landmarks.stature_m,
        "landmarks": lms,
        "joints": joints,
        "verdicts": verdicts,
        "front": {"contour_points": res.front.contour.len(), "parts": parts(&res.front), "person_px": res.front.stats.person_px},
        "side": {"contour_points": res.side.contour.len(), "parts": parts(&res.side), "person_px": res.side.stats.person_px},
        "timings_ms": res.timings,
    })
}

fn print_text(res: &SilhouetteResult) {
    println!("stature: {:.1} mm", res.landmarks.stature_m * 1e3);
    for p in &res.landmarks.points {
        let f = p
            .front_px
            .map_or("-".to_string(), |q| format!("({:.1}, {:.1})", q.x, q.y));
        let s = p
            .side_px
            .map_or("-".to_string(), |q| format!("({:.1}, {:.1})", q.x, q.y));
        println!(
            "{:<18} x {:+.4} y {:.4} z {:+.4} m   front px {f}   side px {s}",
            p.name, p.station.x, p.station.y, p.station.z
        );
    }
    if res.landmarks.verdicts.is_empty() {
        println!("verdicts: none (frame usable)");
    }
    for v in &res.landmarks.verdicts {
        println!("verdict: {}", v.message());
    }
    let t = res.timings;
    println!(
        "timings: segment {:.2} ms, contour {:.2} ms, landmarks {:.2} ms, total {:.2} ms",
        t.segment_ms, t.contour_ms, t.landmarks_ms, t.total_ms
    );
}

fn part_color(p: &ContourPart) -> [u8; 3] {
    match (p.name.as_str(), p.status) {
        ("torso", Status::Left) => [255, 200, 0],
        ("torso", _) => [255, 120, 0],
        ("left_arm", Status::Left) => [0, 220, 0],
        ("left_arm", _) => [0, 140, 60],
        ("right_arm", Status::Left) => [0, 200, 255],
        ("right_arm", _) => [0, 90, 255],
        ("left_leg", Status::Left) => [220, 0, 220],
        ("left_leg", _) => [150, 0, 150],
        ("right_leg", Status::Left) => [255, 60, 60],
        ("right_leg", _) => [180, 0, 0],
        ("side_torso", Status::Front) => [255, 200, 0],
        ("side_torso", _) => [255, 120, 0],
        ("side_leg", Status::Front) => [0, 220, 0],
        _ => [0, 120, 60],
    }
}

fn put(img: &mut RgbImage, x: i64, y: i64, c: [u8; 3]) {
    if x >= 0 && y >= 0 && (x as u32) < img.width() && (y as u32) < img.height() {
        img.put_pixel(x as u32, y as u32, Rgb(c));
    }
}

fn line(img: &mut RgbImage, a: DVec2, b: DVec2, c: [u8; 3]) {
    let n = (a.distance(b).ceil() as usize).max(1);
    for k in 0..=n {
        let p = a.lerp(b, k as f64 / n as f64);
        put(img, p.x.round() as i64, p.y.round() as i64, c);
    }
}

fn dot(img: &mut RgbImage, p: DVec2, r: i64, c: [u8; 3]) {
    for dy in -r..=r {
        for dx in -r..=r {
            if dx * dx + dy * dy <= r * r {
                put(img, p.x.round() as i64 + dx, p.y.round() as i64 + dy, c);
            }
        }
    }
}

/// Skeleton edges drawn on the overlay.
const BONES: [(LandmarkName, LandmarkName); 19] = {
    use LandmarkName::*;
    [
        (HeadTop, Head),
        (Head, Neck),
        (Neck, Chest),
        (Chest, Waist),
        (Waist, Abdomen),
        (Abdomen, Hip),
        (Hip, ThighRootLeft),
        (Hip, ThighRootRight),
        (ThighRootLeft, KneeLeft),
        (KneeLeft, AnkleLeft),
        (ThighRootRight, KneeRight),
        (KneeRight, AnkleRight),
        (Neck, ShoulderLeft),
        (ShoulderLeft, ElbowLeft),
        (ElbowLeft, WristLeft),
        (WristLeft, HandLeft),
        (Neck, ShoulderRight),
        (ShoulderRight, ElbowRight),
        (ElbowRight, WristRight),
    ]
};

fn draw_view(img: &mut RgbImage, frame: &RgbImage, mask: &Mask, a: &ViewAnalysis) {
    img.clone_from(frame);
    // Mask edge in white.
    for y in 0..mask.height as i64 {
        for x in 0..mask.width as i64 {
            if mask.get(x, y)
                && (!mask.get(x - 1, y)
                    || !mask.get(x + 1, y)
                    || !mask.get(x, y - 1)
                    || !mask.get(x, y + 1))
            {
                put(img, x, y, [255, 255, 255]);
            }
        }
    }
    let n = a.contour.len();
    for part in &a.parts {
        let c = part_color(part);
        for i in part.range.indices(n) {
            let p = a.contour.points[i];
            dot(img, p, 1, c);
        }
    }
    if a.parts.is_empty() {
        for &p in &a.contour.points {
            dot(img, p, 1, [255, 255, 0]);
        }
    }
    for (x, y) in BONES {
        if let (Some(p), Some(q)) = (a.landmark(x), a.landmark(y)) {
            line(img, p, q, [255, 0, 255]);
        }
    }
    for &(name, p) in &a.landmarks_px {
        let c = if name.is_joint() {
            [255, 0, 255]
        } else {
            [255, 0, 0]
        };
        dot(img, p, if name.is_joint() { 3 } else { 5 }, c);
    }
}

/// Both views side by side with the mask edge, parts, landmarks and skeleton.
pub fn overlay(front: &RgbImage, side: &RgbImage, res: &SilhouetteResult) -> RgbImage {
    let mut a = RgbImage::new(1, 1);
    let mut b = RgbImage::new(1, 1);
    draw_view(&mut a, front, &res.masks.front, &res.front);
    draw_view(&mut b, side, &res.masks.side, &res.side);
    let mut out = RgbImage::new(a.width() + b.width(), a.height().max(b.height()));
    image::imageops::replace(&mut out, &a, 0, 0);
    image::imageops::replace(&mut out, &b, a.width() as i64, 0);
    out
}
