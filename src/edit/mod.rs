//! Handle edits on the fitted avatar (issue 23; Kazmi et al.'s anchors, SAniHead's
//! handles): the operator drags a point of the surface, the surface within a reach of it
//! follows smoothly ([`field`]: a bi-Laplacian bump over the surface distance), the rest
//! stays where the fit put it, the measurements are taken again on the edited mesh, every
//! edit is listed and can be undone exactly, and the report says which values were
//! edited by hand, where and by how much ([`AvatarEditor::mark_report`]).
//!
//! Metres and the station frame, like the avatar; measurement changes in millimetres.

pub mod cli;
pub mod field;

use crate::measure::{Measurements, Measurer};
use crate::mesh::TriMesh;
use field::{Adjacency, FieldError};
use glam::DVec3;
use serde_json::{json, Map, Value};

/// Default reach of a handle along the surface (metres): about a hand's breadth each way.
pub const DEFAULT_REACH_M: f64 = 0.15;
/// A measurement changed by an edit when it moved more than this (mm).
const CHANGED_MM: f64 = 0.05;
/// Longest drag the editor takes (metres): a correction, not a new body.
pub const MAX_OFFSET_M: f64 = 0.25;

/// Why an edit was refused (the avatar is left as it was).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum EditError {
    #[error(transparent)]
    Field(#[from] FieldError),
    #[error("no handle is being dragged")]
    NoDrag,
    #[error("a drag of {0:.0} mm is longer than an edit may be ({max:.0} mm)", max = MAX_OFFSET_M * 1e3)]
    TooFar(f64),
    #[error("the offset is not a finite vector")]
    BadOffset,
    #[error("the edited avatar could not be measured: {0}")]
    Measure(String),
}

/// One edit: which vertex, from where, by how much, and what it changed.
#[derive(Debug, Clone, PartialEq)]
pub struct HandleEdit {
    pub vertex: u32,
    /// Where the handle was before the edit (metres, station frame).
    pub at_m: DVec3,
    pub offset_m: DVec3,
    pub reach_m: f64,
    /// The level the handle is nearest to ("waist", "thigh left", ...).
    pub near: String,
    /// Vertices the edit moved (the handle included).
    pub moved_vertices: usize,
    /// Measurement changes of this edit (report keys, mm), those over 0.05 mm.
    pub changes_mm: Vec<(String, f64)>,
}

impl HandleEdit {
    /// The edit as listed in `report.json` `hand_edits`.
    pub fn to_json(&self) -> Value {
        let mm = |v: DVec3| [v.x, v.y, v.z].map(|c| (c * 1e4).round() / 10.0);
        let changes: Map<String, Value> = self
            .changes_mm
            .iter()
            .map(|(k, v)| (k.clone(), json!((v * 10.0).round() / 10.0)))
            .collect();
        let at_m = [self.at_m.x, self.at_m.y, self.at_m.z].map(|c| (c * 1e6).round() / 1e6);
        json!({
            "vertex": self.vertex,
            "at_m": at_m,
            "near": self.near,
            "offset_mm": mm(self.offset_m),
            // Unrounded, so that the edit can be made again exactly (`fitstation edit`).
            "offset_m": [self.offset_m.x, self.offset_m.y, self.offset_m.z],
            "reach_m": self.reach_m,
            "distance_mm": (self.offset_m.length() * 1e4).round() / 10.0,
            "reach_mm": (self.reach_m * 1e4).round() / 10.0,
            "moved_vertices": self.moved_vertices,
            "changes_mm": changes,
        })
    }
}

struct Applied {
    edit: HandleEdit,
    /// Positions the edit overwrote, to put back on undo.
    before: Vec<(u32, DVec3)>,
}

struct Drag {
    handle: u32,
    reach_m: f64,
    field: Vec<(u32, f64)>,
    before: Vec<DVec3>,
    offset_m: DVec3,
    measured_before: Measurements,
}

/// The avatar being edited, its edits and its measurements.
pub struct AvatarEditor {
    mesh: TriMesh,
    adjacency: Adjacency,
    measurer: Measurer,
    fit: Measurements,
    now: Measurements,
    edits: Vec<Applied>,
    drag: Option<Drag>,
}

