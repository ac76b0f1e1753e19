//! Synthetic two-camera recordings with ground truth (`fitstation synth`, `synth-set`).
//!
//! A body (see [`subject::subject_body`]) stands in the A-pose on the mark of a kiosk
//! room and is filmed by the two station cameras (front on +Z, side on +X), drawn per
//! seed within the station's ranges: 2.4 to 3.5 m away, portrait or landscape 720p,
//! small yaw/pitch/roll and position errors, focal length fitted to the body with a
//! random margin, OpenCV lens distortion. The images are honest on purpose: shaded body
//! in tight clothing, textured backdrops and floor, soft shadows at the feet, optics
//! blur, vignetting, sensor noise, exposure flicker, a little sway; the first frames
//! show the empty scene.
//!
//! # Conventions
//! - Station frame (`../shared/spec/formats.md`): metres, +Y up, +Z toward the front
//!   camera, +X the subject's left, origin on the floor at the mark.
//! - Pixels as OpenCV. Rendering: [`raster`] (z-buffer, distorted vertices with
//!   adaptive subdivision) for the body, per-pixel ray casting through the exact inverse
//!   lens model for the room ([`scene::Background`]).
//! - Ground truth goes to the sibling folder `<recording>.truth/`, which the station
//!   never reads: `truth.json`, `mesh.obj` (the body in its mean pose, station frame),
//!   `masks/{front,side}/NNNNNN.png` (255 = body) for every frame.
//!
//! # Commands
//! - One recording: `fitstation synth --out recordings/NAME --seed N` (subject and
//!   camera options override what the seed draws; `--format png|jpeg|mp4`).
//! - The evaluation set (not stored; deterministic):
//!   `fitstation synth-set --out /tmp/evalset --count 12` writes `subject_00` ..
//!   `subject_11` from seeds 1000..1011, alternating female/male, builds spread over
//!   the weight range; score fits with `fitstation eval /tmp/evalset/subject_*`.
//!   These bodies come from the shape library the fit chooses its candidate from (the
//!   regression set); two options make sets the library cannot make:
//!   - `--population ansur`: each subject follows one real ANSUR II person
//!     ([`ansur`], data in `../shared/data/ansur2`, `--ansur-dir` to move it; row drawn
//!     from the seed, sexes alternating), the library body warped section-wise to the
//!     person's stature, crotch height, chest depth and circumference, waist breadth,
//!     depth and circumference, buttock breadth and depth and thigh circumference, plus
//!     local shape variation ([`ansur_body`]);
//!     truth.json gains an `ansur` object (id, sex, values used).
//!   - `--stance varied`: arms, elbows, legs and a turn of the whole body drawn per
//!     subject, posed with a skinning that is not the fit's ([`stance`]); truth.json
//!     gains a `stance` object, and its measurements are of the posed body.
//!
//!   The defaults (`--population library --stance rest`) render what earlier versions
//!   rendered for the same seeds. Seeds 30000 and above are kept for final judgements.
//!
//! # Randomness
//! Everything is drawn from [`rng::SplitMix64`] streams derived from the seed (subject,
//! cameras, scene, film, per-frame noise and flicker), so a seed renders the same
//! recording again (bit-exact on the same platform; libm may differ elsewhere).

pub mod ansur;
pub mod ansur_body;
mod cli;
pub mod film;
pub mod passerby;
pub mod raster;
mod render;
pub mod rng;
pub mod scene;
pub mod stance;
pub mod subject;

use crate::camera::{Camera, Intrinsics, Rigid, StationCalibration};
use crate::mesh::TriMesh;
use crate::recording::{FrameFormat, RecordingError};
use glam::{DMat3, DVec2, DVec3};
use rng::SplitMix64;
use serde::Serialize;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use subject::{Landmarks, Placement, SubjectParams};

pub use cli::{
    ansur_member, run, run_set, set_member, Population, StanceKind, SubjectOptions, SynthArgs,
    SynthSetArgs,
};
pub use render::render_recording;

