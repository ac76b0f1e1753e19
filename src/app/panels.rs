//! The screen's panels around the views: the top bar, the kiosk's banner, and the
//! measurements with their stability, stage timings and station messages.

use super::*;

impl StationApp {
    pub(super) fn top_bar(&mut self, ui: &mut egui::Ui) {
        let now = self.now_s();
        ui.horizontal_wrapped(|ui| {
            ui.heading("fitstation");
            ui.separator();
            ui.selectable_value(&mut self.mode, Mode::Kiosk, "Kiosk");
            ui.selectable_value(&mut self.mode, Mode::Operator, "Operator");
            ui.separator();
            ui.label(&self.describe);
            ui.separator();
            ui.label(format!(
                "screen {:.0} fps · snapshots {:.0}/s{} · dropped {}",
                self.ui_meter.rate(now),
                self.snap_meter.rate(now),
                self.fps
                    .map(|f| format!(" (source {f:.0})"))
                    .unwrap_or_default(),
                self.runner.dropped_pairs()
            ));
            let rec = self.runner.controls.recorder.lock().ok().and_then(|r| {
                r.as_ref().map(|r| {
                    (
                        r.stats().written.load(Ordering::Relaxed),
                        r.stats().dropped.load(Ordering::Relaxed),
                    )
                })
            });
            if let Some((w, d)) = rec {
                ui.separator();
                let blink = ((now * 2.0) as u64).is_multiple_of(2);
                let (r, _) = ui.allocate_exact_size(Vec2::splat(14.0), egui::Sense::hover());
                if blink {
                    ui.painter().circle_filled(r.center(), 6.0, Color32::RED);
                } else {
                    ui.painter()
                        .circle_stroke(r.center(), 6.0, Stroke::new(2.0, Color32::RED));
                }
                ui.label(
                    RichText::new(format!("REC {w} pairs ({d} dropped)"))
                        .color(Color32::RED)
                        .strong(),
                );
            }
            let st = self.runner.controls.status();
            if let Some(p) = &st.problem {
                ui.separator();
                ui.label(
                    RichText::new(p)
                        .color(Color32::from_rgb(255, 140, 0))
                        .strong(),
                );
            }
            if let Some(f) = self.fault_line(now, &st) {
                ui.separator();
                ui.label(
                    RichText::new(f)
                        .color(Color32::from_rgb(255, 140, 0))
                        .strong(),
                );
            }
            if st.ended {
                ui.separator();
                ui.label("source ended");
            }
            if self.runner.controls.paused.load(Ordering::Relaxed) {
                ui.separator();
                ui.label(RichText::new("PAUSED").strong());
            }
        });
    }

    pub(super) fn kiosk_banner(&mut self, ui: &mut egui::Ui) {
        let now = self.now_s();
        let (text, colour) = match self.flow.state() {
            FlowState::LearningBackdrop => (
                "Getting ready… please keep the area in front of the cameras empty".to_string(),
                Color32::LIGHT_BLUE,
            ),
            FlowState::EmptyScene => (
                "Step onto the mark and face the screen".to_string(),
                Color32::WHITE,
            ),
            FlowState::Guiding { message } => (message.clone(), Color32::from_rgb(255, 200, 80)),
            FlowState::HoldStill { .. } => {
                let left = self.flow.countdown_left_s(now);
                if left > 0.0 {
                    (
                        format!("Hold still… {}", left.ceil() as u64),
                        Color32::from_rgb(120, 230, 120),
                    )
                } else {
                    (
                        "Hold still… almost there".to_string(),
                        Color32::from_rgb(120, 230, 120),
                    )
                }
            }
            FlowState::Result { .. } => (
                "Your measurements are ready".to_string(),
                Color32::from_rgb(120, 230, 120),
            ),
        };
        ui.vertical_centered(|ui| {
            ui.add_space(6.0);
            ui.label(RichText::new(text).size(28.0).color(colour).strong());
            ui.add_space(6.0);
        });
    }

