//! The operator's hand edits of the avatar on screen (issue 23 item 2): with "Edit avatar"
//! on, a primary-button press on the avatar view picks the vertex under the pointer, a
//! drag moves it in the plane through it facing the eye, and [`crate::edit::AvatarEditor`]
//! makes the surface follow and measures again, every frame of the drag; the secondary
//! button still turns the view. The avatar is frozen into the editor at the first press:
//! while edits exist or a drag is under way, new frames do not replace it (the screen
//! says so), the measurements panel shows the edited values and the operator's exports
//! carry the edits ([`crate::edit::AvatarEditor::mark_report`]).
//!
//! Picking and unprojection are pure functions ([`pick_vertex`], [`unproject_delta`]):
//! pointer positions are points relative to the avatar view's top-left corner (+y
//! down), the view-projection is the orbit camera's (`OrbitCamera::view_proj`, clip from
//! station, wgpu depth 0..1), vertices are in the station frame (metres).

use super::*;
use crate::edit::{AvatarEditor, DEFAULT_REACH_M};
use glam::{DMat4, DVec3, DVec4, Mat4};
use serde_json::{json, Value};

/// A vertex is picked when it is seen within this many points of the pointer.
pub const PICK_RADIUS_PT: f32 = 8.0;
/// Range of the reach slider (millimetres along the surface).
const REACH_RANGE_MM: std::ops::RangeInclusive<f64> = 30.0..=400.0;

/// Where a point of the station is seen in a view of `size_pt` points: its position from
/// the view's top-left corner (points) and its depth (the clip `w`, metres along the
/// view direction); `None` behind the eye or outside the depth range.
pub fn project(view_proj: &DMat4, size_pt: Vec2, p: DVec3) -> Option<(Vec2, f64)> {
    let c = *view_proj * p.extend(1.0);
    if c.w <= f64::from(super::orbit::NEAR_M) || c.z < 0.0 || c.z > c.w {
        return None;
    }
    let (x, y) = (c.x / c.w, c.y / c.w);
    let at = Vec2::new(
        ((x + 1.0) * 0.5 * f64::from(size_pt.x)) as f32,
        ((1.0 - y) * 0.5 * f64::from(size_pt.y)) as f32,
    );
    Some((at, c.w))
}

/// The vertex under the pointer: among the vertices seen within `radius_pt` of
/// `pointer_pt`, the one nearest to the eye (so a vertex hidden behind the surface, which
/// always has a nearer one of that surface beside it on screen, is not picked).
pub fn pick_vertex(
    positions: &[DVec3],
    view_proj: Mat4,
    size_pt: Vec2,
    pointer_pt: Vec2,
    radius_pt: f32,
) -> Option<u32> {
    nearest_seen(
        positions,
        &view_proj.as_dmat4(),
        size_pt,
        pointer_pt,
        radius_pt,
        f64::INFINITY,
    )
}

/// Depth beyond the surface under the pointer (metres) up to which a vertex within the
/// pick radius still counts as on that surface (it may sit on a slope beside it).
const SURFACE_DEPTH_SLACK_M: f64 = 0.03;

/// [`pick_vertex`] on a mesh, safe when the view is zoomed in so far that the surface
/// under the pointer has no vertex within the radius: the pointer's ray is cast on the
/// triangles, vertices deeper than the surface it hits are left out, and without one
/// left the hit triangle's corner nearest to the hit is taken.
pub fn pick_on_mesh(
    mesh: &crate::mesh::TriMesh,
    view_proj: Mat4,
    size_pt: Vec2,
    pointer_pt: Vec2,
    radius_pt: f32,
) -> Option<u32> {
    let vp = view_proj.as_dmat4();
    let Some((tri, hit)) = ray_hit(mesh, &vp, size_pt, pointer_pt) else {
        return pick_vertex(&mesh.positions, view_proj, size_pt, pointer_pt, radius_pt);
    };
    let max_depth = (vp * hit.extend(1.0)).w + SURFACE_DEPTH_SLACK_M;
    nearest_seen(
        &mesh.positions,
        &vp,
        size_pt,
        pointer_pt,
        radius_pt,
        max_depth,
    )
    .or_else(|| {
        tri.iter().copied().min_by(|a, b| {
            let d = |v: u32| mesh.positions[v as usize].distance_squared(hit);
            d(*a).total_cmp(&d(*b))
        })
    })
}

