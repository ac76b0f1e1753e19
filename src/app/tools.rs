//! The operator's tools beside the kiosk: calibration (the wizard, loading and checks),
//! recording, replay controls, exports and the operator's log.

use super::*;

impl StationApp {
    pub(super) fn operator_panel(&mut self, ui: &mut egui::Ui) {
        egui::ScrollArea::vertical().show(ui, |ui| {
            egui::CollapsingHeader::new("Edit avatar").default_open(true).show(ui, |ui| {
                for line in self.edit.section_ui(ui) {
                    self.log(line);
                }
            });
            egui::CollapsingHeader::new("Calibration").default_open(true).show(ui, |ui| {
                self.calibration_section(ui);
            });
            egui::CollapsingHeader::new("Station").default_open(true).show(ui, |ui| {
                ui.label(RichText::new("Station checks").strong());
                let sizes = self.front_tex.as_ref().zip(self.side_tex.as_ref()).map(|(f, s)| (f.frame_size, s.frame_size));
                let mut checks = operator::station_checks(self.calibration.as_ref(), sizes);
                if let Some(cal) = &self.calibration {
                    checks.extend(calib_wizard::checks_lines(&crate::calibrate::check_station(cal)));
                }
                for c in checks {
                    let colour = if c.starts_with("PROBLEM") || c.starts_with("ACTION") || c.starts_with("No calibration") {
                        Color32::from_rgb(255, 140, 0)
                    } else {
                        ui.visuals().text_color()
                    };
                    ui.label(RichText::new(c).color(colour).small());
                }
                if self.processor_factory.is_some() && ui.button("Learn the backdrop again (scene empty!)").clicked() {
                    if let Some(cal) = self.calibration.clone() {
                        self.use_calibration(cal, "learning the backdrop again");
                    }
                }
            });
            egui::CollapsingHeader::new("Recording").default_open(true).show(ui, |ui| {
                ui.horizontal(|ui| {
                    ui.label("folder");
                    ui.text_edit_singleline(&mut self.record_dir);
                });
                let recording = self.runner.controls.recorder.lock().map(|r| r.is_some()).unwrap_or(false);
                if !recording {
                    if ui.button("Start recording").clicked() {
                        self.start_recording();
                    }
                    ui.label(RichText::new("Start with the empty scene (at least 10 frames), then let the subject in.").small());
                } else if ui.button("Stop recording").clicked() {
                    self.stop_recording();
                }
            });
            egui::CollapsingHeader::new("Replay").default_open(true).show(ui, |ui| {
                let c = &self.runner.controls;
                ui.horizontal(|ui| {
                    if ui.button("Play").clicked() {
                        c.paused.store(false, Ordering::Relaxed);
                    }
                    if ui.button("Pause").clicked() {
                        c.paused.store(true, Ordering::Relaxed);
                    }
                    if ui.button("Step").clicked() {
                        c.paused.store(true, Ordering::Relaxed);
                        c.steps.fetch_add(1, Ordering::Relaxed);
                    }
                });
                let st = c.status();
                ui.label(format!(
                    "pairs read {}, last index {}{}",
                    st.pairs,
                    st.last_index.map(|i| i.to_string()).unwrap_or_else(|| "-".into()),
                    if st.ended { ", ended" } else { "" }
                ));
                if ui.button("Reset shopper (clear data)").clicked() {
                    self.edit.discard();
                    self.flow.reset();
                    self.clear_subject();
                }
            });
            egui::CollapsingHeader::new("Export").default_open(true).show(ui, |ui| {
                ui.horizontal(|ui| {
                    ui.label("folder");
                    ui.text_edit_singleline(&mut self.export_dir);
                });
                ui.horizontal(|ui| {
                    for f in export::AvatarFormat::ALL {
                        if ui.button(format!("Avatar .{}", f.extension())).clicked() {
                            self.export_avatar(f);
                        }
                    }
                });
                ui.horizontal(|ui| {
                    if ui.button("Measurements JSON + CSV").clicked() {
                        self.export_measurements();
                    }
                    if ui.button("Screenshot").clicked() {
                        let p = Path::new(&self.export_dir).join(format!("screen-{}.png", self.frames));
                        self.request_screenshot(ui.ctx(), p);
                    }
                });
            });
            ui.separator();
            for l in &self.operator_log {
                ui.label(RichText::new(l).small());
            }
        });
    }

    /// Writes the avatar (as edited by hand, if it is) into the export folder.
    pub(super) fn export_avatar(&mut self, format: export::AvatarFormat) {
        let edited = self.edit.editor().map(|e| e.mesh());
        let live = self.current.as_ref().and_then(|s| s.avatar.clone());
        let r = export::export_avatar(
            Path::new(&self.export_dir),
            edited.or(live.as_deref()),
            format,
        );
        self.log(match r {
            Ok(p) => format!("wrote {}", p.display()),
            Err(e) => format!("export failed: {e}"),
        });
    }

    /// Writes the measurements (with the hand edits, if any) into the export folder.
    pub(super) fn export_measurements(&mut self) {
        let m = match self.edit.fit_values() {
            Some(fit) => fit.to_vec(),
            None => self
                .current
                .as_ref()
                .map(|s| s.measurements.clone())
                .unwrap_or_default(),
        };
        let r = export::export_measurements(Path::new(&self.export_dir), &m, self.edit.editor());
        self.log(match r {
            Ok([j, c]) => format!("wrote {} and {}", j.display(), c.display()),
            Err(e) => format!("export failed: {e}"),
        });
    }

