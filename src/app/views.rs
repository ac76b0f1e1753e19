//! The three views of the screen: both cameras with their overlays (contour, parts,
//! skeleton, landmarks, board detections) and the avatar in 3-D with its orbit controls.

use super::*;

/// Margin around the views (points).
const VIEW_MARGIN: f32 = 6.0;

/// Colours of the overlay layers.
const CONTOUR_COLOUR: Color32 = Color32::from_rgb(255, 220, 0);
const BONE_COLOUR: Color32 = Color32::from_rgb(0, 230, 255);
const LANDMARK_COLOUR: Color32 = Color32::from_rgb(255, 60, 160);
const AVATAR_OUTLINE_COLOUR: Color32 = Color32::from_rgb(120, 255, 120);
const PART_COLOURS: [Color32; 6] = [
    Color32::from_rgb(255, 120, 0),
    Color32::from_rgb(80, 160, 255),
    Color32::from_rgb(200, 90, 255),
    Color32::from_rgb(255, 255, 255),
    Color32::from_rgb(0, 200, 120),
    Color32::from_rgb(255, 80, 80),
];

impl StationApp {
    /// Lays out the three views side by side: the front and side cameras with their
    /// overlays, then the avatar.
    pub(super) fn views(&mut self, ui: &mut egui::Ui) {
        let avail = ui.available_rect_before_wrap().shrink(VIEW_MARGIN);
        let gap = 6.0;
        let w = (avail.width() - 2.0 * gap) / 3.0;
        let cols: Vec<Rect> = (0..3)
            .map(|k| {
                Rect::from_min_size(
                    Pos2::new(avail.min.x + k as f32 * (w + gap), avail.min.y),
                    Vec2::new(w, avail.height()),
                )
            })
            .collect();
        let painter = ui.painter_at(avail);
        let ppp = ui.ctx().pixels_per_point();
        let view_px = Some([w * ppp, avail.height() * ppp]);
        if self.view_px != view_px {
            // The process thread prepares the next frames at this size.
            self.view_px = view_px;
            if let Ok(mut v) = self.runner.controls.view_px.lock() {
                *v = view_px;
            }
        }
        let show_all = self.mode == Mode::Operator;
        if show_all {
            self.refresh_outlines();
        }
        let snap = self.current.as_ref();
        let outline = |k: usize| match &self.outlines {
            Some((_, o)) if show_all => o[k].as_slice(),
            _ => &[],
        };
        self.layout.front = draw_view(
            &painter,
            cols[0],
            "front",
            self.front_tex.as_ref(),
            snap.map(|s| &s.front),
            outline(0),
            &self.wizard_view.detections.front,
            show_all,
        );
        self.layout.side = draw_view(
            &painter,
            cols[1],
            "side",
            self.side_tex.as_ref(),
            snap.map(|s| &s.side),
            outline(1),
            &self.wizard_view.detections.side,
            show_all,
        );
        // The avatar view with orbit controls and presets.
        let avatar_rect = cols[2];
        self.orbit_input(ui, avatar_rect);
        // Hand edits hold the avatar on screen: new fits do not replace it.
        let (mesh, take) = match self.edit.shown_mesh() {
            Some(edited) => (self.show_edited(edited), false),
            None => self.take_newest_avatar(ui),
        };
        if take {
            self.fit_orbit_to(mesh.as_deref(), avatar_rect);
        }
        self.draw_avatar(ui, &painter, avatar_rect, mesh);
        self.avatar_presets(ui, avatar_rect);
        if let Some(note) = self.edit.view_note(self.mode == Mode::Operator) {
            painter.text(
                avatar_rect.center_bottom() - Vec2::new(0.0, 8.0),
                egui::Align2::CENTER_BOTTOM,
                note,
                egui::FontId::proportional(15.0),
                Color32::from_rgb(150, 200, 255),
            );
        }
    }

