//! The shape library: MakeHuman's macro model over adults, its file format, and fast
//! evaluation of one body from [`ShapeParams`].
//!
//! # Model
//! A body is `base + sum_t w_t(p) * offset_t` over the library's targets `t`. Each target
//! carries *keys*, knot names of the macro variables (e.g. `female`, `young`,
//! `averagemuscle`, `maxweight`, `maxheight`); its weight is `factor_t` times the product,
//! over its keys, of the key's piecewise-linear "hat" weight at the variable's value
//! (MakeHuman's macro.json: each part of a variable interpolates linearly between its low
//! and high knot). The knots are read from macro.json by the importer and stored in the
//! file. The race targets (african/asian/caucasian x gender x age) are premixed with equal
//! race weights 1/3 at import (MakeHuman's default), so race is not a parameter here.
//!
//! # Units and frame
//! Positions and offsets are in the station frame (metres, +Y up, facing +Z, +X the
//! subject's left). [`ShapeLibrary::body`] places the soles on y = 0 and the midpoint of
//! the two feet (centroids of the template's foot vertex sets) on x = z = 0.
//!
//! # File format (`*.fsl`, "fitstation shape library", version 1)
//! The file is the 8 magic bytes `FSLIB\0\x01\0` followed by one zlib (deflate) stream.
//! Inside, little-endian; `varint` is unsigned LEB128, `zigzag` a zigzag-mapped varint;
//! `str` is a varint byte length then UTF-8; lengths in metres are integers in units of
//! [`QUANTUM_M`] (10 micrometres; MakeHuman's targets have 0.1 mm resolution, so this is
//! lossless):
//! ```text
//! u32 version (=1)
//! str meta           JSON: {"source": "...", "variables": [{"name", "knots": [{"name", "value"}]}]}
//! varint V           vertex count
//! V x 3 zigzag       base positions x, y, z (each coordinate delta-coded from the previous vertex)
//! varint T           triangle count
//! T x 3 varint       vertex indices (CCW from outside)
//! varint K           target count
//! K x target:        str name, f64 factor, varint nkeys, nkeys x str key,
//!                    varint n, n x varint index delta (first absolute, then > 0),
//!                    n x 3 zigzag offset dx dy dz
//! ```

use super::{BodyError, ShapeParams, Template, TemplateInfo};
use crate::mesh::TriMesh;
use glam::DVec3;
use std::io::{Read, Write};
use std::path::Path;

/// Length quantum of the file format, metres (0.01 mm).
pub const QUANTUM_M: f64 = 1e-5;
/// Magic bytes opening a shape library file (name + format version).
pub const MAGIC: &[u8; 8] = b"FSLIB\0\x01\0";
/// Format version inside the compressed stream.
pub const VERSION: u32 = 1;
/// File name of the committed library under `templates/`.
pub const LIBRARY_FILE: &str = "makehuman-adult.fsl";
/// File name of the average adult's mesh under `templates/` (an OBJ any tool can read).
pub const TEMPLATE_MESH_FILE: &str = "makehuman-adult.obj";
/// File name of the average adult's sidecar under `templates/`.
pub const TEMPLATE_INFO_FILE: &str = "makehuman-adult.template.json";

/// Guards against hostile headers.
const MAX_VERTICES: usize = 5_000_000;
const MAX_TRIANGLES: usize = 10_000_000;
const MAX_TARGETS: usize = 100_000;
const MAX_STRING: usize = 1 << 20;
const MAX_KEYS: usize = 16;
const MAX_DECOMPRESSED: u64 = 1 << 30;
/// Evaluation keeps knot weights in a fixed table (no allocation per body).
const MAX_VARIABLES: usize = 16;
const MAX_KNOTS: usize = 8;

static DEFAULT_LIBRARY: &[u8] = include_bytes!("../../templates/makehuman-adult.fsl");
static DEFAULT_INFO: &str = include_str!("../../templates/makehuman-adult.template.json");

/// One knot of a macro variable: a name used in target file names and its slider value.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Knot {
    pub name: String,
    pub value: f64,
}

/// A macro variable (gender, age, muscle, weight, height, proportions, ...) and its knots
/// in increasing value order.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Variable {
    pub name: String,
    pub knots: Vec<Knot>,
}

/// Metadata stored as JSON inside the library file.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct LibraryMeta {
    pub source: String,
    pub variables: Vec<Variable>,
}