    pub(super) fn measurements_panel(&mut self, ui: &mut egui::Ui) {
        // Hand edits: the frozen fit's values plus each one's change from the edits.
        let (measurements, edited) = self.edit.edited_measurements().unwrap_or_else(|| {
            let live = self.current.as_ref().map(|s| s.measurements.clone());
            (live.unwrap_or_default(), Vec::new())
        });
        if let FlowState::Result { card, .. } = self.flow.state() {
            result_card(ui, card, &edited);
        }
        ui.heading("Measurements");
        // Fitted from one camera: said where the values are (their ± is the wider one).
        if let Some(m) = self.current.as_ref().and_then(|s| {
            s.messages
                .iter()
                .find(|m| *m == crate::station::ONE_VIEW_MESSAGE)
        }) {
            ui.label(RichText::new(m).color(egui::Color32::from_rgb(230, 160, 40)));
        }
        if !edited.is_empty() || self.edit.frozen() {
            ui.label(RichText::new("Edited by hand (avatar frozen)").color(EDITED_COLOUR));
        }
        if measurements.is_empty() {
            ui.label("waiting for a fit…");
        } else {
            measurement_grid(ui, &measurements, &edited);
        }
        ui.separator();
        ui.heading("Timings");
        let now = self.now_s();
        if now - self.timings_table_s >= TIMINGS_REFRESH_S {
            self.timings_table_s = now;
            self.timings_table = self.timings_rows();
        }
        if let Some(s) = &self.current {
            if self.mode == Mode::Operator {
                egui::Grid::new("timings").num_columns(3).show(ui, |ui| {
                    ui.label("stage");
                    ui.label("now");
                    ui.label("median / p95");
                    ui.end_row();
                    for (stage, latest, sum) in &self.timings_table {
                        ui.label(stage);
                        // Fixed widths: see VALUE_CELL_WIDTH.
                        fixed_cell(ui, VALUE_CELL_WIDTH, |ui| {
                            ui.label(latest.map(|ms| format!("{ms:.2} ms")).unwrap_or_default());
                        });
                        fixed_cell(ui, STABILITY_CELL_WIDTH, |ui| {
                            ui.label(format!("{:.2} / {:.2} ms", sum.median, sum.p95));
                        });
                        ui.end_row();
                    }
                });
            } else {
                // The kiosk shows the main figures only: every covered pixel costs on a
                // software renderer, every frame (Operator mode has the whole table).
                for (stage, _, sum) in self
                    .timings_table
                    .iter()
                    .filter(|(n, _, _)| KIOSK_TIMINGS.contains(&n.as_str()))
                {
                    ui.label(
                        RichText::new(format!(
                            "{stage}: {:.1} / {:.1} ms (median / p95)",
                            sum.median, sum.p95
                        ))
                        .small(),
                    );
                }
            }
            ui.label(format!("frame {}  phase {:?}", s.frame_index, s.phase));
            if self.mode == Mode::Operator {
                for m in s.messages.iter().take(MESSAGES_SHOWN) {
                    ui.label(RichText::new(m).small());
                }
            }
        }
    }

    /// The timings table: the station's stages (with the current snapshot's value),
    /// the pipeline threads, the screen's own work and its frame clock.
    pub(super) fn timings_rows(&self) -> Vec<(String, Option<f64>, stats::Summary)> {
        let latest = |stage: &str| {
            self.current
                .as_ref()
                .and_then(|s| s.timings_ms.iter().find(|(n, _)| n == stage))
                .map(|(_, ms)| *ms)
        };
        let mut rows: Vec<(String, Option<f64>, stats::Summary)> = self
            .pipeline_stats
            .summary()
            .into_iter()
            .map(|(n, v)| {
                let now = latest(&n);
                (n, now, v)
            })
            .collect();
        rows.extend(
            self.runner
                .controls
                .thread_stats()
                .summary()
                .into_iter()
                .map(|(n, v)| (n, None, v)),
        );
        rows.extend(
            self.ui_stats
                .summary()
                .into_iter()
                .chain(self.clock.stats().summary())
                .map(|(n, v)| (format!("screen {n}"), None, v)),
        );
        rows
    }
}

/// The kiosk's result card (values changed by hand edits shown with the change).
fn result_card(ui: &mut egui::Ui, card: &flow::ResultCard, edited: &[(String, f64)]) {
    ui.heading("Your result");
    egui::Grid::new("result_card").striped(true).show(ui, |ui| {
        for m in &card.measurements {
            ui.label(pretty_name(&m.name));
            // How sure the station is goes with the value; shown after the settle
            // timeout, the frame-to-frame spread adds to it.
            let pm = if card.settled {
                m.uncertainty_mm
            } else {
                m.uncertainty_mm.max(m.stability_mm)
            };
            let edit = edited.iter().find(|(k, _)| *k == m.name).map(|e| e.1);
            ui.label(
                RichText::new(value_text(m.value_mm + edit.unwrap_or(0.0), pm))
                    .size(18.0)
                    .strong(),
            );
            match edit {
                Some(d) => edited_flag(ui, d),
                None => uncertainty_flag(ui, m),
            }
            ui.end_row();
        }
    });
    ui.separator();
}

