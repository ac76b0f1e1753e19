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
//!     person's stature, crotch height, chest/waist/buttock breadths and depths and
//!     thigh circumference, plus local shape variation ([`ansur_body`]);
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
pub mod passerby;
pub mod raster;
pub mod rng;
pub mod scene;
pub mod stance;
pub mod subject;

use crate::camera::{Camera, Intrinsics, Rigid, StationCalibration, View};
use crate::mesh::TriMesh;
use crate::recording::{FrameFormat, RecordingError, RecordingMeta, RecordingWriter};
use glam::{DMat3, DVec2, DVec3};
use raster::Rasterizer;
use rng::SplitMix64;
use scene::{Background, Dress, Film, FloorShadows, Scene};
use serde::Serialize;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::time::Instant;
use subject::{Landmarks, Placement, SubjectParams};

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

/// Per-view executor: camera, scene background and the reusable buffers.
struct ViewRenderer {
    view: View,
    camera: Camera,
    film: Film,
    background: Background,
    with_shadow: Vec<[f32; 3]>,
    raster: Rasterizer,
    radiance: Vec<[f32; 3]>,
    scratch: Vec<[f32; 3]>,
    frame: image::RgbImage,
}

/// Renders a synthetic recording to `out` (and its truth beside it).
///
/// # Errors
/// The body source or the measurements fail, or a file cannot be written.
pub fn render_recording(cfg: &SynthConfig, out: &Path) -> Result<SynthSummary, SynthError> {
    if cfg.empty_frames < MIN_EMPTY_FRAMES {
        return Err(SynthError::Invalid(format!(
            "at least {MIN_EMPTY_FRAMES} empty frames are needed (formats.md), got {}",
            cfg.empty_frames
        )));
    }
    let t0 = Instant::now();
    let body = subject::subject_body(&cfg.subject)?;
    let canonical = body.mesh;
    let stature = canonical
        .bounds()
        .map(|b| b.size().y)
        .ok_or_else(|| SynthError::Invalid("the body mesh is empty".into()))?;
    let calib = sample_station(cfg.seed, &cfg.cameras, stature);
    let mut rng = SplitMix64::stream(cfg.seed, 0x5C);
    let mut scene = Scene::random(&mut rng, [&calib.front, &calib.side]);
    if cfg.clothing == scene::Clothing::Camouflage {
        // A stream of its own: the other draws of the seed stay as in a plain set.
        scene
            .look
            .camouflage(&mut SplitMix64::stream(cfg.seed, CAMOUFLAGE_STREAM));
    }
    let placement = Placement::sample(&mut rng);
    let sway = Sway::sample(&mut rng);
    // The body's skeleton and landmarks (method.md section 1) dress it and are truth.
    let info = crate::body::prepare(&canonical)
        .map_err(|e| SynthError::Invalid(format!("the body cannot be analysed: {e}")))?;
    let mut canonical_landmarks = subject::template_landmarks(&info);
    // The top of the head is the highest vertex (the skeleton's head-top joint is a
    // proportion, not a surface point).
    if let Some(top) = canonical
        .positions
        .iter()
        .max_by(|a, b| a.y.total_cmp(&b.y))
    {
        canonical_landmarks.insert("head_top".into(), top.to_array());
    }
    let dress = Dress::new(&canonical, scene::Skeleton::from_template(&info));
    let mut truth_mesh = canonical.clone();
    truth_mesh.map_positions(|p| placement.apply(p));
    let tdir = truth_dir(out);
    let measurements = if cfg.truth {
        // The truth is the mesh as stored (OBJ keeps micrometres): write it, read it
        // back, and measure and render that, so re-measuring mesh.obj gives truth.json.
        crate::io::atomic::create_dir(&tdir)?;
        let obj = tdir.join("mesh.obj");
        crate::mesh::io::write_obj(&obj, &truth_mesh)
            .map_err(|e| SynthError::Invalid(e.to_string()))?;
        let stored = crate::mesh::io::read_obj(&obj, None)
            .map_err(|e| SynthError::Invalid(e.to_string()))?;
        if stored.positions.len() == truth_mesh.positions.len()
            && stored.triangles == truth_mesh.triangles
        {
            truth_mesh = stored;
        }
        subject::measurements_mm(&truth_mesh)?
    } else {
        BTreeMap::new()
    };
    let landmarks: Landmarks = canonical_landmarks
        .iter()
        .map(|(k, p)| (k.clone(), placement.apply(DVec3::from_array(*p)).to_array()))
        .collect();
    let canonical_normals = canonical.vertex_normals();
    let pivot = DVec3::new(placement.offset_m[0], 0.0, placement.offset_m[1]);

    let shadows = FloorShadows::compute(&scene, &truth_mesh.positions, &truth_mesh.triangles);
    let mut views: Vec<ViewRenderer> = View::BOTH
        .iter()
        .map(|&view| {
            let camera = *calib.camera(view);
            let mut frng = SplitMix64::stream(cfg.seed, 0xF0 + view as u64);
            let background = Background::render(&scene, &camera);
            let mut with_shadow = Vec::new();
            background.with_shadows(&shadows, &mut with_shadow);
            let mut film = Film::random(&mut frng);
            film.auto_expose(&background.empty);
            ViewRenderer {
                view,
                camera,
                film,
                background,
                with_shadow,
                raster: Rasterizer::new(camera.intrinsics.width, camera.intrinsics.height),
                radiance: Vec::new(),
                scratch: Vec::new(),
                frame: image::RgbImage::new(camera.intrinsics.width, camera.intrinsics.height),
            }
        })
        .collect();
    let mut passer_by = if cfg.passer_by {
        // Through the middle half of the subject's frames: still frames before and after.
        let (first, frames) = passerby::walk_frames(cfg.empty_frames, cfg.subject_frames);
        Some(passerby::PasserBy::new(
            cfg.seed,
            &scene,
            first,
            frames,
            [&calib.front, &calib.side],
        )?)
    } else {
        None
    };
    let setup_ms = t0.elapsed().as_secs_f64() * 1e3;

    let meta = RecordingMeta {
        fps: cfg.fps,
        stature_m: None,
        notes: Some(format!(
            "synthetic recording, seed {}{}{}; ground truth in the sibling .truth folder",
            cfg.seed,
            if cfg.clothing == scene::Clothing::Camouflage {
                ", clothing in the backdrop's colour (camouflage)"
            } else {
                ""
            },
            if cfg.passer_by {
                ", a second person walks behind the subject"
            } else {
                ""
            }
        )),
        date: None,
    };
    let mut writer = RecordingWriter::with_meta(out, &calib, cfg.format, meta)?;
    if cfg.truth {
        for v in View::BOTH {
            let d = tdir.join("masks").join(v.name());
            crate::io::atomic::create_dir(&d)?;
        }
    }
    let total = cfg.empty_frames + cfg.subject_frames;
    let mut posed = truth_mesh.positions.clone();
    let mut normals = canonical_normals.clone();
    let mut per_frame = Vec::with_capacity(total);
    let mut flicker_rng = SplitMix64::stream(cfg.seed, 0xE1);
    let (mut render_s, mut write_s) = (0.0, 0.0);
    let mut mask = image::GrayImage::new(1, 1);
    for k in 0..total {
        let has_subject = k >= cfg.empty_frames;
        let t_s = k as f64 / cfg.fps;
        let motion = sway.motion(t_s, pivot);
        let rot = motion.rotation * placement.rotation();
        if has_subject {
            for (i, p) in truth_mesh.positions.iter().enumerate() {
                posed[i] = motion.apply(*p);
                normals[i] = rot * canonical_normals[i];
            }
        }
        let mut tf = TruthFrame {
            index: k,
            subject: has_subject,
            sway_deg: if has_subject {
                sway.angles_deg(t_s)
            } else {
                [0.0; 2]
            },
            landmarks_px: BTreeMap::new(),
            mask_area_px: BTreeMap::new(),
        };
        let tr = Instant::now();
        for vr in views.iter_mut() {
            let gain = 1.0 + vr.film.flicker * flicker_rng.normal() as f32;
            vr.radiance.clear();
            vr.radiance.extend_from_slice(if has_subject {
                &vr.with_shadow
            } else {
                &vr.background.empty
            });
            vr.raster.clear();
            if has_subject {
                let body = scene::BodyFrame {
                    posed: &posed,
                    canonical: &canonical.positions,
                    normals: &normals,
                    triangles: &canonical.triangles,
                };
                scene::draw_body(
                    &scene,
                    &dress,
                    &vr.camera,
                    &mut vr.raster,
                    &body,
                    &mut vr.radiance,
                );
            }
            if let Some(pb) = passer_by.as_mut() {
                pb.draw(
                    k,
                    vr.view as usize,
                    &vr.camera,
                    &vr.raster,
                    &mut vr.radiance,
                );
            }
            let mut nrng =
                SplitMix64::stream(cfg.seed, ((k as u64) << 8) | (0x10 + vr.view as u64));
            vr.film.develop(
                &mut vr.radiance,
                &mut vr.scratch,
                gain,
                &mut nrng,
                &mut vr.frame,
            );
        }
        render_s += tr.elapsed().as_secs_f64();
        let tw = Instant::now();
        writer.push_pair(&views[0].frame, &views[1].frame)?;
        write_s += tw.elapsed().as_secs_f64();
        if cfg.truth {
            for vr in &views {
                let (w, h) = (vr.camera.intrinsics.width, vr.camera.intrinsics.height);
                if mask.width() != w || mask.height() != h {
                    mask = image::GrayImage::new(w, h);
                }
                let mut area = 0usize;
                for (dst, covered) in mask.as_mut().iter_mut().zip(vr.raster.coverage()) {
                    *dst = if covered { 255 } else { 0 };
                    area += covered as usize;
                }
                let p = tdir
                    .join("masks")
                    .join(vr.view.name())
                    .join(format!("{k:06}.png"));
                crate::io::atomic::save_image(&p, &mask)?;
                tf.mask_area_px.insert(vr.view.name().into(), area);
                if has_subject {
                    let mut lm = BTreeMap::new();
                    for (name, p) in &landmarks {
                        if let Some(px) = vr.camera.project(motion.apply(DVec3::from_array(*p))) {
                            lm.insert(name.clone(), [px.x, px.y]);
                        }
                    }
                    tf.landmarks_px.insert(vr.view.name().into(), lm);
                }
            }
        }
        per_frame.push(tf);
    }
    writer.finish()?;
    if cfg.truth {
        let truth = Truth {
            format: "fitstation-synth-truth/1".into(),
            seed: cfg.seed,
            subject: cfg.subject.clone(),
            body_source: body.source,
            placement,
            sway,
            measurements_mm: measurements.clone(),
            landmarks,
            fps: cfg.fps,
            frames: TruthFrames {
                total,
                empty: cfg.empty_frames,
                with_subject: cfg.subject_frames,
            },
            per_frame,
            ansur: cfg.subject.ansur.clone(),
            stance: cfg.subject.stance.clone(),
            passer_by: passer_by.as_ref().map(|p| p.path.clone()),
        };
        let p = tdir.join("truth.json");
        let text =
            serde_json::to_string_pretty(&truth).map_err(|e| SynthError::Invalid(e.to_string()))?;
        crate::io::atomic::write(&p, text)?;
    }
    Ok(SynthSummary {
        recording: out.to_path_buf(),
        truth: cfg.truth.then_some(tdir),
        frame_pairs: total,
        setup_ms,
        render_ms_per_pair: render_s * 1e3 / total as f64,
        write_ms_per_pair: write_s * 1e3 / total as f64,
        measurements_mm: measurements,
    })
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

/// Subject parameters on the command line (each unset one is drawn from the seed).
#[derive(Debug, Clone, Default, clap::Args)]
pub struct SubjectOptions {
    /// 0 = female .. 1 = male, or "female"/"male".
    #[arg(long)]
    pub gender: Option<String>,
    /// Age in years (the library's adults: 25 to 90; younger is taken as 25).
    #[arg(long)]
    pub age_years: Option<f64>,
    /// 0..1.
    #[arg(long)]
    pub muscle: Option<f64>,
    /// 0..1 (0.5 average).
    #[arg(long)]
    pub weight: Option<f64>,
    /// MakeHuman's height slider, 0..1 (0.5 average; its ends are extreme).
    #[arg(long)]
    pub height: Option<f64>,
    /// 0..1 (0 uncommon .. 1 ideal proportions).
    #[arg(long)]
    pub proportions: Option<f64>,
    /// Rescale the body uniformly to this stature, metres.
    #[arg(long)]
    pub stature_m: Option<f64>,
}

impl SubjectOptions {
    fn apply(&self, mut p: SubjectParams) -> anyhow::Result<SubjectParams> {
        if let Some(g) = &self.gender {
            p.shape.gender = match g.to_ascii_lowercase().as_str() {
                "female" | "f" => 0.0,
                "male" | "m" => 1.0,
                v => v
                    .parse::<f64>()
                    .ok()
                    .filter(|x| (0.0..=1.0).contains(x))
                    .ok_or_else(|| {
                        anyhow::anyhow!(
                            "--gender must be female, male or a number in 0..1, got '{v}'"
                        )
                    })?,
            };
        }
        let unit = |name: &str, v: Option<f64>, into: &mut f64| -> anyhow::Result<()> {
            if let Some(v) = v {
                anyhow::ensure!(
                    (0.0..=1.0).contains(&v),
                    "--{name} must be in 0..1, got {v}"
                );
                *into = v;
            }
            Ok(())
        };
        unit("muscle", self.muscle, &mut p.shape.muscle)?;
        unit("weight", self.weight, &mut p.shape.weight)?;
        unit("height", self.height, &mut p.shape.height)?;
        unit("proportions", self.proportions, &mut p.shape.proportions)?;
        if let Some(a) = self.age_years {
            anyhow::ensure!(
                (1.0..=100.0).contains(&a),
                "--age-years must be in 1..100, got {a}"
            );
            p.shape.age_years = a;
        }
        if let Some(s) = self.stature_m {
            anyhow::ensure!(
                (1.2..=2.2).contains(&s),
                "--stature-m must be in 1.2..2.2 m, got {s}"
            );
            p.stature_m = Some(s);
        }
        Ok(p)
    }
}

/// `fitstation synth`: render one synthetic recording with its ground truth.
#[derive(Debug, Clone, clap::Args)]
pub struct SynthArgs {
    /// Recording folder to write (the truth goes to `<out>.truth/`).
    #[arg(long)]
    pub out: PathBuf,
    /// Seed: subject, cameras, scene, noise.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    #[command(flatten)]
    pub subject: SubjectOptions,
    #[command(flatten)]
    pub cameras: CameraOptions,
    /// Frame pairs of the empty scene at the start (>= 10).
    #[arg(long, default_value_t = 12)]
    pub empty_frames: usize,
    /// Frame pairs with the subject.
    #[arg(long, default_value_t = 12)]
    pub subject_frames: usize,
    #[arg(long, default_value_t = 30.0)]
    pub fps: f64,
    /// Frame storage.
    #[arg(long, value_enum, default_value_t = FrameFormat::Mp4)]
    pub format: FrameFormat,
    /// Do not write the truth folder.
    #[arg(long)]
    pub no_truth: bool,
}

/// Random stream of the camouflage colours (`SplitMix64::stream` label).
const CAMOUFLAGE_STREAM: u64 = 0xCA;

/// Runs `fitstation synth`.
pub fn run(args: SynthArgs) -> anyhow::Result<()> {
    if let Some(d) = args.cameras.distance_m {
        anyhow::ensure!(
            (1.0..=8.0).contains(&d),
            "--distance-m {d} is not a station distance (1 to 8 m)"
        );
    }
    if let Some(h) = args.cameras.camera_height_m {
        anyhow::ensure!(
            (0.2..=2.6).contains(&h),
            "--camera-height-m {h} is not a camera height (0.2 to 2.6 m)"
        );
    }
    anyhow::ensure!(
        args.fps > 0.0 && args.fps <= 240.0,
        "--fps {} is not a frame rate",
        args.fps
    );
    anyhow::ensure!(
        args.subject_frames > 0,
        "--subject-frames must be at least 1"
    );
    let subject = args.subject.apply(SubjectParams::sample(args.seed))?;
    let cfg = SynthConfig {
        seed: args.seed,
        subject,
        cameras: args.cameras.clone(),
        empty_frames: args.empty_frames,
        subject_frames: args.subject_frames,
        fps: args.fps,
        format: args.format,
        truth: !args.no_truth,
        clothing: scene::Clothing::Drawn,
        passer_by: false,
    };
    let s = render_recording(&cfg, &args.out)?;
    print_summary(&s);
    Ok(())
}

fn print_summary(s: &SynthSummary) {
    println!(
        "{}: {} frame pairs; setup {:.0} ms, render {:.1} ms/pair, write {:.1} ms/pair{}",
        s.recording.display(),
        s.frame_pairs,
        s.setup_ms,
        s.render_ms_per_pair,
        s.write_ms_per_pair,
        s.truth
            .as_ref()
            .map(|t| format!("; truth in {}", t.display()))
            .unwrap_or_default()
    );
}

/// `fitstation synth-set`: a deterministic evaluation set of subjects across genders and
/// builds (seeds `first-seed .. first-seed + count`). Bodies from the fit's own shape
/// library (default, the regression set) or following real ANSUR II people
/// (`--population ansur`); in the rest A-pose or a stance drawn per subject (`--stance
/// varied`). Seeds 30000 and above are kept unseen for final judgements.
#[derive(Debug, Clone, clap::Args)]
pub struct SynthSetArgs {
    /// Folder receiving `subject_NN` recordings and their truth folders.
    #[arg(long)]
    pub out: PathBuf,
    #[arg(long, default_value_t = 12)]
    pub count: usize,
    #[arg(long, default_value_t = 1000)]
    pub first_seed: u64,
    #[arg(long, value_enum, default_value_t = FrameFormat::Mp4)]
    pub format: FrameFormat,
    /// Arms turned from the library's rest A-pose, degrees (positive: away from the body).
    #[arg(long, default_value_t = 0.0, allow_hyphen_values = true)]
    pub arms_deg: f64,
    /// Legs turned from the rest pose, degrees (positive: apart).
    #[arg(long, default_value_t = 0.0, allow_hyphen_values = true)]
    pub legs_deg: f64,
    /// Bodies outside the shape library: trunk and legs this much wider (fraction, e.g.
    /// 0.06) about `--warp-at`.
    #[arg(long, default_value_t = 0.0, allow_hyphen_values = true)]
    pub warp_width: f64,
    /// ... and this much deeper, front to back (fraction).
    #[arg(long, default_value_t = 0.0, allow_hyphen_values = true)]
    pub warp_depth: f64,
    /// Height of the warp, fraction of stature (0.52 hips, 0.6 waist, 0.72 chest).
    #[arg(long, default_value_t = 0.6)]
    pub warp_at: f64,
    /// Where the bodies come from: `library` (the fit's own shape library: the
    /// regression set) or `ansur` (each subject one real ANSUR II person, a shape the
    /// library cannot make).
    #[arg(long, value_enum, default_value_t = Population::Library)]
    pub population: Population,
    /// `rest` (the library's A-pose) or `varied` (arms, elbows, legs and a turn of the
    /// whole body drawn per subject).
    #[arg(long, value_enum, default_value_t = StanceKind::Rest)]
    pub stance: StanceKind,
    /// Folder of the ANSUR II CSV files (default ../shared/data/ansur2 from the current
    /// folder, else beside the source tree).
    #[arg(long)]
    pub ansur_dir: Option<PathBuf>,
    /// Shirt and leggings in the backdrop's colour, 15 to 40 levels off (the case a
    /// backdrop model cannot see); the other draws of each seed are the plain set's.
    #[arg(long)]
    pub camouflage: bool,
    /// A second person walks behind each subject while it stands on the mark (behind it
    /// in the front view, beside it in the side view); not part of the truth.
    #[arg(long)]
    pub passer_by: bool,
}

/// Where the bodies of an evaluation set come from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum Population {
    /// The shape library's macro model (the fit's own candidates).
    Library,
    /// Real people: ANSUR II, the library body warped to each person.
    Ansur,
}