/// One target as stored: quantised sparse offsets.
#[derive(Clone, Debug, PartialEq)]
pub struct TargetData {
    pub name: String,
    pub factor: f64,
    pub keys: Vec<String>,
    /// Strictly increasing vertex indices.
    pub indices: Vec<u32>,
    /// Offsets in units of [`QUANTUM_M`], one per index.
    pub offsets: Vec<[i32; 3]>,
}

/// The content of a library file.
#[derive(Clone, Debug, PartialEq)]
pub struct LibraryData {
    pub meta: LibraryMeta,
    /// Base positions in units of [`QUANTUM_M`].
    pub base: Vec<[i32; 3]>,
    pub triangles: Vec<[u32; 3]>,
    pub targets: Vec<TargetData>,
}

fn put_varint(out: &mut Vec<u8>, mut v: u64) {
    while v >= 0x80 {
        out.push((v as u8) | 0x80);
        v >>= 7;
    }
    out.push(v as u8);
}
fn put_zigzag(out: &mut Vec<u8>, v: i64) {
    put_varint(out, ((v << 1) ^ (v >> 63)) as u64);
}
fn put_str(out: &mut Vec<u8>, s: &str) {
    put_varint(out, s.len() as u64);
    out.extend_from_slice(s.as_bytes());
}

impl LibraryData {
    /// Serialises into the file format (magic + zlib stream).
    pub fn encode(&self) -> Vec<u8> {
        let b = self.encode_raw();
        let mut enc = flate2::write::ZlibEncoder::new(MAGIC.to_vec(), flate2::Compression::best());
        // Writing into a Vec cannot fail.
        let _ = enc.write_all(&b);
        enc.finish().unwrap_or_default()
    }

    /// The uncompressed stream (see the module docs).
    pub fn encode_raw(&self) -> Vec<u8> {
        let mut b = Vec::new();
        b.extend_from_slice(&VERSION.to_le_bytes());
        put_str(
            &mut b,
            &serde_json::to_string(&self.meta).unwrap_or_default(),
        );
        put_varint(&mut b, self.base.len() as u64);
        let mut prev = [0i64; 3];
        for p in &self.base {
            for k in 0..3 {
                put_zigzag(&mut b, p[k] as i64 - prev[k]);
                prev[k] = p[k] as i64;
            }
        }
        put_varint(&mut b, self.triangles.len() as u64);
        for t in &self.triangles {
            for &v in t {
                put_varint(&mut b, v as u64);
            }
        }
        put_varint(&mut b, self.targets.len() as u64);
        for t in &self.targets {
            put_str(&mut b, &t.name);
            b.extend_from_slice(&t.factor.to_le_bytes());
            put_varint(&mut b, t.keys.len() as u64);
            for k in &t.keys {
                put_str(&mut b, k);
            }
            put_varint(&mut b, t.indices.len() as u64);
            let mut last = 0u32;
            for (i, &v) in t.indices.iter().enumerate() {
                put_varint(&mut b, if i == 0 { v as u64 } else { (v - last) as u64 });
                last = v;
            }
            for o in &t.offsets {
                for &c in o {
                    put_zigzag(&mut b, c as i64);
                }
            }
        }
        b
    }

    /// Parses the file format. `file` names the source in errors.
    ///
    /// # Errors
    /// [`BodyError::Format`] naming the file, the byte offset inside the decompressed
    /// stream and the record (target name, vertex) for any truncated, oversized or
    /// inconsistent content.
    pub fn decode(bytes: &[u8], file: &Path) -> Result<LibraryData, BodyError> {
        if bytes.len() < MAGIC.len() || &bytes[..MAGIC.len()] != MAGIC {
            return Err(BodyError::format(
                file,
                "not a fitstation shape library (bad magic bytes)",
            ));
        }
        let mut raw = Vec::new();
        flate2::read::ZlibDecoder::new(&bytes[MAGIC.len()..])
            .take(MAX_DECOMPRESSED)
            .read_to_end(&mut raw)
            .map_err(|e| BodyError::format(file, format!("corrupt compressed stream: {e}")))?;
        Self::decode_raw(&raw, file)
    }