/// Among the vertices seen within `radius_pt` of the pointer and no deeper than
/// `max_depth` (clip w, metres), the one nearest to the eye.
fn nearest_seen(
    positions: &[DVec3],
    vp: &DMat4,
    size_pt: Vec2,
    pointer_pt: Vec2,
    radius_pt: f32,
    max_depth: f64,
) -> Option<u32> {
    let r2 = radius_pt * radius_pt;
    positions
        .iter()
        .enumerate()
        .filter_map(|(i, p)| {
            let (at, depth) = project(vp, size_pt, *p)?;
            ((at - pointer_pt).length_sq() <= r2 && depth <= max_depth).then_some((i as u32, depth))
        })
        .min_by(|a, b| a.1.total_cmp(&b.1))
        .map(|(i, _)| i)
}

/// The first triangle the pointer's ray meets and where (Moller-Trumbore, both faces).
fn ray_hit(
    mesh: &crate::mesh::TriMesh,
    vp: &DMat4,
    size_pt: Vec2,
    pointer_pt: Vec2,
) -> Option<([u32; 3], DVec3)> {
    let ndc_x = 2.0 * f64::from(pointer_pt.x) / f64::from(size_pt.x) - 1.0;
    let ndc_y = 1.0 - 2.0 * f64::from(pointer_pt.y) / f64::from(size_pt.y);
    let inv = vp.inverse();
    let at = |z: f64| {
        let p = inv * DVec4::new(ndc_x, ndc_y, z, 1.0);
        p.truncate() / p.w
    };
    let (origin, far) = (at(0.0), at(1.0));
    let dir = far - origin;
    let n = mesh.positions.len();
    let mut best: Option<(f64, [u32; 3])> = None;
    for t in &mesh.triangles {
        if t.iter().any(|&i| i as usize >= n) {
            continue;
        }
        let [a, b, c] = t.map(|i| mesh.positions[i as usize]);
        let (e1, e2) = (b - a, c - a);
        let p = dir.cross(e2);
        let det = e1.dot(p);
        if det.abs() < 1e-18 {
            continue;
        }
        let s = origin - a;
        let u = s.dot(p) / det;
        let q = s.cross(e1);
        let v = dir.dot(q) / det;
        let along = e2.dot(q) / det;
        let inside = u >= 0.0 && v >= 0.0 && u + v <= 1.0 && along > 0.0;
        if inside && best.is_none_or(|(b, _)| along < b) {
            best = Some((along, *t));
        }
    }
    best.map(|(along, t)| (t, origin + dir * along))
}

/// The move in the station (metres) that carries `anchor_m` by `delta_pt` points on
/// screen while keeping its depth: the pointer's move unprojected through the inverse
/// view-projection in the plane through the anchor facing the eye.
pub fn unproject_delta(
    view_proj: Mat4,
    size_pt: Vec2,
    anchor_m: DVec3,
    delta_pt: Vec2,
) -> Option<DVec3> {
    let vp = view_proj.as_dmat4();
    let c = vp * anchor_m.extend(1.0);
    if c.w <= f64::from(super::orbit::NEAR_M) || size_pt.x <= 0.0 || size_pt.y <= 0.0 {
        return None;
    }
    let ndc = c.truncate() / c.w;
    let moved = DVec4::new(
        ndc.x + 2.0 * f64::from(delta_pt.x) / f64::from(size_pt.x),
        ndc.y - 2.0 * f64::from(delta_pt.y) / f64::from(size_pt.y),
        ndc.z,
        1.0,
    );
    let back = vp.inverse() * moved;
    let p = back.truncate() / back.w;
    p.is_finite().then(|| p - anchor_m)
}

/// Measurements as edited, and each value's change from the edits (report key, mm).
pub(super) type EditedValues = (Vec<MeasurementValue>, Vec<(String, f64)>);

/// The avatar frozen for editing and what it was frozen from.
struct Session {
    editor: AvatarEditor,
    /// The station's avatar the editor started from (compared for an exact undo).
    fitted: Arc<crate::mesh::TriMesh>,
    /// The edited avatar as drawn (a new one after each change).
    shown: Arc<crate::mesh::TriMesh>,
    /// The station's measurements when the avatar was frozen (the "fit" values).
    fit_values: Vec<MeasurementValue>,
}

