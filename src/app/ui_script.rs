//! Scripted input for the window tests (`replay --ui --ui-script FILE`, hidden): a JSON
//! list of steps, each an action some screen frames after the previous one, e.g.
//!
//! ```json
//! [{"action": "await_avatar"},
//!  {"wait": 3, "action": "edit_on"},
//!  {"wait": 3, "action": "press", "at": [0.5, 0.35]},
//!  {"wait": 2, "action": "move", "at": [0.55, 0.35]},
//!  {"wait": 2, "action": "release", "at": [0.55, 0.35]},
//!  {"wait": 3, "action": "undo"},
//!  {"wait": 3, "action": "exit"}]
//! ```
//!
//! Pointer actions are given relative to the avatar view's rectangle (0..1 from its
//! top-left corner) and reach the screen as egui pointer events through
//! `eframe::App::raw_input_hook`, so they take the real input path, as do clicks on the
//! edit section's buttons (`{"action": "click", "target": "edit_avatar" | "undo" |
//! "done"}`); `edit_on`, `edit_off`, `undo`, `export` (`"dir": ...`) and `exit` act on
//! the screen's state directly.

use serde::Deserialize;
use std::path::Path;

/// One step of a script.
#[derive(Debug, Clone, PartialEq, Deserialize)]
pub struct ScriptStep {
    /// Screen frames between the previous step and this one.
    #[serde(default)]
    pub wait: u64,
    #[serde(flatten)]
    pub action: ScriptAction,
}

/// What a step does.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(tag = "action", rename_all = "snake_case")]
pub enum ScriptAction {
    /// Holds the script until a fitted avatar and its measurements are on screen.
    AwaitAvatar,
    /// Turns "Edit avatar" on / off ("Done").
    EditOn,
    EditOff,
    /// Button down / pointer moved / button up, at a point of the avatar view
    /// (fractions of its width and height from its top-left corner); the primary button
    /// unless `"button": "secondary"`.
    Press {
        at: [f32; 2],
        #[serde(default)]
        button: Button,
    },
    Move {
        at: [f32; 2],
    },
    Release {
        at: [f32; 2],
        #[serde(default)]
        button: Button,
    },
    /// Takes the last hand edit back.
    Undo,
    /// Clicks a button of Operator > Edit avatar with the primary button (pressed in
    /// this frame, released in the next).
    Click {
        target: ClickTarget,
    },
    /// Exports the measurements and the avatar (OBJ) into this folder, as the operator's
    /// buttons do.
    Export {
        dir: String,
    },
    /// Writes `--ui-edits-out` and closes the window.
    Exit,
}

/// A pointer button.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Button {
    #[default]
    Primary,
    Secondary,
}

impl From<Button> for egui::PointerButton {
    fn from(b: Button) -> Self {
        match b {
            Button::Primary => egui::PointerButton::Primary,
            Button::Secondary => egui::PointerButton::Secondary,
        }
    }
}

/// The buttons a script can click.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ClickTarget {
    /// The "Edit avatar" toggle.
    EditAvatar,
    Undo,
    Done,
}

/// Why a script could not be read.
#[derive(Debug, thiserror::Error)]
pub enum ScriptError {
    #[error("{path}: {source}")]
    Read {
        path: String,
        source: std::io::Error,
    },
    #[error("{path} is not a UI script: {source}")]
    Parse {
        path: String,
        source: serde_json::Error,
    },
}

/// Reads a script file.
///
/// # Errors
/// The file cannot be read or is not a list of steps.
pub fn read_script(path: &Path) -> Result<Vec<ScriptStep>, ScriptError> {
    let p = path.display().to_string();
    let text = std::fs::read_to_string(path).map_err(|source| ScriptError::Read {
        path: p.clone(),
        source,
    })?;
    serde_json::from_str(&text).map_err(|source| ScriptError::Parse { path: p, source })
}

/// Plays a script, one step at most per screen frame.
#[derive(Debug, Clone)]
pub struct ScriptPlayer {
    steps: Vec<ScriptStep>,
    next: usize,
    waited: u64,
    /// Events due in the next frames, one a frame: a button goes down a frame after the
    /// pointer came (a pointer that jumps and presses in one frame would count the jump
    /// as a drag), and a click's release a frame after its press.
    queued: std::collections::VecDeque<egui::Event>,
}

impl ScriptPlayer {
    pub fn new(steps: Vec<ScriptStep>) -> ScriptPlayer {
        ScriptPlayer {
            steps,
            next: 0,
            waited: 0,
            queued: std::collections::VecDeque::new(),
        }
    }

