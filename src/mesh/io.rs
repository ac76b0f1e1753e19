//! Mesh files: OBJ and PLY (ASCII and binary) in and out, binary glTF (GLB) out.
//!
//! Readers never panic on bad input: every failure is a [`MeshIoError`] naming the file
//! and, for text formats, the line. Polygons are fan-triangulated. Units are whatever the
//! file holds (the station's own files hold metres).

use super::TriMesh;
use crate::io::atomic::AtomicFile;
use glam::DVec3;
use std::io::{BufRead, Read, Write};
use std::path::{Path, PathBuf};

/// A mesh file could not be read or written.
#[derive(Debug, thiserror::Error)]
pub enum MeshIoError {
    #[error("{file}: {source}")]
    Io {
        file: PathBuf,
        source: std::io::Error,
    },
    #[error("{file}:{line}: {msg}")]
    Parse {
        file: PathBuf,
        line: usize,
        msg: String,
    },
    #[error("{file}: {msg}")]
    Invalid { file: PathBuf, msg: String },
}

/// Upper bound on element counts a header may announce (guards hostile files).
const MAX_ELEMENTS: usize = 50_000_000;

fn perr(file: &Path, line: usize, msg: impl Into<String>) -> MeshIoError {
    MeshIoError::Parse {
        file: file.to_path_buf(),
        line,
        msg: msg.into(),
    }
}

/// Reads an OBJ or PLY file by its extension.
pub fn read_mesh(path: &Path) -> Result<TriMesh, MeshIoError> {
    match path
        .extension()
        .and_then(|e| e.to_str())
        .map(|e| e.to_ascii_lowercase())
    {
        Some(e) if e == "obj" => read_obj(path, None),
        Some(e) if e == "ply" => read_ply(path),
        _ => Err(MeshIoError::Invalid {
            file: path.to_path_buf(),
            msg: "unknown mesh extension (expected .obj or .ply)".into(),
        }),
    }
}

/// Writes OBJ, PLY or GLB by the extension of `path`.
pub fn write_mesh(path: &Path, mesh: &TriMesh) -> Result<(), MeshIoError> {
    match path
        .extension()
        .and_then(|e| e.to_str())
        .map(|e| e.to_ascii_lowercase())
    {
        Some(e) if e == "obj" => write_obj(path, mesh),
        Some(e) if e == "ply" => write_ply(path, mesh),
        Some(e) if e == "glb" => write_glb(path, mesh),
        _ => Err(MeshIoError::Invalid {
            file: path.to_path_buf(),
            msg: "unknown mesh extension (expected .obj, .ply or .glb)".into(),
        }),
    }
}

fn open(path: &Path) -> Result<std::fs::File, MeshIoError> {
    std::fs::File::open(path).map_err(|source| MeshIoError::Io {
        file: path.to_path_buf(),
        source,
    })
}

/// Reads an OBJ file. With `group = Some(name)`, only faces under `g name` are kept
/// (vertices are still indexed globally; unused ones are dropped at the end).
pub fn read_obj(path: &Path, group: Option<&str>) -> Result<TriMesh, MeshIoError> {
    let reader = std::io::BufReader::new(open(path)?);
    parse_obj(reader, path, group)
}

