//! One entry point per fuzz target (`fuzz/`, run by `tools/fuzz.sh`): each runs an input
//! through a parser of outside data exactly as the station reads that file, then uses
//! what was accepted the way the station would. `Err` means the input was refused with
//! a message (the expected outcome for most fuzz inputs); a panic, a hang or a runaway
//! allocation is the bug the fuzzer looks for. `tests/suite/fuzz_regressions.rs` runs every
//! saved crashing input (`tests/fuzz_cases/<target>/`) through the same function.
//!
//! Formats that live in files (an MP4, a recording folder) are written to a fresh
//! temporary path first, since their readers take paths.

use crate::body::library::LibraryData;
use crate::body::{ShapeLibrary, ShapeParams, TemplateInfo};
use crate::camera::StationCalibration;
use crate::mesh::io::{parse_obj, parse_ply, write_obj_to};
use crate::recording::h264::{annexb_nals, decode_sample_bytes, Mp4VideoReader};
use crate::recording::{decode_frame, Recording};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

/// The fuzz targets, by name (the names of `fuzz/fuzz_targets/*.rs`).
pub const TARGETS: [&str; 8] = [
    "station_yaml",
    "mesh",
    "mp4",
    "h264_sample",
    "frame_image",
    "shape_library",
    "template_sidecar",
    "recording_layout",
];

/// Frames decoded at most per opened video or recording (keeps one run short).
const MAX_FRAMES_TRIED: usize = 3;
/// Separates the parts of a `recording_layout` input (station.yaml, recording.yaml,
/// front frame, side frame, extra front frame).
pub const PART_SEPARATOR: &[u8] = b"\n#fitstation-fuzz-part#\n";

/// Runs `data` through the entry point of the fuzz target `name`.
///
/// # Errors
/// The input's refusal, or an unknown target name.
pub fn run(name: &str, data: &[u8]) -> Result<(), String> {
    match name {
        "station_yaml" => station_yaml(data),
        "mesh" => mesh(data),
        "mp4" => mp4(data),
        "h264_sample" => h264_sample(data),
        "frame_image" => frame_image(data),
        "shape_library" => shape_library(data),
        "template_sidecar" => template_sidecar(data),
        "recording_layout" => recording_layout(data),
        _ => Err(format!("no fuzz target '{name}'")),
    }
}

/// `station.yaml` (OpenCV FileStorage): parse; what parses must write and read back.
pub fn station_yaml(data: &[u8]) -> Result<(), String> {
    let text = std::str::from_utf8(data).map_err(|e| e.to_string())?;
    let cal = StationCalibration::from_yaml_str(text, "station.yaml").map_err(|e| e.to_string())?;
    let written = cal.to_yaml_string();
    if let Err(e) = StationCalibration::from_yaml_str(&written, "written station.yaml") {
        panic!("an accepted calibration does not read back once written: {e}\n{written}");
    }
    Ok(())
}

/// OBJ and PLY readers on the same bytes; an accepted mesh must survive an OBJ round trip.
pub fn mesh(data: &[u8]) -> Result<(), String> {
    let name = Path::new("fuzz.mesh");
    let ply = parse_ply(data, name).map_err(|e| e.to_string());
    let obj = parse_obj(data, name, None).map_err(|e| e.to_string());
    let _ = parse_obj(data, name, Some("body"));
    for m in [&ply, &obj].into_iter().flatten() {
        let mut text = Vec::new();
        write_obj_to(&mut text, m).map_err(|e| e.to_string())?;
        let back = parse_obj(text.as_slice(), name, None)
            .unwrap_or_else(|e| panic!("an accepted mesh does not read back as OBJ: {e}"));
        assert_eq!(
            (back.vertex_count(), back.triangles.len()),
            (m.vertex_count(), m.triangles.len()),
            "an accepted mesh changes in an OBJ round trip"
        );
    }
    match (ply, obj) {
        (Err(p), Err(o)) => Err(format!("as PLY: {p}; as OBJ: {o}")),
        _ => Ok(()),
    }
}

/// An MP4 file: open (index, or recovery from the media data) and decode a few frames.
pub fn mp4(data: &[u8]) -> Result<(), String> {
    let file = TempPath::new("mp4");
    std::fs::write(&file.0, data).map_err(|e| e.to_string())?;
    let mut r = Mp4VideoReader::open(&file.0).map_err(|e| e.to_string())?;
    let mut last = Ok(());
    for k in 0..r.len().min(MAX_FRAMES_TRIED) {
        last = r.frame(k).map(|_| ()).map_err(|e| e.to_string());
    }
    last
}

/// One H.264 sample as an MP4 holds it: `[sps length][sps][pps length][pps][sample]`
/// (lengths one byte; a zero SPS length: no parameter sets, a non-sync sample).
pub fn h264_sample(data: &[u8]) -> Result<(), String> {
    let _ = annexb_nals(data);
    let (&sps_len, rest) = data.split_first().ok_or("empty input")?;
    let (sample, sets) = if sps_len == 0 {
        (rest, None)
    } else {
        let sps = rest.get(..usize::from(sps_len)).ok_or("cut in the SPS")?;
        let rest = &rest[sps.len()..];
        let (&pps_len, rest) = rest.split_first().ok_or("cut before the PPS")?;
        let pps = rest.get(..usize::from(pps_len)).ok_or("cut in the PPS")?;
        (&rest[pps.len()..], Some((sps, pps)))
    };
    decode_sample_bytes(sample, sets, Path::new("fuzz.h264"))
        .map(|_| ())
        .map_err(|e| e.to_string())
}