/// The stance of an evaluation set's subjects.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum StanceKind {
    /// The library's rest A-pose.
    Rest,
    /// Drawn per subject: arms -12..+10 deg at the shoulders, elbows bent 0..15 deg
    /// (forearms forward), legs -3..+4 deg, the whole body turned up to 4 deg.
    Varied,
}

/// The subject of member `i` of an evaluation set: alternating genders, builds spread
/// over the weight range, other parameters (age, muscle, height, proportions) drawn by
/// the shape library from the seed.
pub fn set_member(first_seed: u64, i: usize, count: usize) -> SynthConfig {
    let seed = first_seed + i as u64;
    let mut cfg = SynthConfig::from_seed(seed);
    cfg.subject.shape.gender = if i.is_multiple_of(2) { 0.0 } else { 1.0 };
    let pairs = count.div_ceil(2).max(1);
    cfg.subject.shape.weight = 0.1 + 0.8 * ((i / 2) as f64 + 0.5) / pairs as f64;
    cfg
}

/// Member `i` of an ANSUR II evaluation set: seed `first_seed + i`, women at even `i`
/// and men at odd, the person's row drawn from the seed, the library body nearest in
/// gender, stature and build as the start ([`ansur_body::macro_params`]), the local
/// shape drawn from the seed.
pub fn ansur_member(table: &ansur::AnsurTable, first_seed: u64, i: usize) -> SynthConfig {
    let seed = first_seed + i as u64;
    let mut cfg = SynthConfig::from_seed(seed);
    let sex = if i.is_multiple_of(2) {
        ansur::Sex::Female
    } else {
        ansur::Sex::Male
    };
    let record = table.pick(seed, sex).clone();
    cfg.subject.shape = ansur_body::macro_params(&record);
    cfg.subject.ansur = Some(ansur_body::AnsurSubject {
        record,
        local: ansur_body::LocalShape::sample(seed),
    });
    cfg
}