/// Parses OBJ text from any reader; `path` only names the source in errors.
pub fn parse_obj(
    reader: impl BufRead,
    path: &Path,
    group: Option<&str>,
) -> Result<TriMesh, MeshIoError> {
    let mut positions = Vec::new();
    let mut triangles = Vec::new();
    let mut in_group = group.is_none();
    let mut face = Vec::with_capacity(8);
    for (i, line) in reader.lines().enumerate() {
        let ln = i + 1;
        let line = line.map_err(|e| perr(path, ln, format!("unreadable line: {e}")))?;
        let mut it = line.split_whitespace();
        match it.next() {
            Some("v") => {
                let mut c = [0.0f64; 3];
                for (k, slot) in c.iter_mut().enumerate() {
                    let tok = it.next().ok_or_else(|| {
                        perr(path, ln, format!("vertex has {k} coordinates, needs 3"))
                    })?;
                    *slot = tok
                        .parse()
                        .map_err(|_| perr(path, ln, format!("bad number '{tok}'")))?;
                    if !slot.is_finite() {
                        return Err(perr(path, ln, "vertex coordinate is not finite"));
                    }
                }
                if positions.len() >= MAX_ELEMENTS {
                    return Err(perr(path, ln, "too many vertices"));
                }
                positions.push(DVec3::from_array(c));
            }
            Some("g") | Some("o") => {
                if let Some(g) = group {
                    in_group = it.next() == Some(g);
                }
            }
            Some("f") => {
                if !in_group {
                    continue;
                }
                face.clear();
                for tok in it {
                    let vtok = tok.split('/').next().unwrap_or("");
                    let idx: i64 = vtok
                        .parse()
                        .map_err(|_| perr(path, ln, format!("bad face index '{tok}'")))?;
                    let n = positions.len() as i64;
                    let abs = if idx > 0 {
                        idx - 1
                    } else if idx < 0 {
                        n + idx
                    } else {
                        -1
                    };
                    if abs < 0 || abs >= n {
                        return Err(perr(
                            path,
                            ln,
                            format!("face index {idx} out of range (have {n} vertices)"),
                        ));
                    }
                    face.push(abs as u32);
                }
                if face.len() < 3 {
                    return Err(perr(path, ln, "face with fewer than 3 vertices"));
                }
                for k in 1..face.len() - 1 {
                    let t = [face[0], face[k], face[k + 1]];
                    if t[0] != t[1] && t[1] != t[2] && t[0] != t[2] {
                        triangles.push(t);
                    }
                }
            }
            _ => {}
        }
    }
    finish(path, positions, triangles)
}

fn finish(
    path: &Path,
    positions: Vec<DVec3>,
    triangles: Vec<[u32; 3]>,
) -> Result<TriMesh, MeshIoError> {
    if triangles.is_empty() {
        return Err(MeshIoError::Invalid {
            file: path.to_path_buf(),
            msg: "no faces".into(),
        });
    }
    let mut m = TriMesh::new(positions, triangles);
    m.compact();
    m.validate().map_err(|msg| MeshIoError::Invalid {
        file: path.to_path_buf(),
        msg,
    })?;
    Ok(m)
}

#[derive(Debug, Clone, Copy, PartialEq)]
enum PlyType {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    F32,
    F64,
}

impl PlyType {
    fn parse(s: &str) -> Option<Self> {
        Some(match s {
            "char" | "int8" => PlyType::I8,
            "uchar" | "uint8" => PlyType::U8,
            "short" | "int16" => PlyType::I16,
            "ushort" | "uint16" => PlyType::U16,
            "int" | "int32" => PlyType::I32,
            "uint" | "uint32" => PlyType::U32,
            "float" | "float32" => PlyType::F32,
            "double" | "float64" => PlyType::F64,
            _ => return None,
        })
    }
    fn size(self) -> usize {
        match self {
            PlyType::I8 | PlyType::U8 => 1,
            PlyType::I16 | PlyType::U16 => 2,
            PlyType::I32 | PlyType::U32 | PlyType::F32 => 4,
            PlyType::F64 => 8,
        }
    }
}

#[derive(Debug, Clone)]
enum PlyProp {
    Scalar(String, PlyType),
    List(String, PlyType, PlyType),
}

#[derive(Debug, Clone)]
struct PlyElement {
    name: String,
    count: usize,
    props: Vec<PlyProp>,
}

#[derive(Debug, Clone, Copy, PartialEq)]
enum PlyFormat {
    Ascii,
    BinLe,
    BinBe,
}

/// Reads a PLY file (ASCII or binary, either endianness): `vertex` x/y/z and
/// `face` vertex_indices (or vertex_index); other elements and properties are skipped.
pub fn read_ply(path: &Path) -> Result<TriMesh, MeshIoError> {
    let mut bytes = Vec::new();
    open(path)?
        .read_to_end(&mut bytes)
        .map_err(|source| MeshIoError::Io {
            file: path.to_path_buf(),
            source,
        })?;
    parse_ply(&bytes, path)
}