impl AvatarEditor {
    /// Starts editing a fitted avatar (measures it once).
    ///
    /// # Errors
    /// The avatar cannot be measured.
    pub fn new(mesh: TriMesh) -> Result<AvatarEditor, EditError> {
        let mut measurer = Measurer::new();
        let fit = measurer
            .measure(&mesh)
            .map_err(|e| EditError::Measure(e.to_string()))?;
        Ok(AvatarEditor {
            adjacency: Adjacency::new(&mesh),
            now: fit.clone(),
            fit,
            mesh,
            measurer,
            edits: Vec::new(),
            drag: None,
        })
    }

    /// The avatar with the edits so far (and the drag under way).
    pub fn mesh(&self) -> &TriMesh {
        &self.mesh
    }

    /// The measurements of the fitted avatar, before any edit.
    pub fn fit_measurements(&self) -> &Measurements {
        &self.fit
    }

    /// The measurements of [`Self::mesh`].
    pub fn measurements(&self) -> &Measurements {
        &self.now
    }

    /// The edits in the order they were made.
    pub fn edits(&self) -> impl ExactSizeIterator<Item = &HandleEdit> {
        self.edits.iter().map(|a| &a.edit)
    }

    /// A drag is under way.
    pub fn dragging(&self) -> bool {
        self.drag.is_some()
    }

    /// The vertex nearest to a point (metres).
    pub fn nearest_vertex(&self, p: DVec3) -> Option<u32> {
        self.mesh
            .positions
            .iter()
            .enumerate()
            .min_by(|a, b| a.1.distance_squared(p).total_cmp(&b.1.distance_squared(p)))
            .map(|(i, _)| i as u32)
    }

    /// Picks up `vertex` as a handle with the given reach along the surface.
    ///
    /// # Errors
    /// No such vertex, a reach that is not a positive length, or a field that could not
    /// be solved. A drag under way is cancelled first.
    pub fn begin_drag(&mut self, vertex: u32, reach_m: f64) -> Result<(), EditError> {
        self.cancel_drag();
        let field = field::influence(&self.mesh, &self.adjacency, vertex, reach_m)?;
        let before = field
            .iter()
            .map(|&(v, _)| self.mesh.positions[v as usize])
            .collect();
        self.drag = Some(Drag {
            handle: vertex,
            reach_m,
            field,
            before,
            offset_m: DVec3::ZERO,
            measured_before: self.now.clone(),
        });
        Ok(())
    }

    /// Moves the handle under way to `offset_m` from where it was picked up; the surface
    /// follows and the measurements are taken again.
    ///
    /// # Errors
    /// No drag, an offset that is not finite or longer than [`MAX_OFFSET_M`], or an
    /// edited mesh that cannot be measured (the drag stays where it was).
    pub fn drag_to(&mut self, offset_m: DVec3) -> Result<(), EditError> {
        if !offset_m.is_finite() {
            return Err(EditError::BadOffset);
        }
        if offset_m.length() > MAX_OFFSET_M {
            return Err(EditError::TooFar(offset_m.length() * 1e3));
        }
        let drag = self.drag.as_mut().ok_or(EditError::NoDrag)?;
        place(&mut self.mesh, drag, offset_m);
        match self.measurer.measure(&self.mesh) {
            Ok(m) => {
                drag.offset_m = offset_m;
                self.now = m;
                Ok(())
            }
            Err(e) => {
                let back = drag.offset_m;
                place(&mut self.mesh, drag, back);
                Err(EditError::Measure(e.to_string()))
            }
        }
    }

    /// Lets go of the handle: a drag that moved it becomes an edit (returned).
    pub fn end_drag(&mut self) -> Option<&HandleEdit> {
        let drag = self.drag.take()?;
        if drag.offset_m == DVec3::ZERO {
            return None;
        }
        let changes_mm = changes(&drag.measured_before, &self.now);
        let at_m = drag.before[0];
        let edit = HandleEdit {
            vertex: drag.handle,
            at_m,
            offset_m: drag.offset_m,
            reach_m: drag.reach_m,
            near: nearest_level(&self.fit, at_m),
            moved_vertices: drag.field.len(),
            changes_mm,
        };
        let before = drag
            .field
            .iter()
            .map(|&(v, _)| v)
            .zip(drag.before)
            .collect();
        self.edits.push(Applied { edit, before });
        self.edits.last().map(|a| &a.edit)
    }

    /// Puts the handle under way back where it was picked up.
    pub fn cancel_drag(&mut self) {
        if let Some(drag) = self.drag.take() {
            for (&(v, _), p) in drag.field.iter().zip(&drag.before) {
                self.mesh.positions[v as usize] = *p;
            }
            self.now = drag.measured_before;
        }
    }