    /// Parses the decompressed stream (see [`LibraryData::decode`]).
    pub fn decode_raw(raw: &[u8], file: &Path) -> Result<LibraryData, BodyError> {
        let mut r = Reader {
            b: raw,
            pos: 0,
            file,
            ctx: String::from("header"),
        };
        let version = u32::from_le_bytes(r.bytes(4)?.try_into().map_err(|_| r.err("truncated"))?);
        if version != VERSION {
            return Err(r.err(&format!(
                "unsupported version {version} (expected {VERSION})"
            )));
        }
        r.ctx = "metadata".into();
        let meta_s = r.string()?;
        let meta: LibraryMeta =
            serde_json::from_str(&meta_s).map_err(|e| r.err(&format!("metadata JSON: {e}")))?;
        r.ctx = "vertices".into();
        let nv = r.count(MAX_VERTICES, 3)?;
        let mut base = Vec::with_capacity(nv);
        let mut prev = [0i64; 3];
        for i in 0..nv {
            let mut p = [0i32; 3];
            for k in 0..3 {
                // The step may be any i64: a sum past i64's range is out of range too
                // (not an overflow panic in a build with overflow checks).
                p[k] = prev[k]
                    .checked_add(r.zigzag()?)
                    .and_then(|v| i32::try_from(v).ok())
                    .ok_or_else(|| r.err(&format!("vertex {i}: coordinate out of range")))?;
                prev[k] = i64::from(p[k]);
            }
            base.push(p);
        }
        r.ctx = "triangles".into();
        let nt = r.count(MAX_TRIANGLES, 3)?;
        let mut triangles = Vec::with_capacity(nt);
        for i in 0..nt {
            let mut t = [0u32; 3];
            for slot in &mut t {
                let v = r.varint()?;
                if v >= nv as u64 {
                    return Err(r.err(&format!("triangle {i}: index {v} beyond {nv} vertices")));
                }
                *slot = v as u32;
            }
            if t[0] == t[1] || t[1] == t[2] || t[0] == t[2] {
                return Err(r.err(&format!("triangle {i} repeats a vertex")));
            }
            triangles.push(t);
        }
        r.ctx = "targets".into();
        let nk = r.count(MAX_TARGETS, 10)?;
        let mut targets = Vec::with_capacity(nk);
        for ti in 0..nk {
            r.ctx = format!("target {ti}");
            let name = r.string()?;
            r.ctx = format!("target {ti} '{name}'");
            let factor =
                f64::from_le_bytes(r.bytes(8)?.try_into().map_err(|_| r.err("truncated"))?);
            if !factor.is_finite() {
                return Err(r.err("factor is not finite"));
            }
            let nkeys = r.count(MAX_KEYS, 1)?;
            let mut keys = Vec::with_capacity(nkeys);
            for _ in 0..nkeys {
                keys.push(r.string()?);
            }
            let n = r.count(nv, 4)?;
            let mut indices = Vec::with_capacity(n);
            let mut last = 0u64;
            for i in 0..n {
                let d = r.varint()?;
                if i > 0 && d == 0 {
                    return Err(r.err(&format!("entry {i}: indices not increasing")));
                }
                let v = if i == 0 { d } else { last.saturating_add(d) };
                if v >= nv as u64 {
                    return Err(r.err(&format!("entry {i}: vertex {v} beyond {nv} vertices")));
                }
                indices.push(v as u32);
                last = v;
            }
            let mut offsets = Vec::with_capacity(n);
            for i in 0..n {
                let mut o = [0i32; 3];
                for slot in &mut o {
                    *slot = i32::try_from(r.zigzag()?)
                        .map_err(|_| r.err(&format!("entry {i}: offset out of range")))?;
                }
                offsets.push(o);
            }
            targets.push(TargetData {
                name,
                factor,
                keys,
                indices,
                offsets,
            });
        }
        if r.pos != raw.len() {
            r.ctx = "end".into();
            return Err(r.err(&format!("{} trailing bytes", raw.len() - r.pos)));
        }
        Ok(LibraryData {
            meta,
            base,
            triangles,
            targets,
        })
    }
}

struct Reader<'a> {
    b: &'a [u8],
    pos: usize,
    file: &'a Path,
    ctx: String,
}