/// Parses PLY bytes; `path` only names the source in errors.
pub fn parse_ply(bytes: &[u8], path: &Path) -> Result<TriMesh, MeshIoError> {
    let header = parse_ply_header(bytes, path)?;
    let mut reader = PlyBody {
        bytes,
        pos: header.body_start,
        format: header.format,
        line: header.lines,
        path,
    };
    let mut positions = Vec::new();
    let mut triangles = Vec::new();
    for el in &header.elements {
        if el.props.is_empty() && header.format != PlyFormat::Ascii {
            // Binary records without properties take no bytes: nothing to read (and a
            // header announcing billions of them must not keep the reader spinning).
            continue;
        }
        for _ in 0..el.count {
            if reader.pos > bytes.len() {
                return Err(reader.err("file ends before its last record (truncated?)"));
            }
            read_ply_record(&mut reader, el, &mut positions, &mut triangles)?;
        }
    }
    let n = positions.len() as u32;
    if triangles.iter().any(|t| t.iter().any(|&v| v >= n)) {
        return Err(MeshIoError::Invalid {
            file: path.to_path_buf(),
            msg: format!("face index beyond {n} vertices"),
        });
    }
    triangles.retain(|t| t[0] != t[1] && t[1] != t[2] && t[0] != t[2]);
    finish(path, positions, triangles)
}

/// What a PLY header announces: the body's format, its elements and where it starts.
struct PlyHeader {
    format: PlyFormat,
    elements: Vec<PlyElement>,
    /// Byte offset of the first record.
    body_start: usize,
    /// Header lines read (the line number of the last one).
    lines: usize,
}

/// Reads the header's text lines up to `end_header`: format, elements and properties.
fn parse_ply_header(bytes: &[u8], path: &Path) -> Result<PlyHeader, MeshIoError> {
    // Header: text lines up to "end_header".
    let mut pos = 0usize;
    let mut line_no = 0usize;
    let next_line = |pos: &mut usize| -> Option<String> {
        if *pos >= bytes.len() {
            return None;
        }
        let end = bytes[*pos..]
            .iter()
            .position(|&b| b == b'\n')
            .map(|e| *pos + e)
            .unwrap_or(bytes.len());
        let s = String::from_utf8_lossy(&bytes[*pos..end])
            .trim_end_matches('\r')
            .to_string();
        *pos = (end + 1).min(bytes.len());
        Some(s)
    };
    let mut format = None;
    let mut elements: Vec<PlyElement> = Vec::new();
    let mut first = true;
    loop {
        line_no += 1;
        let line = next_line(&mut pos)
            .ok_or_else(|| perr(path, line_no, "header ends before end_header"))?;
        if first {
            if line.trim() != "ply" {
                return Err(perr(path, 1, "not a PLY file (first line is not 'ply')"));
            }
            first = false;
            continue;
        }
        let toks: Vec<&str> = line.split_whitespace().collect();
        match toks.first().copied() {
            Some("format") => {
                format = Some(match toks.get(1).copied() {
                    Some("ascii") => PlyFormat::Ascii,
                    Some("binary_little_endian") => PlyFormat::BinLe,
                    Some("binary_big_endian") => PlyFormat::BinBe,
                    other => return Err(perr(path, line_no, format!("unknown format {other:?}"))),
                })
            }
            Some("element") => {
                let name = toks
                    .get(1)
                    .ok_or_else(|| perr(path, line_no, "element without name"))?;
                let count: usize = toks
                    .get(2)
                    .and_then(|c| c.parse().ok())
                    .ok_or_else(|| perr(path, line_no, "element without a valid count"))?;
                if count > MAX_ELEMENTS {
                    return Err(perr(
                        path,
                        line_no,
                        format!("element count {count} is implausibly large"),
                    ));
                }
                elements.push(PlyElement {
                    name: name.to_string(),
                    count,
                    props: Vec::new(),
                });
            }
            Some("property") => {
                let el = elements
                    .last_mut()
                    .ok_or_else(|| perr(path, line_no, "property before any element"))?;
                let prop = if toks.get(1) == Some(&"list") {
                    let ct = toks.get(2).and_then(|t| PlyType::parse(t));
                    let it = toks.get(3).and_then(|t| PlyType::parse(t));
                    let name = toks.get(4);
                    match (ct, it, name) {
                        (Some(c), Some(i), Some(n)) => PlyProp::List(n.to_string(), c, i),
                        _ => return Err(perr(path, line_no, "malformed list property")),
                    }
                } else {
                    match (toks.get(1).and_then(|t| PlyType::parse(t)), toks.get(2)) {
                        (Some(t), Some(n)) => PlyProp::Scalar(n.to_string(), t),
                        _ => return Err(perr(path, line_no, "malformed property")),
                    }
                };
                el.props.push(prop);
            }
            Some("end_header") => break,
            Some("comment") | Some("obj_info") | None => {}
            Some(other) => {
                return Err(perr(
                    path,
                    line_no,
                    format!("unknown header keyword '{other}'"),
                ))
            }
        }
    }
    let format = format.ok_or_else(|| perr(path, line_no, "header has no format line"))?;
    Ok(PlyHeader {
        format,
        elements,
        body_start: pos,
        lines: line_no,
    })
}

