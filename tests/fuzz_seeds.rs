//! The seed corpora of the fuzz targets (`fuzz/`, `tools/fuzz.sh`), written from the
//! repository's real files: real meshes, frames and videos cut down to a few kilobytes
//! so that the fuzzer mutates them quickly. With `FITSTATION_FUZZ_SEEDS=DIR` the seeds
//! are written to `DIR/<target>/seed-*` (tools/fuzz.sh does this); either way every seed
//! must be accepted by its target's entry point, so the fuzzer starts past the parsers'
//! first checks.

use fitstation::body::library::LibraryData;
use fitstation::fuzz::PART_SEPARATOR;
use fitstation::mesh::io::{read_obj, write_obj_to, write_ply};
use fitstation::mesh::TriMesh;
use fitstation::recording::h264::{Mp4VideoReader, Mp4VideoWriter};
use image::RgbImage;
use std::path::{Path, PathBuf};

/// Side of the small frames written as seeds, pixels (width; height is 3/4 of it).
const SEED_FRAME_W: u32 = 64;
/// Frames in the small seed videos (more than one group's worth is not needed).
const SEED_FRAMES: usize = 3;
/// Triangles kept from the template for the mesh seeds.
const SEED_TRIANGLES: usize = 60;
/// Vertices kept from the shape library for its seed.
const SEED_LIBRARY_VERTICES: u32 = 200;

type Res<T> = Result<T, Box<dyn std::error::Error>>;

#[test]
fn seeds_are_written_and_each_is_accepted_by_its_target() {
    let seeds = write_seeds().expect("the repository's files make the seeds");
    let mut refused = Vec::new();
    for (target, name, bytes) in &seeds {
        if name.starts_with("part-") {
            continue;
        }
        if let Err(e) = fitstation::fuzz::run(target, bytes) {
            refused.push(format!("{target}/{name}: {e}"));
        }
    }
    assert!(refused.is_empty(), "{}", refused.join("\n"));
    for target in fitstation::fuzz::TARGETS {
        assert!(seeds.iter().any(|s| s.0 == target), "no seed for {target}");
    }
    if let Some(out) = std::env::var_os("FITSTATION_FUZZ_SEEDS") {
        for (target, name, bytes) in &seeds {
            let dir = PathBuf::from(&out).join(target);
            std::fs::create_dir_all(&dir).expect("seed folder");
            std::fs::write(dir.join(format!("seed-{name}")), bytes).expect("seed file");
        }
        eprintln!(
            "{} seeds written to {}",
            seeds.len(),
            Path::new(&out).display()
        );
    }
}

