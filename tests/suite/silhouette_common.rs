//! Shared helpers of the silhouette tests: a station with lens distortion, and phantom
//! frame pairs rendered through it.
#![allow(dead_code)]

use fitstation::camera::StationCalibration;
use fitstation::imgproc::Mask;
use fitstation::landmarks::phantom::{Phantom, PhantomParams, Renderer, SceneParams};
use fitstation::silhouette::{SilhouetteExecutor, SilhouetteOptions};
use image::RgbImage;
use std::sync::OnceLock;

/// Portrait 720 x 1280 cameras 2.6 m from the mark, 1.0 m high, aimed at 0.9 m, with
/// mild barrel distortion.
pub fn station() -> StationCalibration {
    let mut s = StationCalibration::nominal(720, 1280, 1300.0, 2.6, 1.0, 0.9);
    s.front.intrinsics.dist = [-0.06, 0.02, 0.0005, -0.0003, 0.0];
    s.side.intrinsics.dist = [-0.05, 0.015, -0.0004, 0.0002, 0.0];
    s
}

pub struct Rig {
    pub calib: StationCalibration,
    pub front: Renderer,
    pub side: Renderer,
}

pub fn rig() -> &'static Rig {
    static RIG: OnceLock<Rig> = OnceLock::new();
    RIG.get_or_init(|| {
        let calib = station();
        Rig {
            front: Renderer::new(calib.front),
            side: Renderer::new(calib.side),
            calib,
        }
    })
}

pub struct Pair {
    pub front: RgbImage,
    pub side: RgbImage,
    pub front_truth: Mask,
    pub side_truth: Mask,
}

pub fn render(people: &[Phantom], scene: SceneParams) -> Pair {
    let r = rig();
    let (front, front_truth) = r.front.render(people, &scene);
    let side_scene = SceneParams {
        seed: scene.seed.wrapping_add(1000),
        ..scene
    };
    let (side, side_truth) = r.side.render(people, &side_scene);
    Pair {
        front,
        side,
        front_truth,
        side_truth,
    }
}

/// Empty-scene frames (noise varies by seed).
pub fn empty(seed: u64) -> Pair {
    render(
        &[],
        SceneParams {
            seed,
            shadow: false,
            ..Default::default()
        },
    )
}

/// An executor that has learned `n` empty frame pairs.
pub fn learned_executor(n: u64) -> SilhouetteExecutor {
    let r = rig();
    let mut ex = SilhouetteExecutor::new(&r.calib, SilhouetteOptions::default());
    for k in 0..n {
        let e = empty_cached(k as usize);
        ex.learn_background(&e.front, &e.side).expect("learn");
    }
    ex
}

/// The first few empty pairs, rendered once per test binary.
pub fn empty_cached(k: usize) -> &'static Pair {
    static EMPTY: OnceLock<Vec<Pair>> = OnceLock::new();
    &EMPTY.get_or_init(|| (0..4).map(|k| empty(100 + k as u64)).collect())[k % 4]
}

/// The default A-pose phantom.
pub fn subject() -> Phantom {
    Phantom::new(PhantomParams::default())
}
