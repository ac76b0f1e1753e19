//! OpenCV FileStorage YAML: the subset `station.yaml` uses (`%YAML:1.0`, top-level
//! scalars and `!!opencv-matrix` nodes), read and written by hand so that
//! `cv2.FileStorage(path, cv2.FILE_STORAGE_READ)` reads what we write and OpenCV's own
//! calibration output can be pasted in. Unknown keys are kept and ignored.

use super::{Camera, CameraError, Intrinsics, Rigid, StationCalibration};
use glam::{DMat3, DVec3};
use std::collections::BTreeMap;
use std::path::Path;

/// A top-level FileStorage node.
#[derive(Debug, Clone, PartialEq)]
pub enum Node {
    Scalar(String),
    Matrix {
        rows: usize,
        cols: usize,
        data: Vec<f64>,
    },
    /// Anything else (nested maps, sequences): its raw text.
    Other(String),
}

fn ferr(file: &str, msg: impl Into<String>) -> CameraError {
    CameraError::File {
        file: file.to_string(),
        msg: msg.into(),
    }
}

/// Parses FileStorage YAML text into top-level nodes. `file` names the source in errors.
pub fn parse(text: &str, file: &str) -> Result<BTreeMap<String, Node>, CameraError> {
    let mut out = BTreeMap::new();
    let lines: Vec<&str> = text.lines().collect();
    let first = lines
        .iter()
        .find(|l| !l.trim().is_empty())
        .copied()
        .unwrap_or("");
    if !first.trim_start().starts_with("%YAML") {
        return Err(ferr(
            file,
            "not an OpenCV FileStorage YAML file (first line should be %YAML:1.0)",
        ));
    }
    let mut i = 0;
    while i < lines.len() {
        let raw = lines[i];
        let line = strip_comment(raw);
        i += 1;
        if line.trim().is_empty()
            || line.starts_with('%')
            || line.trim() == "---"
            || line.trim() == "..."
        {
            continue;
        }
        if line.starts_with(' ') || line.starts_with('\t') {
            continue; // belongs to an unknown nested node
        }
        let Some((key, rest)) = line.split_once(':') else {
            return Err(ferr(file, format!("line {i}: expected 'key: value'")));
        };
        let key = key.trim().to_string();
        let rest = rest.trim();
        if rest.starts_with("!!opencv-matrix") {
            // Gather the indented block.
            let mut block = String::new();
            while i < lines.len()
                && (lines[i].starts_with(' ')
                    || lines[i].starts_with('\t')
                    || lines[i].trim().is_empty())
            {
                block.push_str(strip_comment(lines[i]));
                block.push('\n');
                i += 1;
            }
            out.insert(
                key.clone(),
                parse_matrix(&block).map_err(|m| ferr(file, format!("{key}: {m}")))?,
            );
        } else if rest.is_empty() {
            let mut block = String::new();
            while i < lines.len() && (lines[i].starts_with(' ') || lines[i].starts_with('\t')) {
                block.push_str(lines[i]);
                block.push('\n');
                i += 1;
            }
            out.insert(key, Node::Other(block));
        } else {
            let v = rest.trim_matches('"').trim_matches('\'').to_string();
            out.insert(key, Node::Scalar(v));
        }
    }
    Ok(out)
}

fn strip_comment(l: &str) -> &str {
    // '#' starts a comment outside quotes; station files do not quote '#'.
    match l.find('#') {
        Some(p) if !l[..p].contains('"') => &l[..p],
        _ => l,
    }
}

fn parse_matrix(block: &str) -> Result<Node, String> {
    let mut rows = None;
    let mut cols = None;
    let mut data_text = String::new();
    let mut in_data = false;
    for l in block.lines() {
        let t = l.trim();
        if in_data {
            data_text.push(' ');
            data_text.push_str(t);
            if t.contains(']') {
                in_data = false;
            }
            continue;
        }
        if let Some(v) = t.strip_prefix("rows:") {
            rows = v.trim().parse::<usize>().ok();
        } else if let Some(v) = t.strip_prefix("cols:") {
            cols = v.trim().parse::<usize>().ok();
        } else if let Some(v) = t.strip_prefix("data:") {
            data_text.push_str(v.trim());
            in_data = !v.contains(']');
        }
    }
    let rows = rows.ok_or("matrix without rows")?;
    let cols = cols.ok_or("matrix without cols")?;
    let inner = data_text
        .trim()
        .trim_start_matches('[')
        .trim_end_matches(']');
    let data: Result<Vec<f64>, _> = inner
        .split(',')
        .map(|s| s.trim())
        .filter(|s| !s.is_empty())
        .map(|s| s.parse::<f64>().map_err(|_| format!("bad number '{s}'")))
        .collect();
    let data = data?;
    if rows > 64 || cols > 64 || data.len() != rows * cols {
        return Err(format!(
            "matrix is {rows}x{cols} but holds {} numbers",
            data.len()
        ));
    }
    if data.iter().any(|v| !v.is_finite()) {
        return Err("matrix holds a non-finite number".into());
    }
    Ok(Node::Matrix { rows, cols, data })
}