/// A drag under way on screen.
struct ScreenDrag {
    anchor_m: DVec3,
    view_proj: Mat4,
    size_pt: Vec2,
    press_pt: Pos2,
    /// The pointer's position when the handle was last moved.
    last_pt: Pos2,
    /// A move of this drag was refused (said once per drag, not every frame).
    refused: bool,
}

/// What the screen's edits did, for `--ui-edits-out` (the window test reads it); kept
/// only when asked for (a kiosk runs for days).
#[derive(Default)]
struct EditRecord {
    on: bool,
    picks: Vec<Value>,
    edits: Vec<Value>,
    undos: Vec<Value>,
    errors: Vec<String>,
}

impl EditRecord {
    fn add(&mut self, list: fn(&mut EditRecord) -> &mut Vec<Value>, entry: Value) {
        if self.on {
            list(self).push(entry);
        }
    }
}

/// Drag step durations kept for the record (the newest).
const STEP_SAMPLES: usize = 1000;

/// The screen's edit state: the toggle, the reach, the frozen avatar and the drag.
pub(super) struct EditTool {
    /// "Edit avatar" is on (operator mode only).
    pub on: bool,
    pub reach_mm: f64,
    session: Option<Session>,
    drag: Option<ScreenDrag>,
    /// Duration of each drag step (move, measure, copy for the screen), milliseconds.
    step_ms: Vec<f64>,
    record: EditRecord,
    /// Where the section's buttons were drawn last (screen points), for scripted clicks.
    pub buttons: EditButtons,
}

/// Where the edit section's buttons are on screen (points); `None`: not drawn.
#[derive(Debug, Clone, Copy, Default)]
pub(super) struct EditButtons {
    pub toggle: Option<Rect>,
    pub undo: Option<Rect>,
    pub done: Option<Rect>,
}

impl Default for EditTool {
    fn default() -> Self {
        EditTool {
            on: false,
            reach_mm: DEFAULT_REACH_M * 1e3,
            session: None,
            drag: None,
            step_ms: Vec::new(),
            record: EditRecord::default(),
            buttons: EditButtons::default(),
        }
    }
}

impl EditTool {
    /// Edits exist or a drag is under way: the edited avatar stays on screen.
    pub fn frozen(&self) -> bool {
        self.session
            .as_ref()
            .is_some_and(|s| s.editor.edits().len() > 0 || s.editor.dragging())
    }

    /// The edited avatar to draw while [`Self::frozen`].
    pub fn shown_mesh(&self) -> Option<Arc<crate::mesh::TriMesh>> {
        self.session
            .as_ref()
            .filter(|_| self.frozen())
            .map(|s| s.shown.clone())
    }

    /// The editor while [`Self::frozen`].
    pub fn editor(&self) -> Option<&AvatarEditor> {
        self.session
            .as_ref()
            .filter(|_| self.frozen())
            .map(|s| &s.editor)
    }