/// Nearest and farthest camera distance from the mark, metres (station geometry).
pub const DISTANCE_RANGE_M: (f64, f64) = (2.4, 3.5);
/// Camera height range, metres.
pub const CAMERA_HEIGHT_RANGE_M: (f64, f64) = (0.8, 1.5);
/// Mounting errors: yaw/pitch/roll (degrees) and lateral position (metres).
pub const MOUNT_ANGLE_ERR_DEG: f64 = 1.5;
pub const MOUNT_POSITION_ERR_M: f64 = 0.05;
/// The long side of 720p frames.
pub const FRAME_LONG: u32 = 1280;
pub const FRAME_SHORT: u32 = 720;
/// Fraction of the image the body's box may fill at most (the rest is margin).
pub const MAX_FILL: f64 = 0.94;
/// Sway amplitude (degrees about the ankles; 0.4 degrees moves the head by ~1.2 cm, as
/// a person standing still does) and period range (seconds). `mesh.obj` is the mean
/// pose; each frame's sway angles are in truth.json.
pub const SWAY_DEG: (f64, f64) = (0.1, 0.4);
pub const SWAY_PERIOD_S: (f64, f64) = (2.0, 5.0);
/// Minimum number of empty frames at the start (formats.md).
pub const MIN_EMPTY_FRAMES: usize = 10;
/// Name suffix of the ground-truth folder beside a recording.
pub const TRUTH_SUFFIX: &str = ".truth";
/// Random stream of the camouflage colours (`SplitMix64::stream` label).
const CAMOUFLAGE_STREAM: u64 = 0xCA;