    /// One whole edit: pick up `vertex`, move it by `offset_m`, let go.
    ///
    /// # Errors
    /// As [`Self::begin_drag`] and [`Self::drag_to`]; the avatar is left as it was.
    pub fn apply(
        &mut self,
        vertex: u32,
        offset_m: DVec3,
        reach_m: f64,
    ) -> Result<&HandleEdit, EditError> {
        self.begin_drag(vertex, reach_m)?;
        if let Err(e) = self.drag_to(offset_m) {
            self.cancel_drag();
            return Err(e);
        }
        self.end_drag().ok_or(EditError::BadOffset)
    }

    /// Takes the last edit back: the vertices it moved return to their exact positions.
    pub fn undo(&mut self) -> Option<HandleEdit> {
        self.cancel_drag();
        let a = self.edits.pop()?;
        for (v, p) in &a.before {
            self.mesh.positions[*v as usize] = *p;
        }
        // The measurements of the mesh as it now is (the same as before the edit).
        if let Ok(m) = self.measurer.measure(&self.mesh) {
            self.now = m;
        }
        Some(a.edit)
    }

    /// Change of each report value from the fitted avatar to the edited one (mm).
    pub fn changes_mm(&self) -> Vec<(String, f64)> {
        changes(&self.fit, &self.now)
    }

    /// Marks a `report.json` as edited by hand: `measurements_mm` gets each value's
    /// change from the edits (the values stay the fit's where no edit reached), the fit's
    /// own values move to `measurements_fit_mm`, `edited_by_hand` lists the changed keys
    /// and `hand_edits` the edits. Without edits the report is left as it is.
    pub fn mark_report(&self, report: &mut Value) {
        if self.edits.is_empty() {
            return;
        }
        let Some(obj) = report.as_object_mut() else {
            return;
        };
        let fitted = obj
            .get("measurements_fit_mm")
            .or_else(|| obj.get("measurements_mm"))
            .cloned()
            .unwrap_or_else(|| json!({}));
        let mut edited = fitted.clone();
        let mut keys = Vec::new();
        for (k, d) in self.changes_mm() {
            if let Some(v) = edited.get_mut(&k) {
                if let Some(x) = v.as_f64() {
                    *v = json!(((x + d) * 10.0).round() / 10.0);
                    keys.push(k);
                }
            }
        }
        obj.insert("measurements_fit_mm".into(), fitted);
        obj.insert("measurements_mm".into(), edited);
        obj.insert("edited_by_hand".into(), json!(keys));
        obj.insert(
            "hand_edits".into(),
            Value::Array(self.edits().map(HandleEdit::to_json).collect()),
        );
    }
}

/// Sets the drag's vertices to where `offset` puts them.
fn place(mesh: &mut TriMesh, drag: &Drag, offset: DVec3) {
    for (&(v, w), p) in drag.field.iter().zip(&drag.before) {
        mesh.positions[v as usize] = *p + w * offset;
    }
}

/// Report values that differ between two measurements (after - before, mm).
fn changes(before: &Measurements, after: &Measurements) -> Vec<(String, f64)> {
    let (b, a) = (before.to_report_map(), after.to_report_map());
    b.iter()
        .filter_map(|(k, vb)| {
            let d = a.get(k)?.as_f64()? - vb.as_f64()?;
            (d.abs() > CHANGED_MM).then(|| (k.clone(), d))
        })
        .collect()
}

/// The measurement level nearest to a point, in words.
fn nearest_level(m: &Measurements, p: DVec3) -> String {
    let l = &m.levels;
    let thigh = if p.x >= l.axis_x_m {
        ("thigh left", l.thigh_left_m)
    } else {
        ("thigh right", l.thigh_right_m)
    };
    if p.y > l.armpit_m + 0.05 {
        return "above the chest".into();
    }
    if p.y < thigh.1 - 0.1 {
        return "below the thighs".into();
    }
    [
        ("chest", l.chest_m),
        ("waist", l.waist_m),
        ("hip", l.hip_m),
        thigh,
    ]
    .into_iter()
    .min_by(|a, b| (a.1 - p.y).abs().total_cmp(&(b.1 - p.y).abs()))
    .map_or_else(String::new, |(name, _)| name.to_string())
}