    /// The line over the avatar view saying what holds it.
    pub fn view_note(&self, operator: bool) -> Option<&'static str> {
        if self.frozen() {
            Some("Edited by hand:\nnew frames do not replace it")
        } else if self.on && operator {
            Some("Edit avatar: drag a point of the body (right button turns)")
        } else {
            None
        }
    }

    /// Keeps a record of the edits for [`Self::record_json`] (window tests).
    pub fn keep_record(&mut self) {
        self.record.on = true;
    }

    pub fn dragging(&self) -> bool {
        self.drag.is_some()
    }

    /// Picks the vertex under `pointer` (screen points) on `shown` as seen by `orbit` in
    /// `rect`, freezing the avatar first when no edit holds it; returns the vertex.
    ///
    /// # Errors
    /// No avatar on screen, or one the editor cannot measure or solve around the vertex.
    pub fn press(
        &mut self,
        shown: Option<Arc<crate::mesh::TriMesh>>,
        fit_values: &[MeasurementValue],
        orbit: &OrbitCamera,
        rect: Rect,
        pointer: Pos2,
    ) -> Result<Option<u32>, String> {
        let shown = shown.ok_or("no avatar on screen to edit")?;
        let t0 = Instant::now();
        let keep = self.frozen()
            || self
                .session
                .as_ref()
                .is_some_and(|s| Arc::ptr_eq(&s.fitted, &shown));
        if !keep {
            let editor = AvatarEditor::new((*shown).clone()).map_err(|e| e.to_string())?;
            // Without the station's (smoothed) values, the avatar's own measurements.
            let fit_values = if fit_values.is_empty() {
                own_values(&editor)
            } else {
                fit_values.to_vec()
            };
            self.session = Some(Session {
                editor,
                fitted: shown.clone(),
                shown,
                fit_values,
            });
        }
        let Some(s) = self.session.as_mut() else {
            return Ok(None);
        };
        let size_pt = rect.size();
        let view_proj = orbit.view_proj(size_pt.x / size_pt.y.max(1.0));
        let pointer_pt = pointer - rect.min;
        let Some(v) = pick_on_mesh(&s.shown, view_proj, size_pt, pointer_pt, PICK_RADIUS_PT) else {
            return Ok(None);
        };
        s.editor
            .begin_drag(v, self.reach_mm / 1e3)
            .map_err(|e| e.to_string())?;
        let anchor_m = s.shown.positions[v as usize];
        self.drag = Some(ScreenDrag {
            anchor_m,
            view_proj,
            size_pt,
            press_pt: pointer,
            last_pt: pointer,
            refused: false,
        });
        self.record.add(
            |r| &mut r.picks,
            json!({
                "vertex": v,
                "at_m": [anchor_m.x, anchor_m.y, anchor_m.z],
                "pointer_pt": [pointer_pt.x, pointer_pt.y],
                // Freezing (when it did), picking and solving the handle's field.
                "press_ms": t0.elapsed().as_secs_f64() * 1e3,
            }),
        );
        Ok(Some(v))
    }

    /// Moves the handle under way to where the pointer (screen points) now is.
    ///
    /// # Errors
    /// The editor refused the move (too far, not measurable): the handle stays. Said
    /// once per drag.
    pub fn drag_to(&mut self, pointer: Pos2) -> Result<(), String> {
        let (Some(d), Some(s)) = (self.drag.as_mut(), self.session.as_mut()) else {
            return Ok(());
        };
        if pointer == d.last_pt {
            return Ok(());
        }
        let t0 = Instant::now();
        let moved = unproject_delta(d.view_proj, d.size_pt, d.anchor_m, pointer - d.press_pt)
            .ok_or_else(|| "the pointer cannot be unprojected".to_string())
            .and_then(|offset| s.editor.drag_to(offset).map_err(|e| e.to_string()));
        if let Err(e) = moved {
            let first = !d.refused;
            d.refused = true;
            return if first { Err(e) } else { Ok(()) };
        }
        d.last_pt = pointer;
        s.shown = Arc::new(s.editor.mesh().clone());
        if self.step_ms.len() >= STEP_SAMPLES {
            self.step_ms.remove(0);
        }
        self.step_ms.push(t0.elapsed().as_secs_f64() * 1e3);
        Ok(())
    }

    /// Lets go of the handle; the edit made, in words, for the log.
    pub fn release(&mut self) -> Option<String> {
        let d = self.drag.take()?;
        let s = self.session.as_mut()?;
        let edit = s.editor.end_drag()?;
        let line = edit_line(edit);
        let mut listed = edit.to_json();
        // The pointer's move and the metres per point at the handle's depth.
        let drag_pt = d.last_pt - d.press_pt;
        let m_per_pt =
            unproject_delta(d.view_proj, d.size_pt, d.anchor_m, Vec2::X).map(|v| v.length());
        if let Some(o) = listed.as_object_mut() {
            o.insert("drag_pt".into(), json!([drag_pt.x, drag_pt.y]));
            o.insert("m_per_pt".into(), json!(m_per_pt));
        }
        self.record.add(|r| &mut r.edits, listed);
        s.shown = Arc::new(s.editor.mesh().clone());
        Some(line)
    }

    /// Takes the last edit back; said in words for the log.
    pub fn undo(&mut self) -> Option<String> {
        self.drag = None;
        let s = self.session.as_mut()?;
        let edit = s.editor.undo()?;
        let exact = s.editor.mesh().positions == s.fitted.positions;
        s.shown = Arc::new(s.editor.mesh().clone());
        self.record.add(
            |r| &mut r.undos,
            json!({
                "vertex": edit.vertex,
                "edits_left": s.editor.edits().len(),
                "mesh_equals_fit": exact,
            }),
        );
        Some(format!("undid the edit at the {}", edit.near))
    }

    /// Forgets the edits: the live avatar comes back.
    pub fn discard(&mut self) {
        self.drag = None;
        self.session = None;
    }

    /// Notes a refused press or drag (for the log and the record).
    pub fn note_error(&mut self, e: &str) -> String {
        if self.record.on {
            self.record.errors.push(e.to_string());
        }
        format!("edit: {e}")
    }

    /// While frozen: the measurements as edited (the frozen fit's values plus each
    /// value's change from the edits) and the changes themselves (report keys, mm).
    pub fn edited_measurements(&self) -> Option<EditedValues> {
        let s = self.session.as_ref().filter(|_| self.frozen())?;
        let changes = s.editor.changes_mm();
        let values = s
            .fit_values
            .iter()
            .map(|m| {
                let d = changes
                    .iter()
                    .find(|(k, _)| *k == m.name)
                    .map_or(0.0, |c| c.1);
                MeasurementValue {
                    value_mm: m.value_mm + d,
                    ..m.clone()
                }
            })
            .collect();
        Some((values, changes))
    }

    /// The frozen fit's measurements (what an export starts from while frozen).
    pub fn fit_values(&self) -> Option<&[MeasurementValue]> {
        self.session
            .as_ref()
            .filter(|_| self.frozen())
            .map(|s| &s.fit_values[..])
    }

    /// What the edits did, for `--ui-edits-out`: picks, edits (vertex, offset, changes),
    /// undos (whether the mesh equals the fitted one again), errors, drag step times.
    pub fn record_json(&self) -> Value {
        let mut ms = self.step_ms.clone();
        ms.sort_by(f64::total_cmp);
        let median = ms.get(ms.len() / 2).copied();
        json!({
            "picks": self.record.picks,
            "edits": self.record.edits,
            "undos": self.record.undos,
            "errors": self.record.errors,
            "edits_now": self.session.as_ref().map_or(0, |s| s.editor.edits().len()),
            "edit_mode_on": self.on,
            "drag_steps": ms.len(),
            "drag_step_ms_median": median,
            "drag_step_ms_max": ms.last(),
        })
    }

    /// The operator panel's section: the toggle, what is frozen, the reach, the edits,
    /// Undo, Discard and Done. Returns lines for the operator's log.
    pub fn section_ui(&mut self, ui: &mut egui::Ui) -> Vec<String> {
        let mut log = Vec::new();
        self.buttons = EditButtons {
            toggle: Some(ui.checkbox(&mut self.on, "Edit avatar").rect),
            ..EditButtons::default()
        };
        if !self.on && !self.frozen() {
            ui.label(
                RichText::new("Drag a point of the avatar to correct the fit by hand.").small(),
            );
            return log;
        }
        let n = self.session.as_ref().map_or(0, |s| s.editor.edits().len());
        let state = if self.frozen() {
            format!("Avatar frozen with {n} hand edit(s): new frames do not replace it.")
        } else {
            "Press and drag on the avatar (right button turns the view); the live avatar is frozen at the first press.".into()
        };
        ui.label(RichText::new(state).color(Color32::from_rgb(150, 200, 255)));
        ui.horizontal(|ui| {
            ui.label("reach");
            ui.add(egui::Slider::new(&mut self.reach_mm, REACH_RANGE_MM).suffix(" mm"));
        });
        if let Some(s) = &self.session {
            for e in s.editor.edits() {
                ui.label(RichText::new(edit_line(e)).small());
            }
        }
        ui.horizontal(|ui| {
            let undo = ui.add_enabled(n > 0, egui::Button::new("Undo"));
            self.buttons.undo = Some(undo.rect);
            if undo.clicked() {
                log.extend(self.undo());
            }
            if ui
                .add_enabled(n > 0, egui::Button::new("Discard edits"))
                .clicked()
            {
                self.discard();
                log.push("hand edits discarded: the live avatar is back".into());
            }
            if self.on {
                let done = ui.button("Done");
                self.buttons.done = Some(done.rect);
                if done.clicked() {
                    self.on = false;
                }
            }
        });
        log
    }
}

