//! Recording I/O: frames written by `RecordingWriter` come back from `Recording`
//! bit-exactly (PNG) or within codec tolerance (JPEG, H.264 MP4); MP4 files play in
//! ffprobe; truncated and corrupt files give up the readable frames with warnings.

use fitstation::camera::StationCalibration;
use fitstation::recording::{FrameFormat, Recording, RecordingMeta, RecordingWriter};
use fitstation::synth::rng::SplitMix64;
use fitstation::synth::scene::{Background, Film, Scene};
use image::RgbImage;
use std::path::{Path, PathBuf};

fn tmp(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("fitstation-rec-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    d
}

/// Frames of the synthetic empty room with a moving bright square (so frames differ),
/// in a landscape front and a portrait side camera of reduced size.
fn frames(n: usize) -> (StationCalibration, Vec<(RgbImage, RgbImage)>) {
    let mut calib = StationCalibration::nominal(320, 240, 300.0, 3.0, 1.2, 1.0);
    let side = StationCalibration::nominal(240, 320, 400.0, 3.0, 1.2, 1.0);
    calib.side = side.side;
    calib.front.intrinsics.dist = [-0.1, 0.02, 0.0, 0.0, 0.0];
    let mut rng = SplitMix64::new(9);
    let scene = Scene::random(&mut rng, [&calib.front, &calib.side]);
    let film = Film::random(&mut rng);
    let bgs = [
        Background::render(&scene, &calib.front),
        Background::render(&scene, &calib.side),
    ];
    let mut out = Vec::new();
    let mut scratch = Vec::new();
    for k in 0..n {
        let mut pair = Vec::new();
        for bg in &bgs {
            let mut rad = bg.empty.clone();
            for y in 40..90 {
                for x in (20 + 6 * k)..(60 + 6 * k) {
                    if let Some(p) = rad.get_mut(y * bg.width as usize + x) {
                        *p = [0.9, 0.5, 0.2];
                    }
                }
            }
            let mut img = RgbImage::new(bg.width, bg.height);
            let mut nrng = SplitMix64::stream(3, k as u64);
            film.develop(&mut rad, &mut scratch, 1.0, &mut nrng, &mut img);
            pair.push(img);
        }
        let side = pair.pop().unwrap();
        let front = pair.pop().unwrap();
        out.push((front, side));
    }
    (calib, out)
}

fn psnr(a: &RgbImage, b: &RgbImage) -> f64 {
    assert_eq!(a.dimensions(), b.dimensions());
    let mse = a
        .as_raw()
        .iter()
        .zip(b.as_raw())
        .map(|(x, y)| (*x as f64 - *y as f64).powi(2))
        .sum::<f64>()
        / a.as_raw().len() as f64;
    10.0 * (255.0f64 * 255.0 / mse.max(1e-12)).log10()
}

fn write(
    dir: &Path,
    calib: &StationCalibration,
    frames: &[(RgbImage, RgbImage)],
    fmt: FrameFormat,
) {
    let meta = RecordingMeta {
        fps: 30.0,
        stature_m: Some(1.71),
        notes: Some("round trip".into()),
        date: None,
    };
    let mut w = RecordingWriter::with_meta(dir, calib, fmt, meta).unwrap();
    for (f, s) in frames {
        w.push_pair(f, s).unwrap();
    }
    w.finish().unwrap();
}

#[test]
fn png_round_trip_is_bit_exact() {
    let (calib, fr) = frames(5);
    let dir = tmp("png");
    write(&dir, &calib, &fr, FrameFormat::Png);
    let mut r = Recording::open(&dir).unwrap();
    assert_eq!(r.len(), 5);
    assert_eq!(r.metadata().stature_m, Some(1.71));
    assert_eq!(r.calibration().front.intrinsics, calib.front.intrinsics);
    for (k, (f, s)) in fr.iter().enumerate() {
        let (rf, rs) = r.frame_pair(k).unwrap();
        assert!(rf == *f && rs == *s, "frame {k} differs");
    }
    assert!(r.warnings().is_empty(), "{:?}", r.warnings());
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn jpeg_round_trip_within_tolerance() {
    let (calib, fr) = frames(3);
    let dir = tmp("jpeg");
    write(&dir, &calib, &fr, FrameFormat::Jpeg);
    let mut r = Recording::open(&dir).unwrap();
    assert_eq!(r.len(), 3);
    for (k, (f, s)) in fr.iter().enumerate() {
        let (rf, rs) = r.frame_pair(k).unwrap();
        assert!(psnr(f, &rf) > 30.0 && psnr(s, &rs) > 30.0, "frame {k}");
    }
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn mp4_round_trip_within_codec_tolerance_and_plays_in_ffprobe() {
    let n = 12;
    let (calib, fr) = frames(n);
    let dir = tmp("mp4");
    write(&dir, &calib, &fr, FrameFormat::Mp4);
    let mut r = Recording::open(&dir).unwrap();
    assert_eq!(r.len(), n);
    let mut worst = f64::INFINITY;
    for (k, (f, s)) in fr.iter().enumerate() {
        let (rf, rs) = r.frame_pair(k).unwrap();
        worst = worst.min(psnr(f, &rf)).min(psnr(s, &rs));
    }
    println!("MP4 round trip: worst PSNR {worst:.1} dB");
    assert!(worst > 30.0, "worst PSNR {worst:.1} dB");
    // Going back re-decodes from the start and gives the same frame.
    let (a, _) = r.frame_pair(1).unwrap();
    let (b, _) = r.frame_pair(1).unwrap();
    assert!(a == b);
    assert!(r.warnings().is_empty(), "{:?}", r.warnings());
    ffprobe_check(&dir.join("front.mp4"), n, (320, 240));
    ffprobe_check(&dir.join("side.mp4"), n, (240, 320));
    let _ = std::fs::remove_dir_all(&dir);
}

/// Runs ffprobe on the file when it is installed (CI installs it): the file must show
/// one H.264 stream of the right size and frame count.
fn ffprobe_check(file: &Path, frames: usize, size: (u32, u32)) {
    let out = std::process::Command::new("ffprobe")
        .args(["-v", "error", "-count_frames", "-select_streams", "v:0"])
        .args([
            "-show_entries",
            "stream=codec_name,width,height,nb_read_frames",
            "-of",
            "csv=p=0",
        ])
        .arg(file)
        .output();
    match out {
        Err(_) => {
            println!(
                "SKIPPED: ffprobe not installed; {} was not checked in a player",
                file.display()
            );
            assert!(
                std::env::var_os("CI").is_none(),
                "ffprobe is required when CI is set"
            );
        }
        Ok(o) => {
            assert!(
                o.status.success(),
                "ffprobe failed: {}",
                String::from_utf8_lossy(&o.stderr)
            );
            let text = String::from_utf8_lossy(&o.stdout).trim().to_string();
            assert_eq!(
                text,
                format!("h264,{},{},{frames}", size.0, size.1),
                "ffprobe says {text}"
            );
        }
    }
}

#[test]
fn truncated_mp4_gives_the_readable_frames() {
    let n = 12;
    let (calib, fr) = frames(n);
    let dir = tmp("trunc");
    write(&dir, &calib, &fr, FrameFormat::Mp4);
    for view in ["front", "side"] {
        let p = dir.join(format!("{view}.mp4"));
        let bytes = std::fs::read(&p).unwrap();
        // Cut in the media data: the index (moov, written last) is lost.
        std::fs::write(&p, &bytes[..bytes.len() * 6 / 10]).unwrap();
    }
    let mut r = Recording::open(&dir).unwrap();
    assert!(!r.warnings().is_empty());
    assert!(r.len() >= 2 && r.len() < n, "{} frames recovered", r.len());
    let recovered = r.len();
    for (k, (front, _)) in fr.iter().enumerate().take(recovered) {
        let (f, _) = r.frame_pair(k).unwrap();
        assert!(psnr(front, &f) > 30.0, "recovered frame {k}");
    }
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn corrupt_files_are_reported_not_panicked_on() {
    let (calib, fr) = frames(6);
    let dir = tmp("corrupt");
    write(&dir, &calib, &fr, FrameFormat::Mp4);
    let p = dir.join("front.mp4");
    let mut bytes = std::fs::read(&p).unwrap();
    // Damage the last frames' media data (just before the index, written last).
    let moov = bytes.windows(4).rposition(|w| w == b"moov").unwrap();
    for b in &mut bytes[moov - 300..moov - 100] {
        *b = 0xFF;
    }
    std::fs::write(&p, &bytes).unwrap();
    let mut r = Recording::open(&dir).unwrap();
    let ok = (0..r.len()).filter(|&k| r.frame_pair(k).is_ok()).count();
    assert!(ok >= 3, "only {ok} of {} frames readable", r.len());
    // A PNG folder with one broken file and one missing side frame.
    let dir2 = tmp("corrupt-png");
    write(&dir2, &calib, &fr, FrameFormat::Png);
    std::fs::write(dir2.join("front/000002.png"), b"not a png").unwrap();
    std::fs::remove_file(dir2.join("side/000004.png")).unwrap();
    let mut r = Recording::open(&dir2).unwrap();
    // The frame without its side frame is a front-only pair (a lost side camera), said.
    assert_eq!(r.len(), 6);
    assert!(r.warnings().iter().any(|w| w.contains("000004")));
    assert!(r.frame_pair(2).is_err());
    assert!(r.frame_pair(3).is_ok());
    let (front4, side4) = r.frame_pair(4).unwrap();
    assert!(front4.width() > 0 && side4.width() == 0);
    assert!(r.warnings().len() >= 2);
    // A looping replay reads the bad frame again every pass: it is said once.
    let said = r.warnings().len();
    assert!(r.frame_pair(2).is_err());
    assert_eq!(r.warnings().len(), said, "{:?}", r.warnings());
    let _ = std::fs::remove_dir_all(&dir);
    let _ = std::fs::remove_dir_all(&dir2);
}

#[test]
fn missing_calibration_is_a_clear_error() {
    let dir = tmp("nocalib");
    std::fs::create_dir_all(&dir).unwrap();
    let e = Recording::open(&dir).err().unwrap().to_string();
    assert!(e.contains("station.yaml"), "{e}");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn mp4_plays_in_opencv_ffmpeg() {
    if !have(
        "python3",
        &["-c", "import cv2"],
        "python3 with cv2",
        "MP4 playback in OpenCV",
    ) {
        return;
    }
    let n = 8;
    let (calib, fr) = frames(n);
    let (mp4, png) = (tmp("play-mp4"), tmp("play-png"));
    write(&mp4, &calib, &fr, FrameFormat::Mp4);
    write(&png, &calib, &fr, FrameFormat::Png);
    let script = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/tests/opencv/synth_mp4_play.py"
    );
    for view in ["front", "side"] {
        let out = std::process::Command::new("python3")
            .arg(script)
            .arg(mp4.join(format!("{view}.mp4")))
            .arg(png.join(view))
            .arg(n.to_string())
            .output()
            .unwrap();
        println!("{}", String::from_utf8_lossy(&out.stdout));
        assert!(
            out.status.success(),
            "{}{}",
            String::from_utf8_lossy(&out.stdout),
            String::from_utf8_lossy(&out.stderr)
        );
    }
    let _ = std::fs::remove_dir_all(&mp4);
    let _ = std::fs::remove_dir_all(&png);
}

#[test]
fn mp4_random_access_gives_the_same_frames() {
    let n = 36; // more than one IDR period
    let (calib, fr) = frames(n);
    let dir = tmp("seek");
    write(&dir, &calib, &fr, FrameFormat::Mp4);
    let mut r = Recording::open(&dir).unwrap();
    let mut sequential = Vec::new();
    for k in 0..n {
        sequential.push(r.frame_pair(k).unwrap().0);
    }
    let mut r = Recording::open(&dir).unwrap();
    for k in [33, 2, 31, 30, 35, 0, 17] {
        let (f, _) = r.frame_pair(k).unwrap();
        assert!(
            f == sequential[k],
            "frame {k} differs when reached by seeking"
        );
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// Whether `program args` runs; when it does not, says the check was skipped (and fails
/// when CI is set: a skip in CI is a failure).
fn have(program: &str, args: &[&str], name: &str, what: &str) -> bool {
    let ok = std::process::Command::new(program)
        .args(args)
        .output()
        .is_ok_and(|o| o.status.success());
    if !ok {
        println!("SKIPPED: {name} is not available; {what} not checked");
        assert!(
            std::env::var_os("CI").is_none(),
            "{name} is required when CI is set"
        );
    }
    ok
}

fn have_ffmpeg(what: &str) -> bool {
    have("ffmpeg", &["-version"], "ffmpeg", what)
}

/// A recording of `n` frames encoded by ffmpeg with the output options `args`; returns
/// its folder, the PNG folder the frames came from, and the frames.
fn ffmpeg_recording(
    name: &str,
    n: usize,
    args: &[&str],
) -> (PathBuf, PathBuf, Vec<(RgbImage, RgbImage)>) {
    let (calib, fr) = frames(n);
    let png = tmp(&format!("{name}-png"));
    write(&png, &calib, &fr, FrameFormat::Png);
    let dir = tmp(&format!("{name}-mp4"));
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::copy(png.join("station.yaml"), dir.join("station.yaml")).unwrap();
    for view in ["front", "side"] {
        let out = std::process::Command::new("ffmpeg")
            .args(["-loglevel", "error", "-y", "-framerate", "30", "-i"])
            .arg(png.join(view).join("%06d.png"))
            .args(args)
            .arg(dir.join(format!("{view}.mp4")))
            .output()
            .unwrap();
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
    }
    (dir, png, fr)
}

/// What ffprobe says of a stream's `key` (e.g. `has_b_frames`, `pix_fmt`).
fn probe(file: &Path, key: &str) -> String {
    let out = std::process::Command::new("ffprobe")
        .args([
            "-v",
            "error",
            "-show_entries",
            &format!("stream={key}"),
            "-of",
            "csv=p=0",
        ])
        .arg(file)
        .output()
        .unwrap();
    String::from_utf8_lossy(&out.stdout).trim().to_string()
}

/// Every frame of `dir` matches its own frame of `fr` (PSNR over 30 dB, and at least 1 dB
/// better than its neighbours': the square moves 6 px a frame), read sequentially and
/// by seeking.
fn frames_in_order(dir: &Path, fr: &[(RgbImage, RgbImage)], seeks: &[usize]) {
    let mut r = Recording::open(dir).unwrap();
    assert_eq!(r.len(), fr.len());
    let view = |pair: &(RgbImage, RgbImage), v: usize| {
        if v == 0 {
            pair.0.clone()
        } else {
            pair.1.clone()
        }
    };
    let mut sequential = Vec::new();
    for k in 0..fr.len() {
        let (f, s) = r.frame_pair(k).unwrap();
        for (v, got) in [(0, &f), (1, &s)] {
            let own = psnr(got, &view(&fr[k], v));
            assert!(own > 30.0, "frame {k}: PSNR {own:.1} dB");
            for j in [k.wrapping_sub(1), k + 1] {
                if let Some(other) = fr.get(j) {
                    let o = psnr(got, &view(other, v));
                    assert!(
                        own > o + 1.0,
                        "frame {k} looks like frame {j}: {own:.1} vs {o:.1} dB"
                    );
                }
            }
        }
        sequential.push(f);
    }
    let mut r = Recording::open(dir).unwrap();
    for &k in seeks {
        let (f, _) = r.frame_pair(k).unwrap();
        assert!(
            f == sequential[k],
            "frame {k} differs when reached by seeking"
        );
    }
}

/// MP4s from other tools: ffmpeg's libx264 writes High profile with B-frames (samples in
/// decoding order, pictures presented in another order); here with closed groups of 12.
/// Every frame comes back in presentation order, sequentially and by seeking.
#[test]
fn mp4_from_ffmpeg_with_b_frames_reads_in_presentation_order() {
    if !have_ffmpeg("MP4s with B-frames") {
        return;
    }
    let args = [
        "-c:v",
        "libx264",
        "-crf",
        "12",
        "-profile:v",
        "high",
        "-bf",
        "3",
        "-g",
        "12",
        "-pix_fmt",
        "yuv420p",
    ];
    let (dir, png, fr) = ffmpeg_recording("bframes", 40, &args);
    for view in ["front", "side"] {
        let b: u32 = probe(&dir.join(format!("{view}.mp4")), "has_b_frames")
            .parse()
            .unwrap_or(0);
        assert!(b > 0, "{view}.mp4 has no B-frames to reorder");
    }
    frames_in_order(&dir, &fr, &[33, 2, 31, 13, 39, 24, 0, 17]);
    let _ = std::fs::remove_dir_all(&png);
    let _ = std::fs::remove_dir_all(&dir);
}

/// MP4s OpenH264 cannot read are decoded through ffmpeg, with a warning naming what they
/// are: 4:4:4 (ffmpeg encodes RGB frames so unless told otherwise: High 4:4:4
/// Predictive) and MPEG-4 Part 2 (OpenCV's VideoWriter with fourcc `mp4v`; not the H.264
/// the format asks for).
#[test]
fn mp4s_openh264_cannot_read_are_decoded_through_ffmpeg() {
    if !have_ffmpeg("4:4:4 and MPEG-4 Part 2 MP4s") {
        return;
    }
    let cases: [(&str, &[&str], &str, &str, &str); 2] = [
        (
            "yuv444",
            &["-c:v", "libx264", "-crf", "12"],
            "pix_fmt",
            "yuv444p",
            "4:4:4",
        ),
        (
            "mpeg4",
            &["-c:v", "mpeg4", "-q:v", "1"],
            "codec_name",
            "mpeg4",
            "not H.264",
        ),
    ];
    for (name, args, key, want, warning) in cases {
        let (dir, png, fr) = ffmpeg_recording(name, 10, args);
        assert_eq!(probe(&dir.join("front.mp4"), key), want);
        let r = Recording::open(&dir).unwrap();
        assert!(
            r.warnings()
                .iter()
                .any(|w| w.contains(warning) && w.contains("ffmpeg")),
            "{name}: {:?}",
            r.warnings()
        );
        frames_in_order(&dir, &fr, &[7, 2, 9, 0]);
        if name == "mpeg4" {
            // Cut before its index (ffmpeg writes `moov` last): nothing can be recovered
            // without it, and the error says why instead of "no frames".
            let p = dir.join("side.mp4");
            let bytes = std::fs::read(&p).unwrap();
            let moov = bytes.windows(4).rposition(|w| w == b"moov").unwrap();
            std::fs::write(&p, &bytes[..moov - 4]).unwrap();
            let e = Recording::open(&dir)
                .err()
                .expect("a cut MPEG-4 file")
                .to_string();
            assert!(
                e.contains("side.mp4") && e.contains("cut before its index"),
                "{e}"
            );
        }
        let _ = std::fs::remove_dir_all(&png);
        let _ = std::fs::remove_dir_all(&dir);
    }
}