    /// The avatar's outline in each view for the operator's screen, once per snapshot:
    /// the processor's when it drew one, else the snapshot's avatar projected here by
    /// the view's camera (so the fitting thread does not project it every pair).
    fn refresh_outlines(&mut self) {
        let Some(s) = self.current.as_ref() else {
            self.outlines = None;
            return;
        };
        let key = (
            s.frame_index,
            s.avatar.as_ref().map(|a| Arc::as_ptr(a) as usize),
        );
        if self.outlines.as_ref().is_some_and(|(k, _)| *k == key) {
            return;
        }
        let one = |o: &ViewOverlay| match (&s.avatar, &o.camera) {
            _ if !o.avatar_outline.is_empty() => o.avatar_outline.clone(),
            (Some(av), Some(cam)) => crate::pipeline::avatar_outline(av, cam),
            _ => Vec::new(),
        };
        self.outlines = Some((key, [one(&s.front), one(&s.side)]));
    }

    /// Turns and zooms the avatar's orbit camera by dragging and scrolling over its view;
    /// while "Edit avatar" is on, the primary button edits ([`edit_tool`]) and the
    /// others turn the view.
    fn orbit_input(&mut self, ui: &mut egui::Ui, avatar_rect: Rect) {
        let resp = ui.interact(
            avatar_rect,
            ui.scope_id().with("avatar_orbit"),
            egui::Sense::drag(),
        );
        let editing = self.mode == Mode::Operator && (self.edit.on || self.edit.dragging());
        if editing {
            self.edit_input(ui, &resp, avatar_rect);
        }
        let turning = resp.dragged() && !(editing && resp.dragged_by(egui::PointerButton::Primary));
        if turning || resp.hovered() {
            let d = if turning {
                resp.drag_delta()
            } else {
                Vec2::ZERO
            };
            let scroll = if resp.hovered() {
                ui.input(|i| i.smooth_scroll_delta.y)
            } else {
                0.0
            };
            if d != Vec2::ZERO || scroll != 0.0 {
                self.orbit.drag(d.x, d.y, scroll);
            }
            if scroll != 0.0 {
                self.user_zoomed = true;
            }
        }
    }

    /// The avatar to draw and whether it was taken this frame: the newest fit, at most
    /// every [`AVATAR_PERIOD_S`] (or a repaint asked for when it has to wait).
    fn take_newest_avatar(&mut self, ui: &egui::Ui) -> (Option<Arc<crate::mesh::TriMesh>>, bool) {
        // The newest fit replaces the one on screen at most every AVATAR_PERIOD_S (the
        // 3-D view is rendered again only then), in a frame that shows a new snapshot
        // anyway; a cleared avatar goes at once. A frame of its own is asked for only
        // as a fallback, later than the next snapshot would come: each frame costs a
        // whole window of software rendering and presenting.
        let latest = self.current.as_ref().and_then(|s| s.avatar.clone());
        let changed = match (&latest, &self.shown_avatar) {
            (Some(a), Some(b)) => !Arc::ptr_eq(a, b),
            (None, None) => false,
            _ => true,
        };
        let now = self.now_s();
        let since = now - self.avatar_shown_s;
        let due = since >= AVATAR_PERIOD_S - AVATAR_PERIOD_SLACK_S;
        let take = changed && (due || latest.is_none() || self.shown_avatar.is_none());
        if take {
            self.shown_avatar = latest;
            self.avatar_generation += 1;
            self.avatar_shown_s = now;
        } else if changed {
            ui.ctx()
                .request_repaint_after(std::time::Duration::from_secs_f64(
                    (AVATAR_PERIOD_S - since).max(0.0) + AVATAR_FALLBACK_S,
                ));
        }
        (self.shown_avatar.clone(), take)
    }

