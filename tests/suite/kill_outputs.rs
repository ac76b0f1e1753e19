//! Outputs that cannot be half-written (issue 21 item 4): the real `fitstation` binary
//! replays the demo recording with `--out` and `--record` and is killed (SIGKILL) at
//! random points, several runs from a fixed seed. After each kill every output file on
//! disk is absent, the old version, or a complete new version (parsed), and the cut
//! recording replays up to the cut: every frame pair whose two frames are on disk is
//! read back, by the library and by `fitstation replay`.

use fitstation::recording::Recording;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::Instant;

/// Seed of the kill delays (the test is reproducible: same delays every run).
const SEED: u64 = 0x21_04;
/// Killed runs.
const RUNS: usize = 12;
/// Marker of the old `report.json` placed before every run.
const OLD_REPORT: &str = "{\"old\": true}\n";
/// The old `avatar.obj`: one triangle.
const OLD_AVATAR: &str = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";

/// SplitMix64: a small deterministic generator for the kill delays.
struct SplitMix64(u64);

impl SplitMix64 {
    /// A uniform number in [0, 1).
    fn unit(&mut self) -> f64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^= z >> 31;
        (z >> 11) as f64 / (1u64 << 53) as f64
    }
}

fn exe() -> &'static str {
    env!("CARGO_BIN_EXE_fitstation")
}

fn demo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("recordings/demo")
}