/// Runs `fitstation synth-set`.
pub fn run_set(args: SynthSetArgs) -> anyhow::Result<()> {
    let table = match args.population {
        Population::Library => None,
        Population::Ansur => {
            let dir = ansur::resolve_dir(args.ansur_dir.as_deref())?;
            Some(ansur::AnsurTable::load(&dir)?)
        }
    };
    crate::io::atomic::create_dir(&args.out)?;
    for i in 0..args.count {
        let mut cfg = match &table {
            None => set_member(args.first_seed, i, args.count),
            Some(t) => ansur_member(t, args.first_seed, i),
        };
        if args.stance == StanceKind::Varied {
            cfg.subject.stance = Some(stance::Stance::sample(cfg.seed));
        }
        cfg.format = args.format;
        if args.camouflage {
            cfg.clothing = scene::Clothing::Camouflage;
        }
        cfg.passer_by = args.passer_by;
        cfg.subject.pose = subject::LimbPose {
            arms_deg: args.arms_deg,
            legs_deg: args.legs_deg,
        };
        cfg.subject.warp = subject::BodyWarp {
            width: args.warp_width,
            depth: args.warp_depth,
            at: args.warp_at,
        };
        let out = args.out.join(format!("subject_{i:02}"));
        let s = render_recording(&cfg, &out)?;
        print_summary(&s);
    }
    Ok(())
}

/// The canonical (un-placed) body of a subject, for callers that need the mesh alone.
pub fn subject_mesh(params: &SubjectParams) -> Result<TriMesh, SynthError> {
    Ok(subject::subject_body(params)?.mesh)
}