    /// Installs a processor for `cal` (through the factory): the station learns the
    /// backdrop again and measures with that calibration from the next frame on.
    pub(super) fn use_calibration(&mut self, cal: StationCalibration, why: &str) {
        let Some(factory) = &self.processor_factory else {
            self.log("this screen cannot change its processor".into());
            return;
        };
        match factory(&cal) {
            Ok(p) => {
                if let Ok(mut slot) = self.runner.controls.replace_processor.lock() {
                    *slot = Some(p);
                }
                self.calibration = Some(cal);
                self.flow.reset();
                self.clear_subject();
                self.log(format!(
                    "{why}: keep the scene empty while the backdrop is learnt"
                ));
            }
            Err(e) => self.log(format!("cannot use the calibration: {e}")),
        }
    }

    pub(super) fn calibration_section(&mut self, ui: &mut egui::Ui) {
        let s = &self.wizard_settings;
        ui.label(format!(
            "{} {}x{} inner corners, {:.1} mm; saves to {}",
            s.target.name(),
            s.board.cols,
            s.board.rows,
            s.board.square_m * 1e3,
            s.out.display()
        ));
        let was_live = self.wizard_live;
        ui.checkbox(&mut self.wizard_live, "Live board detection");
        if self.wizard_live && !was_live && self.wizard.is_none() {
            match CalibrationWizard::start(self.wizard_settings.clone(), self.calibration.clone()) {
                Ok(w) => self.wizard = Some(w),
                Err(e) => {
                    self.wizard_live = false;
                    self.log(format!("cannot start the calibration wizard: {e}"));
                }
            }
        }
        if !self.wizard_live {
            self.wizard_view.detections = Default::default();
        }
        let Some(w) = &self.wizard else {
            ui.label(RichText::new("Turn on live board detection to calibrate.").small());
            return;
        };
        self.wizard_view = w.view();
        let v = &self.wizard_view;
        let step = match v.step {
            WizardStep::Lenses => "1 lenses",
            WizardStep::Placement => "2 placement",
            WizardStep::Review => "3 review",
        };
        ui.label(
            RichText::new(format!(
                "Step {step} · {} frame pairs searched",
                v.frames_searched
            ))
            .strong(),
        );
        for l in &v.lines {
            ui.label(RichText::new(l).small());
        }
        if !v.status.is_empty() {
            ui.label(RichText::new(&v.status).color(Color32::from_rgb(150, 200, 255)));
        }
        let mut actions = Vec::new();
        ui.horizontal_wrapped(|ui| {
            match v.step {
                WizardStep::Lenses => {
                    if ui.button("Solve lenses").clicked() {
                        actions.push(WizardAction::SolveLenses);
                    }
                }
                WizardStep::Placement | WizardStep::Review => {
                    ui.label("board height mm");
                    if ui
                        .add(egui::DragValue::new(&mut self.board_height_mm).range(0.0..=3000.0))
                        .changed()
                    {
                        actions.push(WizardAction::SetBoardHeightMm(self.board_height_mm));
                    }
                    if ui.button("Place cameras").clicked() {
                        actions.push(WizardAction::PlaceCameras);
                    }
                }
            }
            if v.solved.is_some() {
                if ui.button("Save station.yaml").clicked() {
                    actions.push(WizardAction::Save { force: false });
                }
                if ui.button("Save, replacing a better one").clicked() {
                    actions.push(WizardAction::Save { force: true });
                }
            }
            if ui.button("Start over").clicked() {
                actions.push(WizardAction::Reset);
            }
        });
        for a in &v.actions {
            ui.label(
                RichText::new(format!("PROBLEM: {a}"))
                    .color(Color32::from_rgb(255, 140, 0))
                    .small(),
            );
        }
        for c in &v.checks {
            ui.label(RichText::new(c).small());
        }
        let solved = v.solved.clone();
        for a in actions {
            w.act(a);
        }
        if let Some(cal) = solved {
            if self.processor_factory.is_some() && ui.button("Use this calibration now").clicked() {
                self.use_calibration(cal, "new calibration in use");
            }
        }
    }

    pub(super) fn start_recording(&mut self) {
        // Each recording gets its own folder under the one in the field.
        let dir = record::session_dir(Path::new(&self.record_dir), std::time::SystemTime::now());
        match record::Recorder::start(&dir, self.calibration.as_ref(), self.fps) {
            Ok(r) => {
                if self.calibration.is_none() {
                    self.log("recording without station.yaml: no calibration is loaded".into());
                }
                self.log(format!("recording to {}", dir.display()));
                if let Ok(mut slot) = self.runner.controls.recorder.lock() {
                    *slot = Some(r);
                }
            }
            Err(e) => self.log(format!("cannot record: {e}")),
        }
    }

    pub(super) fn stop_recording(&mut self) {
        let r = self
            .runner
            .controls
            .recorder
            .lock()
            .ok()
            .and_then(|mut s| s.take());
        if let Some(r) = r {
            let dir = r.dir().to_path_buf();
            let dropped = r.stats().dropped.load(Ordering::Relaxed);
            match r.finish() {
                Ok(n) => self.log(format!(
                    "recorded {n} pairs to {} ({dropped} dropped)",
                    dir.display()
                )),
                Err(e) => self.log(format!("recording failed: {e}")),
            }
        }
    }
}