    /// Aims the orbit camera at a newly taken avatar, and fits it into the view unless
    /// the operator zoomed by hand.
    fn fit_orbit_to(&mut self, mesh: Option<&crate::mesh::TriMesh>, avatar_rect: Rect) {
        if let Some(m) = mesh {
            if let Some(b) = m.bounds() {
                let c = b.center();
                self.orbit.target = glam::Vec3::new(0.0, c.y as f32, 0.0);
                if !self.user_zoomed {
                    let size = b.size();
                    let aspect = avatar_rect.width() / avatar_rect.height().max(1.0);
                    self.orbit.fit(
                        glam::Vec3::new(size.x as f32, size.y as f32, size.z as f32),
                        aspect,
                    );
                }
            }
        }
    }

    /// Asks the renderer for the avatar's picture at the view's size and paints the
    /// newest finished one over the body ("no avatar yet" without one).
    fn draw_avatar(
        &mut self,
        ui: &egui::Ui,
        painter: &egui::Painter,
        avatar_rect: Rect,
        mesh: Option<Arc<crate::mesh::TriMesh>>,
    ) {
        let has_mesh = mesh.is_some();
        let aspect = avatar_rect.width() / avatar_rect.height().max(1.0);
        let body_ndc = mesh
            .as_deref()
            .and_then(|m| avatar3d::ndc_bounds(m, &self.orbit, aspect));
        let ppp = ui.ctx().pixels_per_point();
        let job = AvatarJob {
            mesh,
            generation: self.avatar_generation,
            camera: self.orbit,
            size_px: [
                (avatar_rect.width() * ppp).round().max(1.0) as u32,
                (avatar_rect.height() * ppp).round().max(1.0) as u32,
            ],
            body_ndc,
        };
        let presented = self.clock.frames();
        self.avatar_on_screen = false;
        if let Some(r) = self.avatar.as_mut() {
            r.request(job, presented);
            // The newest finished picture (it may lag the request by a frame); none
            // at all once the avatar has been cleared.
            if let Some(picture) = r.picture().filter(|p| p.has_mesh && has_mesh) {
                self.avatar_on_screen = true;
                painter.add(eframe::egui_wgpu::Callback::new_paint_callback(
                    avatar_rect,
                    AvatarCallback { picture },
                ));
            }
        }
        self.layout.avatar = Some(avatar_rect);
        if !has_mesh {
            painter.text(
                avatar_rect.center(),
                egui::Align2::CENTER_CENTER,
                "no avatar yet",
                egui::FontId::proportional(18.0),
                Color32::GRAY,
            );
        }
    }

    /// The Front, Side and 3/4 buttons over the avatar view.
    fn avatar_presets(&mut self, ui: &mut egui::Ui, avatar_rect: Rect) {
        let bar = Rect::from_min_size(
            avatar_rect.left_top() + Vec2::new(8.0, 8.0),
            Vec2::new(avatar_rect.width() - 16.0, 24.0),
        );
        ui.scope_builder(egui::UiBuilder::new().max_rect(bar), |ui| {
            ui.horizontal(|ui| {
                for (label, p) in [
                    ("Front", ViewPreset::Front),
                    ("Side", ViewPreset::Side),
                    ("3/4", ViewPreset::ThreeQuarter),
                ] {
                    if ui.small_button(label).clicked() {
                        self.orbit.preset(p);
                        self.user_zoomed = false;
                    }
                }
            });
        });
    }
}