fn matrix<'a>(
    nodes: &'a BTreeMap<String, Node>,
    key: &str,
    rows: usize,
    cols: usize,
    file: &str,
) -> Result<&'a [f64], CameraError> {
    match nodes.get(key) {
        Some(Node::Matrix {
            rows: r,
            cols: c,
            data,
        }) if r * c == rows * cols && (*r == rows || *r == cols) => Ok(data),
        Some(Node::Matrix {
            rows: r, cols: c, ..
        }) => Err(ferr(
            file,
            format!("{key} is {r}x{c}, expected {rows}x{cols}"),
        )),
        Some(_) => Err(ferr(file, format!("{key} is not an !!opencv-matrix"))),
        None => Err(ferr(file, format!("missing key {key}"))),
    }
}

fn int(nodes: &BTreeMap<String, Node>, key: &str, file: &str) -> Result<u32, CameraError> {
    match nodes.get(key) {
        Some(Node::Scalar(s)) => s
            .parse::<u32>()
            .ok()
            .filter(|v| *v > 0 && *v <= 65_536)
            .ok_or_else(|| ferr(file, format!("{key} = '{s}' is not a positive image size"))),
        _ => Err(ferr(file, format!("missing key {key}"))),
    }
}

fn camera(nodes: &BTreeMap<String, Node>, prefix: &str, file: &str) -> Result<Camera, CameraError> {
    let k = matrix(nodes, &format!("{prefix}_camera_matrix"), 3, 3, file)?;
    let d = matrix(
        nodes,
        &format!("{prefix}_distortion_coefficients"),
        1,
        5,
        file,
    )?;
    let r = matrix(nodes, &format!("{prefix}_rotation"), 3, 3, file)?;
    let t = matrix(nodes, &format!("{prefix}_translation"), 3, 1, file)?;
    let rotation = DMat3::from_cols_array(&[r[0], r[3], r[6], r[1], r[4], r[7], r[2], r[5], r[8]]);
    // Reject a rotation that is not one (a pasted matrix in the wrong place).
    let should_be_i = rotation * rotation.transpose();
    if (should_be_i - DMat3::IDENTITY)
        .to_cols_array()
        .iter()
        .any(|e| e.abs() > 1e-3)
        || rotation.determinant() < 0.0
    {
        return Err(ferr(
            file,
            format!("{prefix}_rotation is not a rotation matrix"),
        ));
    }
    if k[0] <= 0.0 || k[4] <= 0.0 {
        return Err(ferr(
            file,
            format!("{prefix}_camera_matrix has a non-positive focal length"),
        ));
    }
    Ok(Camera {
        intrinsics: Intrinsics {
            width: int(nodes, &format!("{prefix}_image_width"), file)?,
            height: int(nodes, &format!("{prefix}_image_height"), file)?,
            fx: k[0],
            fy: k[4],
            cx: k[2],
            cy: k[5],
            dist: [d[0], d[1], d[2], d[3], d[4]],
        },
        camera_from_station: Rigid {
            rotation,
            translation: DVec3::new(t[0], t[1], t[2]),
        },
    })
}

const KNOWN_SUFFIXES: [&str; 6] = [
    "_image_width",
    "_image_height",
    "_camera_matrix",
    "_distortion_coefficients",
    "_rotation",
    "_translation",
];

impl StationCalibration {
    /// Parses `station.yaml` text.
    pub fn from_yaml_str(text: &str, file: &str) -> Result<Self, CameraError> {
        let nodes = parse(text, file)?;
        let front = camera(&nodes, "front", file)?;
        let side = camera(&nodes, "side", file)?;
        let extra = nodes
            .iter()
            .filter(|(k, _)| {
                !(["front", "side"]
                    .iter()
                    .any(|p| KNOWN_SUFFIXES.iter().any(|s| **k == format!("{p}{s}"))))
            })
            .filter_map(|(k, v)| match v {
                Node::Scalar(s) => Some((k.clone(), s.clone())),
                _ => None,
            })
            .collect();
        Ok(StationCalibration { front, side, extra })
    }

    /// Reads `station.yaml`.
    pub fn load(path: &Path) -> Result<Self, CameraError> {
        let name = path.display().to_string();
        let text = std::fs::read_to_string(path).map_err(|e| ferr(&name, e.to_string()))?;
        Self::from_yaml_str(&text, &name)
    }