/// A fresh scratch folder for this test.
fn scratch() -> PathBuf {
    let d = std::env::temp_dir().join(format!("fitstation-kill-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).expect("scratch folder");
    d
}

/// The replay command writing `out` and recording into `rec`.
fn replay_cmd(out: &Path, rec: &Path, format: &str) -> Command {
    let mut c = Command::new(exe());
    c.arg("replay")
        .arg(demo())
        .arg("--out")
        .arg(out)
        .arg("--record")
        .arg(rec)
        .args(["--record-format", format, "--json"])
        .stdout(Stdio::null())
        .stderr(Stdio::null());
    c
}

/// Puts the old outputs in place.
fn place_old_outputs(out: &Path) {
    std::fs::create_dir_all(out).expect("out folder");
    std::fs::write(out.join("report.json"), OLD_REPORT).expect("old report");
    std::fs::write(out.join("avatar.obj"), OLD_AVATAR).expect("old avatar");
}

/// What a complete run wrote: the avatar's vertex count.
struct Reference {
    avatar_vertices: usize,
}

/// Every file in `out` is the old version, a complete new one, or a temporary of the
/// atomic writer (hidden, never under the final name).
fn check_outputs(out: &Path, reference: &Reference, run: usize) -> [&'static str; 2] {
    let mut seen = ["absent", "absent"];
    for entry in std::fs::read_dir(out).expect("read out").flatten() {
        let name = entry.file_name().to_string_lossy().into_owned();
        let path = entry.path();
        match name.as_str() {
            "report.json" => {
                let text = std::fs::read_to_string(&path).expect("read report");
                if text == OLD_REPORT {
                    seen[0] = "old";
                    continue;
                }
                let v: serde_json::Value = serde_json::from_str(&text)
                    .unwrap_or_else(|e| panic!("run {run}: report.json is cut: {e}"));
                assert!(
                    v["measurements_mm"].is_object() && v["series"].is_array(),
                    "run {run}: report.json parses but is not a report"
                );
                seen[0] = "new";
            }
            "avatar.obj" => {
                let text = std::fs::read_to_string(&path).expect("read avatar");
                if text == OLD_AVATAR {
                    seen[1] = "old";
                    continue;
                }
                let m = fitstation::mesh::io::read_obj(&path, None)
                    .unwrap_or_else(|e| panic!("run {run}: avatar.obj is cut: {e}"));
                assert_eq!(
                    m.vertex_count(),
                    reference.avatar_vertices,
                    "run {run}: avatar.obj is not a whole avatar"
                );
                seen[1] = "new";
            }
            n => assert!(
                fitstation::io::atomic::is_temporary(n),
                "run {run}: unexpected file {n} in the output folder"
            ),
        }
    }
    seen
}

/// Polls `out` until a temporary of the child's atomic writer appears (then returns at
/// once), the child exits, or `limit` passes. Temporaries of earlier killed runs do not
/// count: the name carries the writer's process id.
fn wait_for_temporary(out: &Path, child: &mut std::process::Child, limit: std::time::Duration) {
    let mark = format!(".tmp-{}-", child.id());
    let t0 = Instant::now();
    while t0.elapsed() < limit {
        if matches!(child.try_wait(), Ok(Some(_))) {
            return;
        }
        let seen = std::fs::read_dir(out)
            .into_iter()
            .flatten()
            .flatten()
            .any(|e| e.file_name().to_string_lossy().contains(&mark));
        if seen {
            return;
        }
    }
}

/// Frame indices whose file is on disk in one view folder (temporaries excluded).
fn frames_on_disk(dir: &Path) -> Vec<u64> {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return Vec::new();
    };
    let mut v: Vec<u64> = entries
        .flatten()
        .filter_map(|e| {
            let name = e.file_name().to_string_lossy().into_owned();
            if fitstation::io::atomic::is_temporary(&name) {
                return None;
            }
            name.strip_suffix(".png")?.parse().ok()
        })
        .collect();
    v.sort();
    v
}

/// The cut recording replays up to the cut; returns the pairs it holds.
fn check_recording(rec: &Path, run: usize, format: &str) -> usize {
    if !rec.join("station.yaml").exists() {
        // Killed before the recording began: nothing, or only empty folders.
        return 0;
    }
    fitstation::camera::StationCalibration::load(&rec.join("station.yaml"))
        .unwrap_or_else(|e| panic!("run {run}: station.yaml is cut: {e}"));
    let meta = std::fs::read_to_string(rec.join("recording.yaml"))
        .unwrap_or_else(|e| panic!("run {run}: recording.yaml missing beside station.yaml: {e}"));
    assert!(
        meta.contains("fps: 30"),
        "run {run}: recording.yaml: {meta}"
    );
    let expected = if format == "png" {
        let (f, s) = (
            frames_on_disk(&rec.join("front")),
            frames_on_disk(&rec.join("side")),
        );
        // Pairs are appended in order: the side view lags the front by at most one.
        assert!(
            f.len() == s.len() || f.len() == s.len() + 1,
            "run {run}: {} front and {} side frames",
            f.len(),
            s.len()
        );
        // A front frame whose side frame was not written yet is read as a front-only
        // pair (a side camera lost: the station fits it from the front view).
        let pairs = f.len();
        if s.len() != f.len() {
            println!("run {run}: front {} side {}", f.len(), s.len());
        }
        assert_eq!(f, (0..pairs as u64).collect::<Vec<_>>(), "run {run}: a gap");
        assert_eq!(
            s,
            (0..s.len() as u64).collect::<Vec<_>>(),
            "run {run}: a gap"
        );
        Some(pairs)
    } else {
        None
    };
    let mut r = match Recording::open(rec) {
        Ok(r) => r,
        Err(e) => {
            // An MP4 cut before its first chunk (the mp4 crate writes a chunk a second)
            // holds no frame: said in words, not a panic.
            assert!(
                expected.is_none_or(|p| p == 0),
                "run {run}: the cut recording does not open: {e}"
            );
            let msg = e.to_string();
            assert!(
                msg.contains("cut before") || msg.contains("no frames"),
                "run {run}: unclear message for an empty cut recording: {msg}"
            );
            return 0;
        }
    };
    if let Some(p) = expected {
        assert_eq!(r.len(), p, "run {run}: pairs read vs on disk");
    }
    let n = r.len();
    for k in 0..n {
        r.frame_pair(k)
            .unwrap_or_else(|e| panic!("run {run}: frame pair {k} of the cut recording: {e}"));
    }
    // The binary replays the same frames (a cut before anybody stepped in ends with
    // "no frame could be fitted (N frames ...": N frames were still read).
    let o = Command::new(exe())
        .arg("replay")
        .arg(rec)
        .arg("--json")
        .output()
        .expect("run replay");
    if o.status.success() {
        let v: serde_json::Value = serde_json::from_slice(&o.stdout).expect("replay json");
        assert_eq!(v["frames"]["total"], n, "run {run}: frames replayed");
    } else {
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(
            err.contains(&format!("no frame could be fitted ({n} frames")),
            "run {run}: replay of the cut recording failed: {err}"
        );
    }
    n
}

#[test]
fn killed_replay_and_recording_leave_whole_files() {
    let dir = scratch();
    // A complete run first: the reference, and how long one takes.
    let out = dir.join("out");
    place_old_outputs(&out);
    let t0 = Instant::now();
    let status = replay_cmd(&out, &dir.join("rec-full"), "png")
        .status()
        .expect("run fitstation");
    let full = t0.elapsed();
    assert!(status.success(), "the complete replay failed");
    let avatar = fitstation::mesh::io::read_obj(&out.join("avatar.obj"), None).expect("avatar");
    let reference = Reference {
        avatar_vertices: avatar.vertex_count(),
    };
    assert_eq!(check_outputs(&out, &reference, 0), ["new", "new"]);
    let full_pairs = check_recording(&dir.join("rec-full"), 0, "png");
    assert!(full_pairs > 0);
    println!(
        "complete run: {:.1} s, {full_pairs} pairs",
        full.as_secs_f64()
    );

    let mut rng = SplitMix64(SEED);
    let mut tally = std::collections::BTreeMap::<String, usize>::new();
    for run in 1..=RUNS {
        place_old_outputs(&out);
        let format = if run % 4 == 0 { "mp4" } else { "png" };
        let rec = dir.join(format!("rec-{run}"));
        // Half the kills anywhere in the run, half near its end (the output writes).
        let u = rng.unit();
        let frac = if run % 2 == 1 {
            0.05 + 0.9 * u
        } else {
            0.85 + 0.2 * u
        };
        let delay = full.mul_f64(frac);
        let mut child = replay_cmd(&out, &rec, format).spawn().expect("spawn");
        if run % 3 == 0 {
            // Aim at the output writes: kill as soon as a temporary shows up.
            wait_for_temporary(&out, &mut child, full * 4);
        } else {
            std::thread::sleep(delay);
        }
        let finished = matches!(child.try_wait(), Ok(Some(_)));
        let _ = child.kill();
        let _ = child.wait();
        let seen = check_outputs(&out, &reference, run);
        let pairs = check_recording(&rec, run, format);
        println!(
            "run {run}: {format}, killed {}{}: report {}, avatar {}, {pairs} pairs recorded",
            if run % 3 == 0 {
                "when a temporary appeared".to_string()
            } else {
                format!("after {:.2} s ({:.0} %)", delay.as_secs_f64(), frac * 100.0)
            },
            if finished { ", had finished" } else { "" },
            seen[0],
            seen[1]
        );
        *tally.entry(format!("report {}", seen[0])).or_default() += 1;
        *tally.entry(format!("avatar {}", seen[1])).or_default() += 1;
    }
    println!("{tally:?}");
    // A complete run after the kills removes the killed writers' temporaries.
    place_old_outputs(&out);
    let status = replay_cmd(&out, &dir.join("rec-last"), "png")
        .status()
        .expect("run fitstation");
    assert!(status.success());
    assert_eq!(check_outputs(&out, &reference, RUNS + 1), ["new", "new"]);
    let left: Vec<String> = std::fs::read_dir(&out)
        .expect("read out")
        .flatten()
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .filter(|n| fitstation::io::atomic::is_temporary(n))
        .collect();
    assert!(left.is_empty(), "temporaries left: {left:?}");
    let _ = std::fs::remove_dir_all(&dir);
}
