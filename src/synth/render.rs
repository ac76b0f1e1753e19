//! Rendering a synthetic recording ([`render_recording`]): the subject staged in a
//! sampled station and scene, then frame by frame the posed body drawn into each view's
//! backdrop, developed into 8-bit frames and written, with the truth (masks, landmark
//! pixels, truth.json) beside the recording.

use super::passerby;
use super::raster::Rasterizer;
use super::rng::SplitMix64;
use super::scene::{self, Background, Dress, Film, FloorShadows, Scene};
use super::subject::{self, Landmarks, Placement};
use super::{
    sample_station, truth_dir, Rigid, Sway, SynthConfig, SynthError, SynthSummary, Truth,
    TruthFrame, TruthFrames, CAMOUFLAGE_STREAM, MIN_EMPTY_FRAMES,
};
use crate::camera::{Camera, StationCalibration, View};
use crate::mesh::TriMesh;
use crate::recording::{RecordingMeta, RecordingWriter};
use glam::DVec3;
use std::collections::BTreeMap;
use std::path::Path;
use std::time::Instant;

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

/// What every frame of a recording shares: the body in its canonical pose and where it
/// stands, the station, the lit scene, the truth mesh (as stored) and its landmarks.
struct Staged {
    body_source: String,
    canonical: TriMesh,
    calib: StationCalibration,
    scene: Scene,
    placement: Placement,
    sway: Sway,
    dress: Dress,
    truth_mesh: TriMesh,
    measurements: BTreeMap<String, f64>,
    landmarks: Landmarks,
}

/// The body posed for one frame: positions and normals of the swaying body.
struct Pose {
    posed: Vec<DVec3>,
    normals: Vec<DVec3>,
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
    let tdir = truth_dir(out);
    let st = stage(cfg, &tdir)?;
    let canonical_normals = st.canonical.vertex_normals();
    let pivot = DVec3::new(st.placement.offset_m[0], 0.0, st.placement.offset_m[1]);
    let mut views = view_renderers(cfg, &st);
    let mut passer_by = if cfg.passer_by {
        // Through the middle half of the subject's frames: still frames before and after.
        let (first, frames) = passerby::walk_frames(cfg.empty_frames, cfg.subject_frames);
        let cameras = [&st.calib.front, &st.calib.side];
        Some(passerby::PasserBy::new(
            cfg.seed, &st.scene, first, frames, cameras,
        )?)
    } else {
        None
    };
    let setup_ms = t0.elapsed().as_secs_f64() * 1e3;

    let mut writer = open_writer(cfg, out, &st.calib, &tdir)?;
    let total = cfg.empty_frames + cfg.subject_frames;
    let mut pose = Pose {
        posed: st.truth_mesh.positions.clone(),
        normals: canonical_normals.clone(),
    };
    let mut per_frame = Vec::with_capacity(total);
    let mut flicker_rng = SplitMix64::stream(cfg.seed, 0xE1);
    let (mut render_s, mut write_s) = (0.0, 0.0);
    let mut mask = image::GrayImage::new(1, 1);
    for k in 0..total {
        let has_subject = k >= cfg.empty_frames;
        let t_s = k as f64 / cfg.fps;
        let motion = st.sway.motion(t_s, pivot);
        if has_subject {
            let rot = motion.rotation * st.placement.rotation();
            for (i, p) in st.truth_mesh.positions.iter().enumerate() {
                pose.posed[i] = motion.apply(*p);
                pose.normals[i] = rot * canonical_normals[i];
            }
        }
        let mut tf = TruthFrame {
            index: k,
            subject: has_subject,
            sway_deg: if has_subject {
                st.sway.angles_deg(t_s)
            } else {
                [0.0; 2]
            },
            landmarks_px: BTreeMap::new(),
            mask_area_px: BTreeMap::new(),
        };
        let tr = Instant::now();
        for vr in views.iter_mut() {
            let gain = 1.0 + vr.film.flicker * flicker_rng.normal() as f32;
            let subject = has_subject.then_some(&pose);
            render_view(cfg, &st, vr, subject, passer_by.as_mut(), k, gain);
        }
        render_s += tr.elapsed().as_secs_f64();
        let tw = Instant::now();
        writer.push_pair(&views[0].frame, &views[1].frame)?;
        write_s += tw.elapsed().as_secs_f64();
        if cfg.truth {
            for vr in &views {
                let landmarks = has_subject.then_some((&st.landmarks, &motion));
                write_truth_view(vr, &tdir, k, landmarks, &mut mask, &mut tf)?;
            }
        }
        per_frame.push(tf);
    }
    writer.finish()?;
    if cfg.truth {
        let walk = passer_by.as_ref().map(|p| p.path.clone());
        write_truth_json(cfg, &st, &tdir, total, per_frame, walk)?;
    }
    Ok(SynthSummary {
        recording: out.to_path_buf(),
        truth: cfg.truth.then_some(tdir),
        frame_pairs: total,
        setup_ms,
        render_ms_per_pair: render_s * 1e3 / total as f64,
        write_ms_per_pair: write_s * 1e3 / total as f64,
        measurements_mm: st.measurements,
    })
}