/// (target, name, input) of every seed.
type Seeds = Vec<(&'static str, String, Vec<u8>)>;

fn write_seeds() -> Res<Seeds> {
    let repo = Path::new(env!("CARGO_MANIFEST_DIR"));
    let seeds = std::cell::RefCell::new(Seeds::new());
    let put = |target: &'static str, name: &str, bytes: &[u8]| -> Res<()> {
        seeds
            .borrow_mut()
            .push((target, name.to_string(), bytes.to_vec()));
        Ok(())
    };
    // station.yaml: the example and the demo recording's, plus the demo's at seed size.
    let demo_station = std::fs::read_to_string(repo.join("recordings/demo/station.yaml"))?;
    put("station_yaml", "demo", demo_station.as_bytes())?;
    put(
        "station_yaml",
        "example",
        &std::fs::read(repo.join("calib/examples/station.example.yaml"))?,
    )?;
    let small_station = demo_station
        .replace("image_width: 1280", &format!("image_width: {SEED_FRAME_W}"))
        .replace(
            "image_height: 720",
            &format!("image_height: {}", SEED_FRAME_W * 3 / 4),
        );

    // Meshes: a patch of the template as OBJ, binary PLY and ASCII PLY.
    let template = read_obj(&repo.join("templates/makehuman-adult-decimated.obj"), None)?;
    let patch = mesh_patch(&template, SEED_TRIANGLES);
    let mut obj = Vec::new();
    write_obj_to(&mut obj, &patch)?;
    put("mesh", "patch.obj", &obj)?;
    let ply = std::env::temp_dir().join(format!("fitstation-seed-{}.ply", std::process::id()));
    write_ply(&ply, &patch)?;
    put("mesh", "patch.ply", &std::fs::read(&ply)?)?;
    let _ = std::fs::remove_file(&ply);
    put("mesh", "patch-ascii.ply", ascii_ply(&patch).as_bytes())?;

    // Frames: the demo's first frames, scaled down, as PNG and JPEG.
    let mut demo = Mp4VideoReader::open(&repo.join("recordings/demo/front.mp4"))?;
    let mut demo_side = Mp4VideoReader::open(&repo.join("recordings/demo/side.mp4"))?;
    let small = |img: &RgbImage| {
        image::imageops::resize(
            img,
            SEED_FRAME_W,
            SEED_FRAME_W * 3 / 4,
            image::imageops::FilterType::Triangle,
        )
    };
    let frames: Vec<RgbImage> = (0..SEED_FRAMES)
        .map(|k| demo.frame(k).map(|f| small(&f)))
        .collect::<Result<_, _>>()?;
    let side = small(&demo_side.frame(0)?);
    let png = encode(&frames[0], image::ImageFormat::Png)?;
    let jpg = encode(&frames[0], image::ImageFormat::Jpeg)?;
    put("frame_image", "front.png", &png)?;
    put("frame_image", "front.jpg", &jpg)?;
    put(
        "frame_image",
        "station-front.png",
        &std::fs::read(repo.join("calib/examples/station_front_small.png"))?,
    )?;

    // Videos: the small frames as an H.264 MP4 (written by the station's writer), and
    // the same file cut before its index (the recovery path).
    let mp4 = small_video(&frames)?;
    put("mp4", "small.mp4", &mp4)?;
    let moov = find_box(&mp4, b"moov").unwrap_or(mp4.len());
    put("mp4", "cut.mp4", &mp4[..moov])?;

    // H.264 samples from that video: [sps len][sps][pps len][pps][sample].
    // Samples after the first need the decoder's state: seeds, but not decodable alone.
    for (k, (sync, sample)) in video_samples(&mp4)?.iter().enumerate() {
        let name = if *sync {
            format!("sync{k}")
        } else {
            format!("part-{k}")
        };
        put("h264_sample", &name, sample)?;
    }

    // The shape library, cut to its first vertices, stored and raw.
    let lib = std::fs::read(repo.join("templates/makehuman-adult.fsl"))?;
    let data = LibraryData::decode(&lib, Path::new("makehuman-adult.fsl"))?;
    let cut = library_patch(data, SEED_LIBRARY_VERTICES);
    put(
        "shape_library",
        "stored",
        &[&[0u8][..], &cut.encode()].concat(),
    )?;
    put(
        "shape_library",
        "raw",
        &[&[1u8][..], &cut.encode_raw()].concat(),
    )?;

    // The template sidecar of the decimated template.
    put(
        "template_sidecar",
        "decimated",
        &std::fs::read(repo.join("templates/makehuman-adult-decimated.template.json"))?,
    )?;

    // Recording folders: PNG, JPEG and MP4 layouts with the demo's recording.yaml.
    let meta = std::fs::read(repo.join("recordings/demo/recording.yaml"))?;
    let side_png = encode(&side, image::ImageFormat::Png)?;
    let side_jpg = encode(&side, image::ImageFormat::Jpeg)?;
    let side_mp4 = small_video(&[side.clone(), side.clone()])?;
    let layout = |kind: u8, parts: &[&[u8]]| -> Vec<u8> {
        let mut v = vec![kind];
        v.extend(parts.join(PART_SEPARATOR));
        v
    };
    let st = small_station.as_bytes();
    put(
        "recording_layout",
        "png",
        &layout(b'p', &[st, &meta, &png, &side_png, &png]),
    )?;
    put(
        "recording_layout",
        "jpg",
        &layout(b'j', &[st, b"", &jpg, &side_jpg]),
    )?;
    put(
        "recording_layout",
        "mp4",
        &layout(b'm', &[st, &meta, &mp4, &side_mp4]),
    )?;
    Ok(seeds.into_inner())
}