/// The fitted avatar's own measurements as the station's values (no spread, no `±`).
fn own_values(editor: &AvatarEditor) -> Vec<MeasurementValue> {
    let map = editor.fit_measurements().to_report_map();
    crate::station::MEASUREMENT_KEYS
        .iter()
        .filter_map(|k| {
            Some(MeasurementValue {
                name: k.to_string(),
                value_mm: map.get(*k)?.as_f64()?,
                stability_mm: 0.0,
                uncertainty_mm: f64::INFINITY,
                uncertain: false,
            })
        })
        .collect()
}

/// An edit in words: "waist: 20.0 mm, waist_girth +15.6 mm".
pub fn edit_line(e: &crate::edit::HandleEdit) -> String {
    let mut s = format!("{}: {:.1} mm", e.near, e.offset_m.length() * 1e3);
    for (k, d) in &e.changes_mm {
        s.push_str(&format!(", {k} {d:+.1} mm"));
    }
    s
}

impl StationApp {
    /// Primary-button presses and drags over the avatar view while "Edit avatar" is on.
    pub(super) fn edit_input(&mut self, ui: &egui::Ui, resp: &egui::Response, rect: Rect) {
        use egui::PointerButton::Primary;
        let (origin, latest) = ui.input(|i| (i.pointer.press_origin(), i.pointer.latest_pos()));
        if resp.drag_started_by(Primary) {
            let fits = self
                .current
                .as_ref()
                .map(|s| s.measurements.clone())
                .unwrap_or_default();
            let shown = self.shown_avatar.clone();
            match origin.map(|p| self.edit.press(shown, &fits, &self.orbit, rect, p)) {
                Some(Ok(Some(v))) => self.log(format!("edit: picked vertex {v}")),
                Some(Ok(None)) | None => self.log("edit: no avatar under the pointer".into()),
                Some(Err(e)) => {
                    let line = self.edit.note_error(&e);
                    self.log(line);
                }
            }
        }
        if !self.edit.dragging() {
            return;
        }
        if resp.dragged_by(Primary) || resp.drag_stopped() {
            if let Some(p) = latest {
                if let Err(e) = self.edit.drag_to(p) {
                    let line = self.edit.note_error(&e);
                    self.log(line);
                }
            }
            ui.ctx().request_repaint();
        }
        if resp.drag_stopped() || !ui.input(|i| i.pointer.primary_down()) {
            if let Some(line) = self.edit.release() {
                self.log(format!("hand edit {line}"));
            }
        }
    }