/// Stages the subject: its body and the station sampled for its stature, the scene,
/// where it stands and how it sways, its dress, and the truth mesh (written to and read
/// back from `tdir` with the truth on) with its measurements and landmarks.
fn stage(cfg: &SynthConfig, tdir: &Path) -> Result<Staged, SynthError> {
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
    let info =
        crate::body::prepare(&canonical).map_err(|e| SynthError::Unanalysable(e.to_string()))?;
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
    let measurements = if cfg.truth {
        // The truth is the mesh as stored (OBJ keeps micrometres): write it, read it
        // back, and measure and render that, so re-measuring mesh.obj gives truth.json.
        crate::io::atomic::create_dir(tdir)?;
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
    Ok(Staged {
        body_source: body.source,
        canonical,
        calib,
        scene,
        placement,
        sway,
        dress,
        truth_mesh,
        measurements,
        landmarks,
    })
}

/// Each view's renderer: the backdrop rendered once, with and without the body's floor
/// shadow, and a film exposed for the empty scene.
fn view_renderers(cfg: &SynthConfig, st: &Staged) -> Vec<ViewRenderer> {
    let shadows = FloorShadows::compute(
        &st.scene,
        &st.truth_mesh.positions,
        &st.truth_mesh.triangles,
    );
    View::BOTH
        .iter()
        .map(|&view| {
            let camera = *st.calib.camera(view);
            let mut frng = SplitMix64::stream(cfg.seed, 0xF0 + view as u64);
            let background = Background::render(&st.scene, &camera);
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
        .collect()
}

/// The recording's writer with its metadata, and the truth's mask folders.
fn open_writer(
    cfg: &SynthConfig,
    out: &Path,
    calib: &StationCalibration,
    tdir: &Path,
) -> Result<RecordingWriter, SynthError> {
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
    let writer = RecordingWriter::with_meta(out, calib, cfg.format, meta)?;
    if cfg.truth {
        for v in View::BOTH {
            let d = tdir.join("masks").join(v.name());
            crate::io::atomic::create_dir(&d)?;
        }
    }
    Ok(writer)
}

/// Frame `k` of one view: the backdrop (with the body's shadow when the subject is in),
/// the posed body drawn over it (and a passer-by, depth-tested against it), developed
/// at exposure `gain` with the frame's noise.
fn render_view(
    cfg: &SynthConfig,
    st: &Staged,
    vr: &mut ViewRenderer,
    subject: Option<&Pose>,
    passer_by: Option<&mut passerby::PasserBy>,
    k: usize,
    gain: f32,
) {
    vr.radiance.clear();
    vr.radiance.extend_from_slice(if subject.is_some() {
        &vr.with_shadow
    } else {
        &vr.background.empty
    });
    vr.raster.clear();
    if let Some(pose) = subject {
        let body = scene::BodyFrame {
            posed: &pose.posed,
            canonical: &st.canonical.positions,
            normals: &pose.normals,
            triangles: &st.canonical.triangles,
        };
        scene::draw_body(
            &st.scene,
            &st.dress,
            &vr.camera,
            &mut vr.raster,
            &body,
            &mut vr.radiance,
        );
    }
    if let Some(pb) = passer_by {
        pb.draw(
            k,
            vr.view as usize,
            &vr.camera,
            &vr.raster,
            &mut vr.radiance,
        );
    }
    let mut nrng = SplitMix64::stream(cfg.seed, ((k as u64) << 8) | (0x10 + vr.view as u64));
    vr.film.develop(
        &mut vr.radiance,
        &mut vr.scratch,
        gain,
        &mut nrng,
        &mut vr.frame,
    );
}

/// The truth of frame `k` in one view: the body's mask (written as PNG) and its area,
/// and with the subject in, the landmarks moved by `motion` and projected.
fn write_truth_view(
    vr: &ViewRenderer,
    tdir: &Path,
    k: usize,
    landmarks: Option<(&Landmarks, &Rigid)>,
    mask: &mut image::GrayImage,
    tf: &mut TruthFrame,
) -> Result<(), SynthError> {
    let (w, h) = (vr.camera.intrinsics.width, vr.camera.intrinsics.height);
    if mask.width() != w || mask.height() != h {
        *mask = image::GrayImage::new(w, h);
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
    crate::io::atomic::save_image(&p, mask)?;
    tf.mask_area_px.insert(vr.view.name().into(), area);
    if let Some((landmarks, motion)) = landmarks {
        let mut lm = BTreeMap::new();
        for (name, p) in landmarks {
            if let Some(px) = vr.camera.project(motion.apply(DVec3::from_array(*p))) {
                lm.insert(name.clone(), [px.x, px.y]);
            }
        }
        tf.landmarks_px.insert(vr.view.name().into(), lm);
    }
    Ok(())
}

/// truth.json: the subject, where it stood and swayed, its measurements and landmarks,
/// and each frame's truth.
fn write_truth_json(
    cfg: &SynthConfig,
    st: &Staged,
    tdir: &Path,
    total: usize,
    per_frame: Vec<TruthFrame>,
    passer_by: Option<passerby::PasserByPath>,
) -> Result<(), SynthError> {
    let truth = Truth {
        format: "fitstation-synth-truth/1".into(),
        seed: cfg.seed,
        subject: cfg.subject.clone(),
        body_source: st.body_source.clone(),
        placement: st.placement,
        sway: st.sway,
        measurements_mm: st.measurements.clone(),
        landmarks: st.landmarks.clone(),
        fps: cfg.fps,
        frames: TruthFrames {
            total,
            empty: cfg.empty_frames,
            with_subject: cfg.subject_frames,
        },
        per_frame,
        ansur: cfg.subject.ansur.clone(),
        stance: cfg.subject.stance.clone(),
        passer_by,
    };
    let p = tdir.join("truth.json");
    let text =
        serde_json::to_string_pretty(&truth).map_err(|e| SynthError::Invalid(e.to_string()))?;
    crate::io::atomic::write(&p, text)?;
    Ok(())
}