/// The first `n` triangles of a mesh and the vertices they use (renumbered).
fn mesh_patch(m: &TriMesh, n: usize) -> TriMesh {
    let mut map = std::collections::HashMap::new();
    let mut positions = Vec::new();
    let mut triangles = Vec::new();
    for t in m.triangles.iter().take(n) {
        let mut out = [0u32; 3];
        for (o, &v) in out.iter_mut().zip(t) {
            *o = *map.entry(v).or_insert_with(|| {
                positions.push(m.positions[v as usize]);
                positions.len() as u32 - 1
            });
        }
        triangles.push(out);
    }
    TriMesh::new(positions, triangles)
}

/// A mesh as ASCII PLY text.
fn ascii_ply(m: &TriMesh) -> String {
    let mut s = format!(
        "ply\nformat ascii 1.0\ncomment seed\nelement vertex {}\nproperty float x\nproperty float y\nproperty float z\nelement face {}\nproperty list uchar int vertex_indices\nend_header\n",
        m.positions.len(),
        m.triangles.len()
    );
    for p in &m.positions {
        s += &format!("{} {} {}\n", p.x, p.y, p.z);
    }
    for t in &m.triangles {
        s += &format!("3 {} {} {}\n", t[0], t[1], t[2]);
    }
    s
}

fn encode(img: &RgbImage, format: image::ImageFormat) -> Res<Vec<u8>> {
    let mut out = std::io::Cursor::new(Vec::new());
    img.write_to(&mut out, format)?;
    Ok(out.into_inner())
}

/// The frames as an H.264 MP4 written by the station's own writer.
fn small_video(frames: &[RgbImage]) -> Res<Vec<u8>> {
    let path = std::env::temp_dir().join(format!("fitstation-seed-{}.mp4", std::process::id()));
    let (w, h) = frames[0].dimensions();
    let mut wr = Mp4VideoWriter::create(&path, w, h, 30.0)?;
    for f in frames {
        wr.push(f)?;
    }
    wr.finish()?;
    let bytes = std::fs::read(&path)?;
    let _ = std::fs::remove_file(&path);
    Ok(bytes)
}

/// Offset of the first top-level box of `kind`.
fn find_box(file: &[u8], kind: &[u8; 4]) -> Option<usize> {
    let mut pos = 0usize;
    while pos + 8 <= file.len() {
        let size = u32::from_be_bytes(file[pos..pos + 4].try_into().ok()?) as usize;
        if &file[pos + 4..pos + 8] == kind {
            return Some(pos);
        }
        if size < 8 {
            return None;
        }
        pos += size;
    }
    None
}

/// Every sample of the video's track as an `h264_sample` input (sync samples with
/// the SPS and PPS, the others without), and whether it is a sync sample.
fn video_samples(mp4_bytes: &[u8]) -> Res<Vec<(bool, Vec<u8>)>> {
    let size = mp4_bytes.len() as u64;
    let mut r = mp4::Mp4Reader::read_header(std::io::Cursor::new(mp4_bytes), size)?;
    let track = *r.tracks().keys().min().ok_or("no track")?;
    let t = &r.tracks()[&track];
    let (sps, pps) = (
        t.sequence_parameter_set()?.to_vec(),
        t.picture_parameter_set()?.to_vec(),
    );
    let n = t.sample_count();
    let mut out = Vec::new();
    for i in 1..=n {
        let Some(s) = r.read_sample(track, i)? else {
            continue;
        };
        let mut v = Vec::new();
        if s.is_sync {
            v.push(u8::try_from(sps.len())?);
            v.extend(&sps);
            v.push(u8::try_from(pps.len())?);
            v.extend(&pps);
        } else {
            v.push(0);
        }
        v.extend(&s.bytes[..]);
        out.push((s.is_sync, v));
    }
    Ok(out)
}

/// The library cut to its first `n` vertices: triangles among them, target offsets on
/// them.
fn library_patch(mut d: LibraryData, n: u32) -> LibraryData {
    d.base.truncate(n as usize);
    d.triangles.retain(|t| t.iter().all(|&v| v < n));
    for t in &mut d.targets {
        let keep: Vec<bool> = t.indices.iter().map(|&i| i < n).collect();
        let mut k = keep.iter();
        t.offsets.retain(|_| *k.next().unwrap_or(&false));
        t.indices.retain(|&i| i < n);
    }
    d
}