    /// The avatar to draw while edits hold it: the edited one (uploaded as a new avatar
    /// when it changed).
    pub(super) fn show_edited(
        &mut self,
        mesh: Arc<crate::mesh::TriMesh>,
    ) -> Option<Arc<crate::mesh::TriMesh>> {
        if !self
            .shown_avatar
            .as_ref()
            .is_some_and(|m| Arc::ptr_eq(m, &mesh))
        {
            self.shown_avatar = Some(mesh);
            self.avatar_generation += 1;
        }
        self.shown_avatar.clone()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn camera() -> (Mat4, Vec2) {
        let size = Vec2::new(400.0, 600.0);
        let orbit = OrbitCamera::default();
        (orbit.view_proj(size.x / size.y), size)
    }

    #[test]
    fn the_front_vertex_is_picked_not_the_one_behind_it() {
        let (vp, size) = camera();
        let t = OrbitCamera::default().target;
        let target = DVec3::new(t.x as f64, t.y as f64, t.z as f64);
        // Behind first in the list, in front second; both on the line of sight.
        let positions = vec![
            target - DVec3::Z * 0.1,
            target + DVec3::Z * 0.1,
            target + DVec3::X,
        ];
        let centre = size * 0.5;
        assert_eq!(
            pick_vertex(&positions, vp, size, centre, PICK_RADIUS_PT),
            Some(1)
        );
        // A few points off still picks it; far off picks nothing.
        assert_eq!(
            pick_vertex(
                &positions,
                vp,
                size,
                centre + Vec2::new(5.0, 0.0),
                PICK_RADIUS_PT
            ),
            Some(1)
        );
        assert_eq!(
            pick_vertex(
                &positions,
                vp,
                size,
                centre + Vec2::new(0.0, 40.0),
                PICK_RADIUS_PT
            ),
            None
        );
    }

    #[test]
    fn on_a_closed_surface_the_side_facing_the_eye_is_picked() {
        let (vp, size) = camera();
        let t = OrbitCamera::default().target;
        let mut sphere = crate::mesh::shapes::uv_sphere(0.3, 24, 32);
        for p in &mut sphere.positions {
            *p += DVec3::new(t.x as f64, t.y as f64, t.z as f64);
        }
        let eye = OrbitCamera::default().eye();
        let eye = DVec3::new(eye.x as f64, eye.y as f64, eye.z as f64);
        for pointer in [size * 0.5, size * 0.5 + Vec2::new(20.0, -30.0)] {
            let v = pick_vertex(&sphere.positions, vp, size, pointer, PICK_RADIUS_PT)
                .expect("a vertex under the pointer");
            let p = sphere.positions[v as usize];
            // Seen: its outward normal points toward the eye.
            let normal = p - DVec3::new(t.x as f64, t.y as f64, t.z as f64);
            assert!(
                normal.dot(eye - p) > 0.0,
                "picked a hidden vertex {v} at {p:?}"
            );
        }
    }

    #[test]
    fn a_large_triangle_in_front_hides_the_vertex_behind_it() {
        let (vp, size) = camera();
        let t = OrbitCamera::default().target;
        let c = DVec3::new(t.x as f64, t.y as f64, t.z as f64);
        // A quad 1 m wide in front (no corner near the pointer), a lone vertex behind.
        let positions = vec![
            c + DVec3::new(-0.5, -0.5, 0.2),
            c + DVec3::new(0.5, -0.5, 0.2),
            c + DVec3::new(0.5, 0.5, 0.2),
            c + DVec3::new(-0.5, 0.5, 0.2),
            c + DVec3::new(0.0, 0.0, -0.2),
        ];
        let mesh = crate::mesh::TriMesh::new(positions, vec![[0, 1, 2], [0, 2, 3], [4, 4, 4]]);
        let pointer = size * 0.5 + Vec2::new(10.0, -25.0);
        // By the pick radius alone only the hidden vertex is near the pointer ...
        assert_eq!(
            pick_vertex(&mesh.positions, vp, size, pointer, 40.0),
            Some(4)
        );
        // ... the ray finds the quad first and takes its corner nearest to the hit.
        assert_eq!(pick_on_mesh(&mesh, vp, size, pointer, 40.0), Some(2));
        // Beside the quad the radius rule holds.
        assert_eq!(
            pick_on_mesh(&mesh, vp, size, size * 0.5 + Vec2::new(0.0, 350.0), 8.0),
            None
        );
    }

    #[test]
    fn a_pixel_delta_unprojects_to_metres_at_the_vertex_depth() {
        let (vp, size) = camera();
        let orbit = OrbitCamera::default();
        let t = orbit.target;
        let anchor = DVec3::new(t.x as f64, t.y as f64, t.z as f64);
        // At the target the view's height spans 2 d tan(fov / 2) metres.
        let m_per_pt =
            2.0 * orbit.distance_m as f64 * (f64::from(super::super::orbit::FOV_Y_RAD) * 0.5).tan()
                / 600.0;
        let d = unproject_delta(vp, size, anchor, Vec2::new(30.0, -20.0)).expect("delta");
        // The default camera looks from +Z, slightly from above: right is +X, up is
        // about +Y, and the move stays at the anchor's depth.
        assert!((d.x - 30.0 * m_per_pt).abs() < 1e-4, "{d:?} vs {m_per_pt}");
        assert!((d.length() - 36.0555 * m_per_pt).abs() < 1e-4, "{d:?}");
        let eye = orbit.eye();
        let eye = DVec3::new(eye.x as f64, eye.y as f64, eye.z as f64);
        let view_dir = (anchor - eye).normalize();
        assert!(
            d.dot(view_dir).abs() < 1e-6,
            "the move leaves the plane facing the eye"
        );
        // From any side, the moved point lands where the pointer is, at the same depth.
        for preset in [
            ViewPreset::Front,
            ViewPreset::Side,
            ViewPreset::ThreeQuarter,
        ] {
            let mut orbit = OrbitCamera::default();
            orbit.preset(preset);
            let vp = orbit.view_proj(size.x / size.y);
            let off = anchor + DVec3::new(0.05, 0.2, -0.03);
            let d = unproject_delta(vp, size, off, Vec2::new(30.0, -20.0)).expect("delta");
            let (at0, w0) = project(&vp.as_dmat4(), size, off).expect("seen");
            let (at1, w1) = project(&vp.as_dmat4(), size, off + d).expect("seen");
            assert!(
                ((at1 - at0) - Vec2::new(30.0, -20.0)).length() < 1e-3,
                "{preset:?}"
            );
            assert!((w1 - w0).abs() < 1e-6, "{preset:?}: depth {w0} -> {w1}");
        }
    }
}