/// The measurements grid: name, value, stability (or the hand edit's change), flag.
fn measurement_grid(
    ui: &mut egui::Ui,
    measurements: &[MeasurementValue],
    edited: &[(String, f64)],
) {
    egui::Grid::new("measurements")
        .striped(true)
        .num_columns(4)
        .show(ui, |ui| {
            for m in measurements {
                ui.label(pretty_name(&m.name));
                fixed_cell(ui, VALUE_CELL_WIDTH, |ui| {
                    ui.label(RichText::new(value_text(m.value_mm, m.uncertainty_mm)).monospace());
                });
                match edited.iter().find(|(k, _)| *k == m.name) {
                    Some((_, d)) => fixed_cell(ui, STABILITY_CELL_WIDTH, |ui| edited_flag(ui, *d)),
                    None => stability_indicator(ui, m.stability_mm),
                }
                uncertainty_flag(ui, m);
                ui.end_row();
            }
        });
}

/// "edited by hand +5.9" (mm) in the hand edits' colour.
fn edited_flag(ui: &mut egui::Ui, d_mm: f64) {
    ui.label(
        RichText::new(format!("edited by hand {d_mm:+.1}"))
            .small()
            .color(EDITED_COLOUR),
    );
}

/// Colour of the words that mark values edited by hand.
const EDITED_COLOUR: Color32 = Color32::from_rgb(150, 200, 255);

/// Report key -> label ("chest_girth" -> "chest girth").
fn pretty_name(key: &str) -> String {
    key.replace('_', " ")
}

fn stability_indicator(ui: &mut egui::Ui, spread_mm: f64) {
    let (colour, word) = if spread_mm < STABLE_MM {
        (Color32::from_rgb(80, 200, 80), "settled")
    } else if spread_mm < UNSTABLE_MM {
        (Color32::from_rgb(230, 180, 40), "settling")
    } else {
        (Color32::from_rgb(230, 80, 60), "moving")
    };
    fixed_cell(ui, STABILITY_CELL_WIDTH, |ui| {
        let (r, _) = ui.allocate_exact_size(Vec2::splat(10.0), egui::Sense::hover());
        ui.painter().circle_filled(r.center(), 5.0, colour);
        ui.label(RichText::new(format!("{word}, spread {spread_mm:.1}")).small());
    });
}

/// A measurement's value with how sure the station is of it (`±` two standard deviations,
/// `station::uncertainty`), or the value alone while that is unknown.
fn value_text(value_mm: f64, pm_mm: f64) -> String {
    if pm_mm.is_finite() {
        format!("{value_mm:.0} ±{pm_mm:.0} mm")
    } else {
        format!("{value_mm:.0} mm")
    }
}

/// Flags a measurement the station did not see well enough to vouch for (its `±` beyond
/// the ANSUR II observer tolerance).
fn uncertain_flag_text(m: &MeasurementValue) -> Option<&'static str> {
    m.uncertain.then_some("not sure: check by hand")
}

fn uncertainty_flag(ui: &mut egui::Ui, m: &MeasurementValue) {
    match uncertain_flag_text(m) {
        Some(t) => {
            ui.label(
                RichText::new(t)
                    .small()
                    .color(Color32::from_rgb(230, 150, 40)),
            );
        }
        None => {
            ui.label("");
        }
    }
}

/// Widths of the measurement grid's value and stability cells (points): wide enough for
/// any value, and fixed, because a grid whose column widths change asks egui for one
/// more frame to lay itself out again (a whole extra frame of software rendering,
/// whenever a value gains a digit or a word changes).
const VALUE_CELL_WIDTH: f32 = 120.0;
const STABILITY_CELL_WIDTH: f32 = 130.0;

/// A grid cell exactly `width` points wide (unless its content is wider), laid out left
/// to right.
fn fixed_cell(ui: &mut egui::Ui, width: f32, content: impl FnOnce(&mut egui::Ui)) {
    let height = ui.spacing().interact_size.y;
    ui.allocate_ui_with_layout(
        Vec2::new(width, height),
        egui::Layout::left_to_right(egui::Align::Center),
        |ui| {
            ui.set_min_width(width);
            content(ui);
        },
    );
}