/// Draws one camera view fitted into `area` with its overlays; returns the image rect.
// One call per camera view with what that view shows; a struct would only rename them.
#[allow(clippy::too_many_arguments)]
fn draw_view(
    painter: &egui::Painter,
    area: Rect,
    name: &str,
    tex: Option<&ViewTexture>,
    overlay: Option<&ViewOverlay>,
    avatar_outline: &[glam::DVec2],
    boards: &[operator::BoardDetection],
    operator: bool,
) -> Option<Rect> {
    let Some(tex) = tex else {
        // No fill: on a software renderer every covered pixel costs each frame.
        painter.rect_stroke(
            area,
            4.0,
            Stroke::new(1.0, Color32::from_gray(60)),
            egui::StrokeKind::Inside,
        );
        painter.text(
            area.center(),
            egui::Align2::CENTER_CENTER,
            format!("{name}: no frames"),
            egui::FontId::proportional(18.0),
            Color32::GRAY,
        );
        return None;
    };
    let [fw, fh] = tex.frame_size;
    let scale = (area.width() / fw as f32).min(area.height() / fh as f32);
    let size = Vec2::new(fw as f32 * scale, fh as f32 * scale);
    let rect = Rect::from_center_size(area.center(), size);
    painter.add(eframe::egui_wgpu::Callback::new_paint_callback(
        rect,
        frame_view::FrameViewCallback {
            slot: tex.slot,
            image: tex.image.clone(),
            generation: tex.generation,
        },
    ));
    let to_screen = |p: glam::DVec2| {
        Pos2::new(
            rect.min.x + p.x as f32 * scale,
            rect.min.y + p.y as f32 * scale,
        )
    };
    if let Some(o) = overlay {
        if operator {
            for (k, (_, pts)) in o.parts.iter().enumerate() {
                let c = PART_COLOURS[k % PART_COLOURS.len()];
                // Dots closer than a segment overlap anyway.
                for p in screen_polyline(pts.iter().map(|p| to_screen(*p))) {
                    painter.circle_filled(p, 2.0, c);
                }
            }
            if avatar_outline.len() > 2 {
                let pts = screen_polyline(avatar_outline.iter().map(|p| to_screen(*p)));
                painter.add(egui::Shape::closed_line(
                    pts,
                    Stroke::new(1.0, AVATAR_OUTLINE_COLOUR),
                ));
            }
        }
        if o.contour.len() > 2 {
            let pts = screen_polyline(o.contour.iter().map(|p| to_screen(*p)));
            painter.add(egui::Shape::closed_line(
                pts,
                Stroke::new(2.0, CONTOUR_COLOUR),
            ));
        }
        for (a, b) in &o.bones {
            painter.line_segment(
                [to_screen(*a), to_screen(*b)],
                Stroke::new(2.0, BONE_COLOUR),
            );
        }
        for (_, p) in &o.landmarks {
            painter.circle_filled(to_screen(*p), 3.5, LANDMARK_COLOUR);
        }
    }
    for b in boards {
        for p in &b.corners_px {
            let c = to_screen(*p);
            painter.line_segment(
                [c - Vec2::new(3.0, 0.0), c + Vec2::new(3.0, 0.0)],
                Stroke::new(1.0, Color32::GREEN),
            );
            painter.line_segment(
                [c - Vec2::new(0.0, 3.0), c + Vec2::new(0.0, 3.0)],
                Stroke::new(1.0, Color32::GREEN),
            );
        }
    }
    painter.text(
        rect.left_top() + Vec2::new(6.0, 4.0),
        egui::Align2::LEFT_TOP,
        name,
        egui::FontId::proportional(16.0),
        Color32::WHITE,
    );
    Some(rect)
}

/// Shortest segment of an outline as drawn (points). The station's contours have a
/// point every pixel or two of the camera frame, several per screen pixel once the frame
/// is scaled into its view; every segment is a few triangles for the software
/// rasteriser, so points closer than this to the last one kept are left out.
pub(super) const OUTLINE_MIN_SEGMENT: f32 = 2.5;

/// The points of a closed outline on screen, without those closer than
/// [`OUTLINE_MIN_SEGMENT`] to the previous point kept.
pub(super) fn screen_polyline(points: impl Iterator<Item = Pos2>) -> Vec<Pos2> {
    let mut out: Vec<Pos2> = Vec::new();
    for p in points {
        match out.last() {
            Some(last) if last.distance(p) < OUTLINE_MIN_SEGMENT => {}
            _ => out.push(p),
        }
    }
    out
}