impl Reader<'_> {
    fn err(&self, msg: &str) -> BodyError {
        BodyError::format(
            self.file,
            format!("byte {} ({}): {msg}", self.pos, self.ctx),
        )
    }
    fn bytes(&mut self, n: usize) -> Result<&[u8], BodyError> {
        if self.b.len() - self.pos < n {
            return Err(self.err("truncated"));
        }
        let s = &self.b[self.pos..self.pos + n];
        self.pos += n;
        Ok(s)
    }
    fn varint(&mut self) -> Result<u64, BodyError> {
        let mut v = 0u64;
        for shift in (0..64).step_by(7) {
            let byte = *self.b.get(self.pos).ok_or_else(|| self.err("truncated"))?;
            self.pos += 1;
            v |= ((byte & 0x7f) as u64) << shift;
            if byte & 0x80 == 0 {
                return Ok(v);
            }
        }
        Err(self.err("varint too long"))
    }
    fn zigzag(&mut self) -> Result<i64, BodyError> {
        let u = self.varint()?;
        Ok(((u >> 1) as i64) ^ -((u & 1) as i64))
    }
    /// A count bounded by `max` and by the remaining bytes (each item >= `min_bytes`).
    fn count(&mut self, max: usize, min_bytes: usize) -> Result<usize, BodyError> {
        let n = self.varint()?;
        let rest = (self.b.len() - self.pos) as u64;
        if n > max as u64 || n.saturating_mul(min_bytes as u64) > rest {
            return Err(self.err(&format!("count {n} too large")));
        }
        Ok(n as usize)
    }
    fn string(&mut self) -> Result<String, BodyError> {
        let n = self.count(MAX_STRING, 1)?;
        let s = self.bytes(n)?;
        String::from_utf8(s.to_vec()).map_err(|_| self.err("string is not UTF-8"))
    }
}

/// A target ready for evaluation: key -> (variable index, knot index), dense f32 offsets.
#[derive(Clone, Debug)]
struct Target {
    factor: f64,
    keys: Vec<(usize, usize)>,
    /// Vertex of each offset; empty for a dense target (one offset per vertex).
    indices: Vec<u32>,
    offsets: Vec<[f32; 3]>,
}

/// Targets touching more than this share of the vertices are expanded to dense arrays
/// (no index per entry: less memory traffic per body).
const DENSE_SHARE: f64 = 0.4;

/// Which [`ShapeParams`] field drives a macro variable of the file (by its macro.json name).
fn param_value(var: &str, p: &ShapeParams) -> Option<f64> {
    Some(match var {
        "gender" => p.gender,
        "age" => p.makehuman_age(),
        "muscle" => p.muscle,
        "weight" => p.weight,
        "height" => p.height,
        "proportions" => p.proportions,
        "cupsize" => p.cup,
        _ => return None,
    })
}

/// The shape library (MakeHuman macro model over adults) with its average template.
#[derive(Clone, Debug)]
pub struct ShapeLibrary {
    meta: LibraryMeta,
    base: Vec<DVec3>,
    targets: Vec<Target>,
    template: Template,
}

impl ShapeLibrary {
    /// The committed `templates/` data, embedded in the binary.
    ///
    /// # Errors
    /// Only if the embedded data were corrupt (a build problem).
    pub fn load_default() -> Result<ShapeLibrary, BodyError> {
        let file = Path::new("templates").join(LIBRARY_FILE);
        let data = LibraryData::decode(DEFAULT_LIBRARY, &file)?;
        let info = TemplateInfo::from_json(
            DEFAULT_INFO,
            &Path::new("templates").join(TEMPLATE_INFO_FILE),
            data.base.len(),
        )?;
        ShapeLibrary::from_data(data, Some(info), &file)
    }