    /// Every step has been played.
    pub fn finished(&self) -> bool {
        self.next >= self.steps.len() && self.queued.is_empty()
    }

    /// Called once per screen frame: the action due in this frame, if any
    /// (`avatar_ready`: a fitted avatar is on screen, for [`ScriptAction::AwaitAvatar`]).
    pub fn due(&mut self, avatar_ready: bool) -> Option<ScriptAction> {
        let step = self.steps.get(self.next)?;
        if self.waited < step.wait {
            self.waited += 1;
            return None;
        }
        if step.action == ScriptAction::AwaitAvatar && !avatar_ready {
            return None;
        }
        self.next += 1;
        self.waited = 0;
        Some(step.action.clone())
    }
}

impl super::StationApp {
    /// Plays the script's step due this frame into `raw` (pointer events) or the
    /// screen's state; keeps the screen painting until the script is finished.
    pub(super) fn play_script(&mut self, ctx: &egui::Context, raw: &mut egui::RawInput) {
        let ready = self.avatar_on_screen
            && self
                .current
                .as_ref()
                .is_some_and(|s| !s.measurements.is_empty());
        let Some(player) = self.script.as_mut() else {
            return;
        };
        let button = |pos, b: Button, pressed| egui::Event::PointerButton {
            pos,
            button: b.into(),
            pressed,
            modifiers: egui::Modifiers::NONE,
        };
        if let Some(event) = player.queued.pop_front() {
            raw.events.push(event);
            ctx.request_repaint();
            return;
        }
        let action = player.due(ready);
        if !player.finished() {
            ctx.request_repaint();
        }
        let Some(action) = action else {
            return;
        };
        let rect = self.layout.avatar;
        let at = |a: [f32; 2]| {
            rect.map(|r| r.min + egui::Vec2::new(a[0] * r.width(), a[1] * r.height()))
        };
        match action {
            ScriptAction::AwaitAvatar => {}
            ScriptAction::EditOn => self.edit.on = true,
            ScriptAction::EditOff => self.edit.on = false,
            ScriptAction::Press { at: a, .. }
            | ScriptAction::Move { at: a }
            | ScriptAction::Release { at: a, .. } => {
                let Some(pos) = at(a) else {
                    eprintln!("ui script: no avatar view to point at yet");
                    return;
                };
                raw.events.push(egui::Event::PointerMoved(pos));
                match action {
                    ScriptAction::Press { button: b, .. } => {
                        if let Some(p) = self.script.as_mut() {
                            p.queued.push_back(button(pos, b, true));
                        }
                    }
                    ScriptAction::Release { button: b, .. } => {
                        raw.events.push(button(pos, b, false))
                    }
                    _ => {}
                }
            }
            ScriptAction::Click { target } => {
                let b = self.edit.buttons;
                let rect = match target {
                    ClickTarget::EditAvatar => b.toggle,
                    ClickTarget::Undo => b.undo,
                    ClickTarget::Done => b.done,
                };
                let Some(pos) = rect.map(|r| r.center()) else {
                    eprintln!("ui script: the {target:?} button is not on screen");
                    return;
                };
                raw.events.push(egui::Event::PointerMoved(pos));
                if let Some(p) = self.script.as_mut() {
                    p.queued.push_back(button(pos, Button::Primary, true));
                    p.queued.push_back(button(pos, Button::Primary, false));
                }
            }
            ScriptAction::Undo => {
                if let Some(line) = self.edit.undo() {
                    self.log(line);
                }
            }
            ScriptAction::Export { dir } => {
                self.export_dir = dir;
                self.export_measurements();
                self.export_avatar(super::export::AvatarFormat::Obj);
            }
            ScriptAction::Exit => {
                self.write_edits_out();
                ctx.send_viewport_cmd(egui::ViewportCommand::Close);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn steps_come_after_their_waits_and_the_avatar() {
        let steps: Vec<ScriptStep> = serde_json::from_str(
            r#"[{"action": "await_avatar"}, {"wait": 2, "action": "press", "at": [0.5, 0.25]},
                {"action": "exit"}]"#,
        )
        .expect("script");
        let mut p = ScriptPlayer::new(steps);
        assert_eq!(p.due(false), None);
        assert_eq!(p.due(true), Some(ScriptAction::AwaitAvatar));
        assert_eq!(p.due(true), None);
        assert_eq!(p.due(true), None);
        assert_eq!(
            p.due(true),
            Some(ScriptAction::Press {
                at: [0.5, 0.25],
                button: Button::Primary
            })
        );
        assert_eq!(p.due(true), Some(ScriptAction::Exit));
        assert!(p.finished() && p.due(true).is_none());
    }
}