/// Errors of the synthetic recorder.
#[derive(Debug, thiserror::Error)]
pub enum SynthError {
    #[error("{0}")]
    Subject(#[from] subject::SubjectError),
    #[error("{0}")]
    Measure(#[from] crate::measure::MeasureError),
    #[error(transparent)]
    Recording(#[from] RecordingError),
    #[error("{path}: {source}")]
    Io {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error(transparent)]
    Output(#[from] crate::io::atomic::AtomicError),
    #[error("{0}")]
    Invalid(String),
    /// The posed body has no skeleton to be found (a stance whose thighs merge below the
    /// crotch): the draw is unusable, not the configuration.
    #[error("the body cannot be analysed: {0}")]
    Unanalysable(String),
}

fn io_err(path: &Path) -> impl Fn(std::io::Error) -> SynthError + '_ {
    move |source| SynthError::Io {
        path: path.to_path_buf(),
        source,
    }
}

/// Portrait (720 wide, 1280 tall) or landscape (1280 x 720).
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum, Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Orientation {
    Portrait,
    Landscape,
}

/// Camera options (each unset one is drawn from the seed).
#[derive(Debug, Clone, Default, clap::Args)]
pub struct CameraOptions {
    /// Camera distance from the mark, metres (both cameras).
    #[arg(long)]
    pub distance_m: Option<f64>,
    /// Camera height, metres (both cameras).
    #[arg(long)]
    pub camera_height_m: Option<f64>,
    /// Frame orientation (both cameras).
    #[arg(long, value_enum)]
    pub orientation: Option<Orientation>,
    /// Render without lens distortion.
    #[arg(long)]
    pub no_distortion: bool,
    /// Render without mounting errors (ideal yaw/pitch/roll, centred principal point).
    #[arg(long)]
    pub ideal_mount: bool,
}

/// Everything a synthetic recording is made of.
#[derive(Debug, Clone)]
pub struct SynthConfig {
    pub seed: u64,
    pub subject: SubjectParams,
    pub cameras: CameraOptions,
    pub empty_frames: usize,
    pub subject_frames: usize,
    pub fps: f64,
    pub format: FrameFormat,
    /// Write the truth folder (masks, mesh, truth.json).
    pub truth: bool,
    /// Clothing as drawn from the seed, or in the backdrop's own colour
    /// ([`scene::Clothing::Camouflage`]).
    pub clothing: scene::Clothing,
    /// A second person walks behind the subject while it stands on the mark
    /// ([`passerby`]).
    pub passer_by: bool,
}

impl SynthConfig {
    /// Defaults for a seed: 12 empty + 12 subject frame pairs, MP4, subject from the seed.
    pub fn from_seed(seed: u64) -> SynthConfig {
        SynthConfig {
            seed,
            subject: SubjectParams::sample(seed),
            cameras: CameraOptions::default(),
            empty_frames: 12,
            subject_frames: 12,
            fps: crate::recording::DEFAULT_FPS,
            format: FrameFormat::Mp4,
            truth: true,
            clothing: scene::Clothing::Drawn,
            passer_by: false,
        }
    }
}

/// Draws one camera of the station for a subject of `stature_m`, facing the mark from
/// `direction` (unit, horizontal: +Z front, +X side).
pub fn sample_camera(
    rng: &mut SplitMix64,
    opts: &CameraOptions,
    direction: DVec3,
    stature_m: f64,
) -> Camera {
    let orientation = opts.orientation.unwrap_or(if rng.chance(0.5) {
        Orientation::Portrait
    } else {
        Orientation::Landscape
    });
    let (width, height) = match orientation {
        Orientation::Portrait => (FRAME_SHORT, FRAME_LONG),
        Orientation::Landscape => (FRAME_LONG, FRAME_SHORT),
    };
    let distance = opts
        .distance_m
        .unwrap_or_else(|| rng.range(DISTANCE_RANGE_M.0, DISTANCE_RANGE_M.1));
    let cam_height = opts
        .camera_height_m
        .unwrap_or_else(|| rng.range(CAMERA_HEIGHT_RANGE_M.0, CAMERA_HEIGHT_RANGE_M.1));
    let aim = DVec3::new(0.0, rng.range(0.47, 0.56) * stature_m, 0.0);
    let lateral = direction.cross(DVec3::Y);
    let (pos_err, ang_err) = if opts.ideal_mount {
        (0.0, 0.0)
    } else {
        (MOUNT_POSITION_ERR_M, MOUNT_ANGLE_ERR_DEG)
    };
    let eye = direction * distance + DVec3::Y * cam_height + lateral * rng.range(-pos_err, pos_err);
    let look = Rigid::camera_looking_at(eye, aim, DVec3::Y);
    // Small mounting error: a rotation in the camera frame (roll about z, pitch x, yaw y).
    let (yaw, pitch, roll) = (
        rng.range(-ang_err, ang_err).to_radians(),
        rng.range(-ang_err, ang_err).to_radians(),
        rng.range(-ang_err, ang_err).to_radians(),
    );
    let err =
        DMat3::from_rotation_z(roll) * DMat3::from_rotation_x(pitch) * DMat3::from_rotation_y(yaw);
    let rotation = err * look.rotation;
    let camera_from_station = Rigid {
        rotation,
        translation: -(rotation * eye),
    };
    let pp = if opts.ideal_mount { 0.0 } else { 0.015 };
    let mut intr = Intrinsics {
        width,
        height,
        fx: 1000.0,
        fy: 1000.0,
        cx: (width as f64 - 1.0) / 2.0 + rng.range(-pp, pp) * width as f64,
        cy: (height as f64 - 1.0) / 2.0 + rng.range(-pp, pp) * height as f64,
        dist: [0.0; 5],
    };
    let aspect = if opts.ideal_mount {
        1.0
    } else {
        rng.range(0.998, 1.002)
    };
    if !opts.no_distortion {
        loop {
            let d = [
                rng.range(-0.18, 0.06),
                rng.range(-0.05, 0.12),
                rng.range(-0.0015, 0.0015),
                rng.range(-0.0015, 0.0015),
                rng.range(-0.02, 0.02),
            ];
            if radially_monotonic(&d, 1.0) {
                intr.dist = d;
                break;
            }
        }
    }
    // Focal length: the largest that fits the body's box, times a random margin.
    let body_box = body_box(stature_m);
    let mut cam = Camera {
        intrinsics: intr,
        camera_from_station,
    };
    let fits = |c: &Camera| {
        body_box.iter().all(|p| {
            c.project(*p).is_some_and(|px| {
                let (w, h) = (c.intrinsics.width as f64, c.intrinsics.height as f64);
                let (mx, my) = (0.5 * (1.0 - MAX_FILL) * w, 0.5 * (1.0 - MAX_FILL) * h);
                px.x > mx && px.x < w - mx && px.y > my && px.y < h - my
            })
        })
    };
    let mut f = 3000.0;
    loop {
        cam.intrinsics.fx = f;
        cam.intrinsics.fy = f * aspect;
        if fits(&cam) || f < 200.0 {
            break;
        }
        f *= 0.99;
    }
    let margin = rng.range(0.85, 1.0);
    cam.intrinsics.fx *= margin;
    cam.intrinsics.fy *= margin;
    cam
}

/// Corners of a box that holds an adult of `stature_m` in the A-pose on the mark.
fn body_box(stature_m: f64) -> Vec<DVec3> {
    let half_w = 0.34 * stature_m;
    let mut out = Vec::with_capacity(8);
    for x in [-half_w, half_w] {
        for z in [-half_w, half_w] {
            for y in [-0.02, stature_m + 0.06] {
                out.push(DVec3::new(x, y, z));
            }
        }
    }
    out
}

/// True when the radial distortion r(1 + k1 r^2 + k2 r^4 + k3 r^6) increases up to
/// normalised radius `r_max` (the lens folds no part of the image back).
fn radially_monotonic(d: &[f64; 5], r_max: f64) -> bool {
    let [k1, k2, _, _, k3] = *d;
    (1..=100).all(|i| {
        let r2 = (r_max * i as f64 / 100.0).powi(2);
        1.0 + 3.0 * k1 * r2 + 5.0 * k2 * r2 * r2 + 7.0 * k3 * r2 * r2 * r2 > 0.2
    })
}

/// Draws the station calibration of a seed.
pub fn sample_station(seed: u64, opts: &CameraOptions, stature_m: f64) -> StationCalibration {
    let mut rng = SplitMix64::stream(seed, 0xCA);
    let front = sample_camera(&mut rng, opts, DVec3::Z, stature_m);
    let side = sample_camera(&mut rng, opts, DVec3::X, stature_m);
    let mut s = StationCalibration {
        front,
        side,
        extra: Vec::new(),
    };
    s.extra.push(("synthetic_seed".into(), seed.to_string()));
    s
}

/// Per-frame sway: small rotations about the ankles (x: forward/back, z: sideways).
#[derive(Debug, Clone, Copy, Serialize, serde::Deserialize)]
pub struct Sway {
    pub amplitude_deg: [f64; 2],
    pub period_s: [f64; 2],
    pub phase: [f64; 2],
}

/// Height of the ankle pivot of the sway, metres.
const ANKLE_M: f64 = 0.08;

impl Sway {
    pub fn sample(rng: &mut SplitMix64) -> Sway {
        Sway {
            amplitude_deg: [
                rng.range(SWAY_DEG.0, SWAY_DEG.1),
                rng.range(SWAY_DEG.0, SWAY_DEG.1),
            ],
            period_s: [
                rng.range(SWAY_PERIOD_S.0, SWAY_PERIOD_S.1),
                rng.range(SWAY_PERIOD_S.0, SWAY_PERIOD_S.1),
            ],
            phase: [
                rng.range(0.0, std::f64::consts::TAU),
                rng.range(0.0, std::f64::consts::TAU),
            ],
        }
    }
    /// Angles (degrees about x and z) at time `t_s`.
    pub fn angles_deg(&self, t_s: f64) -> [f64; 2] {
        [0, 1].map(|i| {
            self.amplitude_deg[i]
                * (std::f64::consts::TAU * t_s / self.period_s[i] + self.phase[i]).sin()
        })
    }
    /// The sway motion at `t_s` about the ankle point `pivot`.
    pub fn motion(&self, t_s: f64, pivot: DVec3) -> Rigid {
        let [ax, az] = self.angles_deg(t_s);
        let r = DMat3::from_rotation_x(ax.to_radians()) * DMat3::from_rotation_z(az.to_radians());
        let pivot = DVec3::new(pivot.x, ANKLE_M, pivot.z);
        Rigid {
            rotation: r,
            translation: pivot - r * pivot,
        }
    }
}

/// truth.json: everything known about a synthetic recording that the station must find.
#[derive(Debug, Clone, Serialize, serde::Deserialize)]
pub struct Truth {
    pub format: String,
    pub seed: u64,
    pub subject: SubjectParams,
    pub body_source: String,
    pub placement: Placement,
    pub sway: Sway,
    /// Measurements of `mesh.obj` (the measurement module's keys), millimetres.
    pub measurements_mm: BTreeMap<String, f64>,
    /// Landmarks of `mesh.obj`, station frame, metres.
    pub landmarks: Landmarks,
    pub fps: f64,
    pub frames: TruthFrames,
    pub per_frame: Vec<TruthFrame>,
    /// The ANSUR II person the body follows (`--population ansur`): id, sex, the
    /// values used (mm) and the drawn local shape. No personal field.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub ansur: Option<ansur_body::AnsurSubject>,
    /// The drawn stance (`--stance varied`); `mesh.obj` and the measurements are of the
    /// posed, turned body.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub stance: Option<stance::Stance>,
    /// The second person walking behind the subject (`--passer-by`): not in the masks,
    /// the mesh or the measurements.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub passer_by: Option<passerby::PasserByPath>,
}

#[derive(Debug, Clone, Serialize, serde::Deserialize)]
pub struct TruthFrames {
    pub total: usize,
    pub empty: usize,
    pub with_subject: usize,
}

/// Truth of one frame pair.
#[derive(Debug, Clone, Serialize, serde::Deserialize)]
pub struct TruthFrame {
    pub index: usize,
    pub subject: bool,
    /// Sway angles about x and z, degrees (zero on empty frames).
    pub sway_deg: [f64; 2],
    /// Landmark pixels per view (distorted image), empty on empty frames.
    pub landmarks_px: BTreeMap<String, BTreeMap<String, [f64; 2]>>,
    /// Body pixels per view.
    pub mask_area_px: BTreeMap<String, usize>,
}

/// Where the truth of a recording lives: `<recording>.truth/`.
pub fn truth_dir(recording: &Path) -> PathBuf {
    let name = recording
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| "recording".into());
    recording.with_file_name(format!("{name}{TRUTH_SUFFIX}"))
}

/// What a synthetic run produced and how long it took.
#[derive(Debug, Clone)]
pub struct SynthSummary {
    pub recording: PathBuf,
    pub truth: Option<PathBuf>,
    pub frame_pairs: usize,
    pub setup_ms: f64,
    /// Mean time to render one frame pair (both views), milliseconds.
    pub render_ms_per_pair: f64,
    /// Mean time to write (encode) one frame pair, milliseconds.
    pub write_ms_per_pair: f64,
    pub measurements_mm: BTreeMap<String, f64>,
}

/// Reads a recording's truth.json.
pub fn load_truth(truth_dir: &Path) -> Result<Truth, SynthError> {
    let p = truth_dir.join("truth.json");
    let text = std::fs::read_to_string(&p).map_err(io_err(&p))?;
    serde_json::from_str(&text).map_err(|e| SynthError::Invalid(format!("{}: {e}", p.display())))
}

/// Projects station points with the renderer's camera model (the function whose
/// agreement with `cv2.projectPoints` the OpenCV reference test checks).
pub fn project_points(camera: &Camera, points: &[DVec3]) -> Vec<Option<DVec2>> {
    points.iter().map(|p| camera.project(*p)).collect()
}

/// The canonical (un-placed) body of a subject, for callers that need the mesh alone.
pub fn subject_mesh(params: &SubjectParams) -> Result<TriMesh, SynthError> {
    Ok(subject::subject_body(params)?.mesh)
}