    /// The embedded library, loaded once per process and shared (loading takes a few
    /// hundred milliseconds; tests and tools that need it often should use this).
    ///
    /// # Errors
    /// As [`ShapeLibrary::load_default`] (the message of the first failure).
    pub fn shared() -> Result<&'static ShapeLibrary, BodyError> {
        static SHARED: std::sync::OnceLock<Result<ShapeLibrary, String>> =
            std::sync::OnceLock::new();
        SHARED
            .get_or_init(|| ShapeLibrary::load_default().map_err(|e| e.to_string()))
            .as_ref()
            .map_err(|m| BodyError::format(Path::new("templates"), m.clone()))
    }

    /// Loads `dir/makehuman-adult.fsl` and its sidecar `dir/makehuman-adult.template.json`
    /// (prepared afresh when the sidecar is missing).
    ///
    /// # Errors
    /// Unreadable or malformed files, naming the file.
    pub fn load(dir: &Path) -> Result<ShapeLibrary, BodyError> {
        let file = dir.join(LIBRARY_FILE);
        let bytes = std::fs::read(&file).map_err(|e| BodyError::io(&file, e))?;
        let data = LibraryData::decode(&bytes, &file)?;
        let side = dir.join(TEMPLATE_INFO_FILE);
        let info = if side.exists() {
            Some(TemplateInfo::load(&side, data.base.len())?)
        } else {
            None
        };
        ShapeLibrary::from_data(data, info, &file)
    }

    /// Builds a library from decoded data. Without `info`, the template is prepared here
    /// (about a second).
    ///
    /// # Errors
    /// Targets whose keys are not knots of the stored variables, or a template that
    /// [`super::prepare`] cannot analyse.
    pub fn from_data(
        data: LibraryData,
        info: Option<TemplateInfo>,
        file: &Path,
    ) -> Result<ShapeLibrary, BodyError> {
        let mut targets = Vec::with_capacity(data.targets.len());
        for t in &data.targets {
            let mut keys = Vec::with_capacity(t.keys.len());
            for k in &t.keys {
                let found = data
                    .meta
                    .variables
                    .iter()
                    .enumerate()
                    .find_map(|(vi, var)| {
                        var.knots
                            .iter()
                            .position(|kn| &kn.name == k)
                            .map(|ki| (vi, ki))
                    });
                match found {
                    Some(f) => keys.push(f),
                    None => {
                        return Err(BodyError::format(
                            file,
                            format!("target '{}': key '{k}' is no macro knot", t.name),
                        ))
                    }
                }
            }
            let q = QUANTUM_M as f32;
            let scaled = |o: &[i32; 3]| [o[0] as f32 * q, o[1] as f32 * q, o[2] as f32 * q];
            let nv = data.base.len();
            if t.indices.len() as f64 > DENSE_SHARE * nv as f64 {
                let mut dense = vec![[0.0f32; 3]; nv];
                for (&i, o) in t.indices.iter().zip(&t.offsets) {
                    if let Some(d) = dense.get_mut(i as usize) {
                        *d = scaled(o);
                    }
                }
                targets.push(Target {
                    factor: t.factor,
                    keys,
                    indices: Vec::new(),
                    offsets: dense,
                });
            } else {
                targets.push(Target {
                    factor: t.factor,
                    keys,
                    indices: t.indices.clone(),
                    offsets: t.offsets.iter().map(scaled).collect(),
                });
            }
        }
        if data.meta.variables.len() > MAX_VARIABLES
            || data
                .meta
                .variables
                .iter()
                .any(|v| v.knots.len() > MAX_KNOTS)
        {
            return Err(BodyError::format(file, "too many macro variables or knots"));
        }
        for v in &data.meta.variables {
            if v.knots
                .windows(2)
                .any(|w| w[1].value.partial_cmp(&w[0].value) != Some(std::cmp::Ordering::Greater))
                || v.knots.iter().any(|k| !k.value.is_finite())
            {
                return Err(BodyError::format(
                    file,
                    format!("variable '{}': knots not increasing", v.name),
                ));
            }
        }
        let base: Vec<DVec3> = data
            .base
            .iter()
            .map(|p| DVec3::new(p[0] as f64, p[1] as f64, p[2] as f64) * QUANTUM_M)
            .collect();
        let mesh = TriMesh::new(base.clone(), data.triangles.clone());
        mesh.validate().map_err(|m| BodyError::format(file, m))?;
        if let Some(i) = &info {
            if i.vertex_count != mesh.vertex_count() {
                return Err(BodyError::format(
                    file,
                    "template sidecar is for another vertex count",
                ));
            }
        }
        let mut lib = ShapeLibrary {
            meta: data.meta,
            base,
            targets,
            template: Template {
                mesh,
                info: TemplateInfo::empty(),
            },
        };
        let info = match info {
            Some(i) => i,
            None => {
                // Feet are needed to centre the body; find them on the uncentred body,
                // centre, then analyse the centred body.
                let mut m = lib.template.mesh.clone();
                lib.body_into(&ShapeParams::default(), &mut m.positions);
                let first = super::prepare(&m)?;
                lib.template.info = first;
                let mut m2 = lib.template.mesh.clone();
                lib.body_into(&ShapeParams::default(), &mut m2.positions);
                super::prepare(&m2)?
            }
        };
        lib.template.info = info;
        let mut pos = Vec::new();
        lib.body_into(&ShapeParams::default(), &mut pos);
        lib.template.mesh.positions = pos;
        Ok(lib)
    }

    /// The average adult (default [`ShapeParams`]) in rest pose, with its analysis.
    pub fn template(&self) -> &Template {
        &self.template
    }

    /// A library body with its own analysis (a candidate template for the fit; the
    /// [`super::prepare`] step takes tens of milliseconds).
    ///
    /// # Errors
    /// When [`super::prepare`] cannot analyse the body (not seen within the sampled range).
    pub fn template_for(&self, p: &ShapeParams) -> Result<Template, BodyError> {
        let mesh = self.body(p);
        let info = super::prepare(&mesh)?;
        Ok(Template { mesh, info })
    }

    /// Metadata of the library (source, macro variables).
    pub fn meta(&self) -> &LibraryMeta {
        &self.meta
    }

    /// Number of targets (for reports).
    pub fn target_count(&self) -> usize {
        self.targets.len()
    }

    /// One body: same topology and vertex order as `template().mesh`, station frame,
    /// soles on y = 0, centred on the mark.
    pub fn body(&self, p: &ShapeParams) -> TriMesh {
        let mut pos = Vec::with_capacity(self.base.len());
        self.body_into(p, &mut pos);
        TriMesh::new(pos, self.template.mesh.triangles.clone())
    }

    /// [`ShapeLibrary::body`] into a caller's buffer (no allocation once `out` has the
    /// capacity of the vertex count).
    pub fn body_into(&self, p: &ShapeParams, out: &mut Vec<DVec3>) {
        self.eval_uncentred(p, out);
        let min_y = out.iter().map(|v| v.y).fold(f64::INFINITY, f64::min);
        let rigid = &self.template.info.rigid;
        let centroid = |set: &[u32]| {
            let mut s = DVec3::ZERO;
            let mut n = 0usize;
            for &i in set {
                if let Some(v) = out.get(i as usize) {
                    s += *v;
                    n += 1;
                }
            }
            if n == 0 {
                None
            } else {
                Some(s / n as f64)
            }
        };
        let mark = match (centroid(&rigid.foot_left), centroid(&rigid.foot_right)) {
            (Some(a), Some(b)) => 0.5 * (a + b),
            _ => DVec3::ZERO,
        };
        let shift = DVec3::new(mark.x, if min_y.is_finite() { min_y } else { 0.0 }, mark.z);
        for v in out.iter_mut() {
            *v -= shift;
        }
    }

    /// base + sum of weighted targets, without placing the body on the mark.
    fn eval_uncentred(&self, p: &ShapeParams, out: &mut Vec<DVec3>) {
        let p = p.clamp();
        // Hat weights of every knot of every variable at the parameter values.
        let mut knot_w = [[0.0f64; MAX_KNOTS]; MAX_VARIABLES];
        for (vi, var) in self.meta.variables.iter().enumerate().take(MAX_VARIABLES) {
            let n = var.knots.len().min(MAX_KNOTS);
            if n == 0 {
                continue;
            }
            let first = var.knots[0].value;
            let last = var.knots[n - 1].value;
            // A variable without a parameter (firmness) sits at its middle.
            let v = param_value(&var.name, &p)
                .unwrap_or(0.5 * (first + last))
                .clamp(first, last);
            if n == 1 {
                knot_w[vi][0] = 1.0;
                continue;
            }
            for k in 0..n - 1 {
                let (a, b) = (var.knots[k].value, var.knots[k + 1].value);
                if v >= a && v <= b {
                    let t = (v - a) / (b - a);
                    knot_w[vi][k] = 1.0 - t;
                    knot_w[vi][k + 1] = t;
                    break;
                }
            }
        }
        out.clear();
        out.extend_from_slice(&self.base);
        for t in &self.targets {
            let mut w = t.factor;
            for &(vi, ki) in &t.keys {
                w *= if vi < MAX_VARIABLES && ki < MAX_KNOTS {
                    knot_w[vi][ki]
                } else {
                    0.0
                };
            }
            if w == 0.0 {
                continue;
            }
            let wf = w as f32;
            if t.indices.is_empty() {
                for (v, o) in out.iter_mut().zip(&t.offsets) {
                    *v += DVec3::new((o[0] * wf) as f64, (o[1] * wf) as f64, (o[2] * wf) as f64);
                }
                continue;
            }
            for (&i, o) in t.indices.iter().zip(&t.offsets) {
                // Indices were checked against the vertex count at decode.
                if let Some(v) = out.get_mut(i as usize) {
                    *v += DVec3::new((o[0] * wf) as f64, (o[1] * wf) as f64, (o[2] * wf) as f64);
                }
            }
        }
    }

    /// A deterministic, plausible adult from a seed: half women, half men (gender near
    /// its end), ages 25..75, muscle/weight/proportions spread around the average, the
    /// height slider spread so that statures stay in a human range (about 1.47 to 1.92 m).
    ///
    /// Note: MakeHuman's height slider is extreme at its ends (about 1.22 m at 0 and 2.3 to
    /// 2.45 m at 1 for an average build), so its full 0..1 range is not an adult range.
    pub fn sample_adult(seed: u64) -> ShapeParams {
        let mut rng = SplitMix64(seed ^ 0x5eed_b0d1_u64);
        let male = rng.uniform() < 0.5;
        let g = SAMPLE_GENDER_SPREAD * rng.uniform();
        ShapeParams {
            gender: if male { 1.0 - g } else { g },
            age_years: SAMPLE_AGE_YEARS.0
                + (SAMPLE_AGE_YEARS.1 - SAMPLE_AGE_YEARS.0) * rng.uniform(),
            muscle: rng.normal_in(0.5, SAMPLE_SD, SAMPLE_SLIDER_RANGE),
            weight: rng.normal_in(0.5, SAMPLE_SD, SAMPLE_SLIDER_RANGE),
            height: {
                // MakeHuman's height slider is steep and asymmetric (about +1.4 m per unit
                // above 0.5, +0.7 m below): spread it so statures stay human.
                let z = rng.normal_in(0.0, 1.0, (-SAMPLE_HEIGHT_Z_MAX, SAMPLE_HEIGHT_Z_MAX));
                0.5 + z * if z > 0.0 {
                    SAMPLE_HEIGHT_SD.1
                } else {
                    SAMPLE_HEIGHT_SD.0
                }
            },
            proportions: rng.normal_in(0.5, SAMPLE_SD, SAMPLE_SLIDER_RANGE),
            // The library's sample keeps the average cup: its bodies (and the regression
            // set drawn from them) are those of before the cup size was a parameter.
            cup: 0.5,
        }
    }
}