/// Reads one record of `el`: a vertex's x, y, z into `positions`, a face's polygon
/// fan-triangulated into `triangles`, anything else read and dropped.
fn read_ply_record(
    reader: &mut PlyBody<'_>,
    el: &PlyElement,
    positions: &mut Vec<DVec3>,
    triangles: &mut Vec<[u32; 3]>,
) -> Result<(), MeshIoError> {
    reader.begin_record()?;
    let mut xyz = [f64::NAN; 3];
    let mut face: Vec<u32> = Vec::new();
    for p in &el.props {
        match p {
            PlyProp::Scalar(name, t) => {
                let v = reader.scalar(*t)?;
                if el.name == "vertex" {
                    match name.as_str() {
                        "x" => xyz[0] = v,
                        "y" => xyz[1] = v,
                        "z" => xyz[2] = v,
                        _ => {}
                    }
                }
            }
            PlyProp::List(name, ct, it) => {
                let n = reader.scalar(*ct)?;
                if !(0.0..=1024.0).contains(&n) {
                    return Err(reader.err(format!("list length {n} out of range")));
                }
                let keep =
                    el.name == "face" && (name == "vertex_indices" || name == "vertex_index");
                for _ in 0..n as usize {
                    let v = reader.scalar(*it)?;
                    if keep {
                        if v < 0.0 || v.fract() != 0.0 {
                            return Err(reader.err(format!("bad vertex index {v}")));
                        }
                        face.push(v as u32);
                    }
                }
            }
        }
    }
    if el.name == "vertex" {
        if !xyz.iter().all(|c| c.is_finite()) {
            return Err(reader.err("vertex without finite x, y, z"));
        }
        positions.push(DVec3::from_array(xyz));
    } else if el.name == "face" {
        if face.len() < 3 {
            return Err(reader.err("face with fewer than 3 vertices"));
        }
        for k in 1..face.len() - 1 {
            triangles.push([face[0], face[k], face[k + 1]]);
        }
    }
    reader.end_record()
}

struct PlyBody<'a> {
    bytes: &'a [u8],
    pos: usize,
    format: PlyFormat,
    line: usize,
    path: &'a Path,
}