    /// Serialises to OpenCV FileStorage YAML.
    pub fn to_yaml_string(&self) -> String {
        let mut s = String::from("%YAML:1.0\n---\n");
        for (prefix, cam) in [("front", &self.front), ("side", &self.side)] {
            let i = &cam.intrinsics;
            s += &format!(
                "{prefix}_image_width: {}\n{prefix}_image_height: {}\n",
                i.width, i.height
            );
            s += &mat_node(&format!("{prefix}_camera_matrix"), 3, 3, &i.k_rows());
            s += &mat_node(&format!("{prefix}_distortion_coefficients"), 1, 5, &i.dist);
            let r = cam.camera_from_station.rotation;
            let rows = [
                r.x_axis.x, r.y_axis.x, r.z_axis.x, r.x_axis.y, r.y_axis.y, r.z_axis.y, r.x_axis.z,
                r.y_axis.z, r.z_axis.z,
            ];
            s += &mat_node(&format!("{prefix}_rotation"), 3, 3, &rows);
            let t = cam.camera_from_station.translation;
            s += &mat_node(&format!("{prefix}_translation"), 3, 1, &[t.x, t.y, t.z]);
        }
        for (k, v) in &self.extra {
            let safe = v.replace('"', "'");
            s += &format!("{k}: \"{safe}\"\n");
        }
        s
    }

    /// Writes `station.yaml` atomically ([`crate::io::atomic`]: temporary file, fsync,
    /// rename).
    pub fn save(&self, path: &Path) -> Result<(), CameraError> {
        crate::io::atomic::write(path, self.to_yaml_string())
            .map_err(|e| ferr(&path.display().to_string(), e.cause()))
    }
}

/// One `!!opencv-matrix` node with doubles printed round-trip exact.
pub fn mat_node(key: &str, rows: usize, cols: usize, data: &[f64]) -> String {
    let nums: Vec<String> = data.iter().map(|v| fmt_double(*v)).collect();
    format!(
        "{key}: !!opencv-matrix\n   rows: {rows}\n   cols: {cols}\n   dt: d\n   data: [ {} ]\n",
        nums.join(", ")
    )
}

/// Shortest round-trip representation that YAML/OpenCV read as a double.
fn fmt_double(v: f64) -> String {
    let s = format!("{v:?}");
    if s.contains('.') || s.contains('e') || s.contains("inf") || s.contains("NaN") {
        s
    } else {
        format!("{s}.")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trip_is_exact() {
        let mut s = StationCalibration::nominal(720, 1280, 1100.5, 3.1, 1.2, 1.0);
        s.front.intrinsics.dist = [-0.1, 0.02, 0.001, -0.002, 0.003];
        s.extra.push(("rms_px".into(), "0.21".into()));
        let text = s.to_yaml_string();
        assert!(text.starts_with("%YAML:1.0\n---\n"));
        let r = StationCalibration::from_yaml_str(&text, "t.yaml").unwrap();
        assert_eq!(r, s);
    }

    #[test]
    fn reads_opencv_multiline_matrices() {
        let text = "%YAML:1.0\n---\nfront_image_width: 1280\nfront_image_height: 720\nfront_camera_matrix: !!opencv-matrix\n   rows: 3\n   cols: 3\n   dt: d\n   data: [ 1.1e+03, 0., 6.4e+02, 0.,\n       1.1e+03, 3.6e+02, 0., 0., 1. ]\nfront_distortion_coefficients: !!opencv-matrix\n   rows: 1\n   cols: 5\n   dt: d\n   data: [ 0., 0., 0., 0., 0. ]\nfront_rotation: !!opencv-matrix\n   rows: 3\n   cols: 3\n   dt: d\n   data: [ 1., 0., 0., 0., 1., 0., 0., 0., 1. ]\nfront_translation: !!opencv-matrix\n   rows: 3\n   cols: 1\n   dt: d\n   data: [ 0., 0., 3. ]\nboard: \"9x6\"\nnested:\n   a: 1\n";
        let nodes = parse(text, "x").unwrap();
        assert!(matches!(
            nodes.get("front_camera_matrix"),
            Some(Node::Matrix {
                rows: 3,
                cols: 3,
                ..
            })
        ));
        let e = StationCalibration::from_yaml_str(text, "x.yaml")
            .unwrap_err()
            .to_string();
        assert!(e.contains("side_camera_matrix"), "{e}");
    }

    #[test]
    fn garbage_is_an_error() {
        for t in ["", "hello", "%YAML:1.0\nfront_camera_matrix: !!opencv-matrix\n   rows: 3\n   cols: 3\n   data: [1, 2]\n", "%YAML:1.0\n---\nfront_image_width: -3\n"] {
            assert!(StationCalibration::from_yaml_str(t, "bad.yaml").is_err());
        }
    }
}