/// Gender values of sampled adults lie within this distance of 0 (women) or 1 (men).
const SAMPLE_GENDER_SPREAD: f64 = 0.2;
/// Age range of sampled adults, years.
const SAMPLE_AGE_YEARS: (f64, f64) = (25.0, 75.0);
/// Standard deviation of the sampled sliders around 0.5.
const SAMPLE_SD: f64 = 0.18;
/// Deviation of the sampled height slider below and above 0.5 (about 6 cm of stature
/// either way) and the truncation of its standard score.
const SAMPLE_HEIGHT_SD: (f64, f64) = (0.08, 0.045);
const SAMPLE_HEIGHT_Z_MAX: f64 = 2.2;
/// Sampled sliders are truncated to this range (the extremes of MakeHuman's sliders are
/// caricatures, not shoppers).
const SAMPLE_SLIDER_RANGE: (f64, f64) = (0.1, 0.9);

/// SplitMix64 (Steele, Lea, Flood 2014): a tiny deterministic generator.
struct SplitMix64(u64);

impl SplitMix64 {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    /// Uniform in [0, 1).
    fn uniform(&mut self) -> f64 {
        (self.next() >> 11) as f64 / (1u64 << 53) as f64
    }
    /// Normal (Box-Muller) with mean `m` and deviation `sd`, resampled until inside `range`.
    fn normal_in(&mut self, m: f64, sd: f64, range: (f64, f64)) -> f64 {
        for _ in 0..64 {
            let u1 = self.uniform().max(1e-300);
            let u2 = self.uniform();
            let z = (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos();
            let v = m + sd * z;
            if v >= range.0 && v <= range.1 {
                return v;
            }
        }
        m
    }
}