impl PlyBody<'_> {
    fn err(&self, msg: impl Into<String>) -> MeshIoError {
        match self.format {
            PlyFormat::Ascii => perr(self.path, self.line, msg),
            _ => MeshIoError::Invalid {
                file: self.path.to_path_buf(),
                msg: format!("at byte {}: {}", self.pos, msg.into()),
            },
        }
    }
    fn begin_record(&mut self) -> Result<(), MeshIoError> {
        if self.format == PlyFormat::Ascii {
            self.line += 1;
            // Skip blank lines.
            while self.pos < self.bytes.len()
                && (self.bytes[self.pos] == b'\n' || self.bytes[self.pos] == b'\r')
            {
                if self.bytes[self.pos] == b'\n' {
                    self.line += 1;
                }
                self.pos += 1;
            }
        }
        Ok(())
    }
    fn end_record(&mut self) -> Result<(), MeshIoError> {
        if self.format == PlyFormat::Ascii {
            while self.pos < self.bytes.len() && self.bytes[self.pos] != b'\n' {
                self.pos += 1;
            }
            self.pos += 1;
        }
        Ok(())
    }
    fn scalar(&mut self, t: PlyType) -> Result<f64, MeshIoError> {
        match self.format {
            PlyFormat::Ascii => {
                while self.pos < self.bytes.len()
                    && (self.bytes[self.pos] == b' ' || self.bytes[self.pos] == b'\t')
                {
                    self.pos += 1;
                }
                let start = self.pos;
                while self.pos < self.bytes.len() && !self.bytes[self.pos].is_ascii_whitespace() {
                    self.pos += 1;
                }
                if start == self.pos {
                    return Err(self.err("record ends early (truncated file?)"));
                }
                let tok = String::from_utf8_lossy(&self.bytes[start..self.pos]).to_string();
                tok.parse::<f64>()
                    .map_err(|_| self.err(format!("bad number '{tok}'")))
            }
            PlyFormat::BinLe | PlyFormat::BinBe => {
                let n = t.size();
                if self.pos + n > self.bytes.len() {
                    return Err(self.err("file ends early (truncated?)"));
                }
                let mut b = [0u8; 8];
                b[..n].copy_from_slice(&self.bytes[self.pos..self.pos + n]);
                if self.format == PlyFormat::BinBe {
                    b[..n].reverse();
                }
                self.pos += n;
                Ok(match t {
                    PlyType::I8 => b[0] as i8 as f64,
                    PlyType::U8 => b[0] as f64,
                    PlyType::I16 => i16::from_le_bytes([b[0], b[1]]) as f64,
                    PlyType::U16 => u16::from_le_bytes([b[0], b[1]]) as f64,
                    PlyType::I32 => i32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f64,
                    PlyType::U32 => u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f64,
                    PlyType::F32 => f32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f64,
                    PlyType::F64 => f64::from_le_bytes(b),
                })
            }
        }
    }
}

/// Opens an output mesh file under a temporary name ([`crate::io::atomic`]).
fn create(path: &Path) -> Result<AtomicFile, MeshIoError> {
    AtomicFile::create(path).map_err(|e| MeshIoError::Io {
        file: path.to_path_buf(),
        source: e.into(),
    })
}

/// Puts a written mesh file in place (fsync, rename).
fn commit(w: AtomicFile, path: &Path) -> Result<(), MeshIoError> {
    w.commit().map_err(|e| MeshIoError::Io {
        file: path.to_path_buf(),
        source: e.into(),
    })
}

fn wio(path: &Path) -> impl Fn(std::io::Error) -> MeshIoError + '_ {
    move |source| MeshIoError::Io {
        file: path.to_path_buf(),
        source,
    }
}

/// Writes an OBJ file (`v` and `f` lines, 1-based indices, 6 decimals = micrometres).
pub fn write_obj(path: &Path, mesh: &TriMesh) -> Result<(), MeshIoError> {
    let mut w = create(path)?;
    write_obj_to(&mut w, mesh).map_err(wio(path))?;
    commit(w, path)
}

pub fn write_obj_to(w: &mut impl Write, mesh: &TriMesh) -> std::io::Result<()> {
    writeln!(
        w,
        "# fitstation mesh, metres, station frame (+Y up, +Z front, +X subject's left)"
    )?;
    for p in &mesh.positions {
        writeln!(w, "v {:.6} {:.6} {:.6}", p.x, p.y, p.z)?;
    }
    for t in &mesh.triangles {
        writeln!(w, "f {} {} {}", t[0] + 1, t[1] + 1, t[2] + 1)?;
    }
    Ok(())
}