/// A frame file (PNG or JPEG) as a frame folder holds it.
pub fn frame_image(data: &[u8]) -> Result<(), String> {
    decode_frame(data, Path::new("front/000000.png"))
        .map(|_| ())
        .map_err(|e| e.to_string())
}

/// The shape library file: first byte 0 = the file as stored (magic + zlib), else the
/// decompressed stream; what decodes is built into a library and a body is made.
pub fn shape_library(data: &[u8]) -> Result<(), String> {
    let file = Path::new("fuzz.fsl");
    let (&kind, rest) = data.split_first().ok_or("empty input")?;
    let lib = if kind == 0 {
        LibraryData::decode(rest, file)
    } else {
        LibraryData::decode_raw(rest, file)
    }
    .map_err(|e| e.to_string())?;
    let info = TemplateInfo {
        vertex_count: lib.base.len(),
        ..TemplateInfo::empty()
    };
    let lib = ShapeLibrary::from_data(lib, Some(info), file).map_err(|e| e.to_string())?;
    let _ = lib.body(&ShapeParams::default());
    let _ = lib.body(&ShapeLibrary::sample_adult(u64::from(kind)));
    Ok(())
}

/// The template sidecar (`MESH.template.json`) for the committed decimated template
/// mesh's vertex count (read once), then its part landmarks.
pub fn template_sidecar(data: &[u8]) -> Result<(), String> {
    let text = std::str::from_utf8(data).map_err(|e| e.to_string())?;
    let info = TemplateInfo::from_json(
        text,
        Path::new("fuzz.template.json"),
        decimated_template_vertices(),
    )
    .map_err(|e| e.to_string())?;
    let template = crate::body::Template {
        mesh: crate::mesh::TriMesh::new(Vec::new(), Vec::new()),
        info,
    };
    crate::fit::pose::template_part_landmarks(&template).map(|_| ())
}

/// The vertex count of `templates/makehuman-adult-decimated.obj` (0 if unreadable).
fn decimated_template_vertices() -> usize {
    static COUNT: std::sync::OnceLock<usize> = std::sync::OnceLock::new();
    *COUNT.get_or_init(|| {
        let path = Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("templates")
            .join("makehuman-adult-decimated.obj");
        crate::mesh::io::read_obj(&path, None).map_or(0, |m| m.vertex_count())
    })
}

/// A recording folder. The first byte picks the layout (`j`: JPEG frame folders, `m`:
/// front.mp4 and side.mp4, else PNG frame folders); the rest is split at
/// [`PART_SEPARATOR`] into station.yaml, recording.yaml (absent when empty), the front
/// frame, the side frame and an optional extra front-only frame. The folder is opened
/// and its first frame pairs read.
pub fn recording_layout(data: &[u8]) -> Result<(), String> {
    let (&layout, rest) = data.split_first().ok_or("empty input")?;
    let parts = split_parts(rest);
    let dir = TempPath::new("rec");
    std::fs::create_dir_all(&dir.0).map_err(|e| e.to_string())?;
    let write = |rel: &str, bytes: &[u8]| -> Result<(), String> {
        let p = dir.0.join(rel);
        if let Some(parent) = p.parent() {
            std::fs::create_dir_all(parent).map_err(|e| e.to_string())?;
        }
        std::fs::write(p, bytes).map_err(|e| e.to_string())
    };
    write("station.yaml", parts.first().copied().unwrap_or_default())?;
    if let Some(meta) = parts.get(1).filter(|m| !m.is_empty()) {
        write("recording.yaml", meta)?;
    }
    let front = parts.get(2).copied().unwrap_or_default();
    let side = parts.get(3).copied().unwrap_or_default();
    match layout {
        b'm' => {
            write("front.mp4", front)?;
            write("side.mp4", side)?;
        }
        _ => {
            let ext = if layout == b'j' { "jpg" } else { "png" };
            write(&format!("front/000000.{ext}"), front)?;
            write(&format!("side/000000.{ext}"), side)?;
            if let Some(extra) = parts.get(4) {
                write(&format!("front/000001.{ext}"), extra)?;
            }
        }
    }
    let mut rec = Recording::open(&dir.0).map_err(|e| e.to_string())?;
    let _ = rec.metadata();
    let mut last = Ok(());
    for k in 0..rec.len().min(MAX_FRAMES_TRIED) {
        last = rec.frame_pair(k).map(|_| ()).map_err(|e| e.to_string());
    }
    last
}

/// `data` cut at every [`PART_SEPARATOR`].
pub fn split_parts(data: &[u8]) -> Vec<&[u8]> {
    let mut parts = Vec::new();
    let mut rest = data;
    while let Some(i) = rest
        .windows(PART_SEPARATOR.len())
        .position(|w| w == PART_SEPARATOR)
    {
        parts.push(&rest[..i]);
        rest = &rest[i + PART_SEPARATOR.len()..];
    }
    parts.push(rest);
    parts
}

/// A fresh path under the temporary folder (process id and a counter), removed (file or
/// folder) when dropped.
struct TempPath(PathBuf);

impl TempPath {
    fn new(kind: &str) -> TempPath {
        static NEXT: AtomicU64 = AtomicU64::new(0);
        let n = NEXT.fetch_add(1, Ordering::Relaxed);
        TempPath(
            std::env::temp_dir().join(format!("fitstation-fuzz-{}-{n}.{kind}", std::process::id())),
        )
    }
}

impl Drop for TempPath {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
        let _ = std::fs::remove_file(&self.0);
    }
}