/// Writes a binary little-endian PLY (float vertices, int indices).
pub fn write_ply(path: &Path, mesh: &TriMesh) -> Result<(), MeshIoError> {
    let mut w = create(path)?;
    (|| -> std::io::Result<()> {
        write!(
            w,
            "ply\nformat binary_little_endian 1.0\ncomment fitstation mesh, metres\nelement vertex {}\nproperty float x\nproperty float y\nproperty float z\nelement face {}\nproperty list uchar int vertex_indices\nend_header\n",
            mesh.positions.len(),
            mesh.triangles.len()
        )?;
        for p in &mesh.positions {
            for c in p.to_array() {
                w.write_all(&(c as f32).to_le_bytes())?;
            }
        }
        for t in &mesh.triangles {
            w.write_all(&[3u8])?;
            for v in t {
                w.write_all(&(*v as i32).to_le_bytes())?;
            }
        }
        w.flush()
    })()
    .map_err(wio(path))?;
    commit(w, path)
}

/// Writes a binary glTF 2.0 file (one mesh, positions + normals + indices, metres, Y up).
/// glTF's axes (+Y up, +Z forward facing the viewer) match the station frame.
pub fn write_glb(path: &Path, mesh: &TriMesh) -> Result<(), MeshIoError> {
    let normals = mesh.vertex_normals();
    let mut bin: Vec<u8> = Vec::new();
    let bb = mesh.bounds().ok_or_else(|| MeshIoError::Invalid {
        file: path.to_path_buf(),
        msg: "empty mesh".into(),
    })?;
    for p in &mesh.positions {
        for c in p.to_array() {
            bin.extend_from_slice(&(c as f32).to_le_bytes());
        }
    }
    let npos = bin.len();
    for n in &normals {
        for c in n.to_array() {
            bin.extend_from_slice(&(c as f32).to_le_bytes());
        }
    }
    let nidx_off = bin.len();
    for t in &mesh.triangles {
        for v in t {
            bin.extend_from_slice(&v.to_le_bytes());
        }
    }
    while !bin.len().is_multiple_of(4) {
        bin.push(0);
    }
    let nv = mesh.positions.len();
    let json = serde_json::json!({
        "asset": {"version": "2.0", "generator": "fitstation"},
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": [{"mesh": 0, "name": "avatar"}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0, "NORMAL": 1}, "indices": 2, "mode": 4}]}],
        "buffers": [{"byteLength": bin.len()}],
        "bufferViews": [
            {"buffer": 0, "byteOffset": 0, "byteLength": npos, "target": 34962},
            {"buffer": 0, "byteOffset": npos, "byteLength": nidx_off - npos, "target": 34962},
            {"buffer": 0, "byteOffset": nidx_off, "byteLength": mesh.triangles.len() * 12, "target": 34963}
        ],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": nv, "type": "VEC3",
             "min": [bb.min.x as f32, bb.min.y as f32, bb.min.z as f32],
             "max": [bb.max.x as f32, bb.max.y as f32, bb.max.z as f32]},
            {"bufferView": 1, "componentType": 5126, "count": nv, "type": "VEC3"},
            {"bufferView": 2, "componentType": 5125, "count": mesh.triangles.len() * 3, "type": "SCALAR"}
        ]
    });
    let mut js = serde_json::to_vec(&json).map_err(|e| MeshIoError::Invalid {
        file: path.to_path_buf(),
        msg: e.to_string(),
    })?;
    while js.len() % 4 != 0 {
        js.push(b' ');
    }
    let total = 12 + 8 + js.len() + 8 + bin.len();
    let mut w = create(path)?;
    (|| -> std::io::Result<()> {
        w.write_all(b"glTF")?;
        w.write_all(&2u32.to_le_bytes())?;
        w.write_all(&(total as u32).to_le_bytes())?;
        w.write_all(&(js.len() as u32).to_le_bytes())?;
        w.write_all(b"JSON")?;
        w.write_all(&js)?;
        w.write_all(&(bin.len() as u32).to_le_bytes())?;
        w.write_all(b"BIN\0")?;
        w.write_all(&bin)?;
        w.flush()
    })()
    .map_err(wio(path))?;
    commit(w, path)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::shapes;

    fn tmp(name: &str) -> PathBuf {
        let d = std::env::temp_dir().join(format!("fitstation-io-{}", std::process::id()));
        std::fs::create_dir_all(&d).unwrap();
        d.join(name)
    }

    #[test]
    fn obj_and_ply_round_trip() {
        let m = shapes::uv_sphere(0.5, 6, 12);
        for name in ["a.obj", "a.ply"] {
            let p = tmp(name);
            write_mesh(&p, &m).unwrap();
            let r = read_mesh(&p).unwrap();
            assert_eq!(r.triangles, m.triangles);
            for (a, b) in r.positions.iter().zip(&m.positions) {
                assert!((*a - *b).length() < 1e-6);
            }
        }
        let g = tmp("a.glb");
        write_mesh(&g, &m).unwrap();
        let bytes = std::fs::read(&g).unwrap();
        assert_eq!(&bytes[..4], b"glTF");
        assert_eq!(
            u32::from_le_bytes(bytes[8..12].try_into().unwrap()) as usize,
            bytes.len()
        );
    }

    #[test]
    fn obj_group_selection_and_quads() {
        let src = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 5 5 5\ng body\nf 1/1 2/2 3/3 4/4\ng other\nf 2 3 5\n";
        let m = parse_obj(src.as_bytes(), Path::new("x.obj"), Some("body")).unwrap();
        assert_eq!(m.triangle_count(), 2);
        assert_eq!(m.vertex_count(), 4);
    }

    #[test]
    fn ascii_ply_parses() {
        let src = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nproperty uchar red\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0 1\n1 0 0 2\n0 1 0 3\n3 0 1 2\n";
        let m = parse_ply(src.as_bytes(), Path::new("x.ply")).unwrap();
        assert_eq!(m.triangles, vec![[0, 1, 2]]);
    }

    /// Garbled inputs: every reader returns an error naming the file, never panics.
    #[test]
    fn garbled_inputs_are_errors_not_panics() {
        let obj_cases = [
            "v 1 2\nf 1 2 3\n",
            "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n",
            "v 0 0 0\nv a b c\n",
            "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2\n",
            "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n",
            "v nan 0 0\n",
            "",
            "f -5 -6 -7\n",
            "v 1e999 0 0\n",
        ];
        for (i, c) in obj_cases.iter().enumerate() {
            let e = parse_obj(c.as_bytes(), Path::new("bad.obj"), None);
            let msg = e.expect_err(&format!("case {i} should fail")).to_string();
            assert!(msg.contains("bad.obj"), "case {i}: {msg}");
        }
        let head = "ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n";
        let mut truncated = head.as_bytes().to_vec();
        truncated.extend_from_slice(&[0u8; 20]);
        let ply_cases: Vec<Vec<u8>> = vec![
            b"plx\n".to_vec(),
            b"ply\nformat ascii 1.0\nelement vertex 99999999999\nend_header\n".to_vec(),
            b"ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\n".to_vec(),
            b"ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\nproperty float z\nend_header\n0 0 0\n".to_vec(),
            b"ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 7\n".to_vec(),
            b"ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n200 0 1 7\n".to_vec(),
            truncated,
            b"ply\nformat binary_middle_endian 1.0\nend_header\n".to_vec(),
        ];
        for (i, c) in ply_cases.iter().enumerate() {
            let e = parse_ply(c, Path::new("bad.ply"));
            let msg = e
                .expect_err(&format!("ply case {i} should fail"))
                .to_string();
            assert!(msg.contains("bad.ply"), "ply case {i}: {msg}");
        }
        // Random bytes never panic.
        let mut s = 0x1234_5678_u64;
        for _ in 0..200 {
            let mut b = head.as_bytes().to_vec();
            for _ in 0..(s % 97) {
                s ^= s << 13;
                s ^= s >> 7;
                s ^= s << 17;
                b.push((s & 0xff) as u8);
            }
            let _ = parse_ply(&b, Path::new("r.ply"));
            let _ = parse_obj(&b[..], Path::new("r.obj"), None);
        }
    }
}
