//! An optional timeline of the screen's pipeline, for finding where a frame's time
//! goes: with `FITSTATION_UI_TRACE=PATH` in the environment every pair read, handed
//! on, processed and published, every screen frame's start, end of UI code and
//! present, and every render of the avatar is noted (milliseconds since the first
//! event, the event's name, a number: pair index or frame count), and the list is
//! written to PATH when the screen closes, one event a line (names without spaces). Without the variable
//! (read once per process) noting an event costs one atomic load.

use std::sync::{Mutex, OnceLock};
use std::time::Instant;

/// Events kept at most (about ten minutes of a 30 fps replay); later ones are dropped.
const MAX_EVENTS: usize = 200_000;

struct Timeline {
    path: std::path::PathBuf,
    start: Instant,
    events: Mutex<Vec<(f64, &'static str, u64)>>,
}

fn timeline() -> Option<&'static Timeline> {
    static T: OnceLock<Option<Timeline>> = OnceLock::new();
    T.get_or_init(|| {
        std::env::var_os("FITSTATION_UI_TRACE").map(|p| Timeline {
            path: p.into(),
            start: Instant::now(),
            events: Mutex::new(Vec::new()),
        })
    })
    .as_ref()
}

/// Notes the event `name` with the number `value` now (when tracing is on).
pub fn ev(name: &'static str, value: u64) {
    let Some(t) = timeline() else {
        return;
    };
    let ms = t.start.elapsed().as_secs_f64() * 1e3;
    if let Ok(mut e) = t.events.lock() {
        if e.len() < MAX_EVENTS {
            e.push((ms, name, value));
        }
    }
}

/// Writes the timeline to its file (when tracing is on); says so on stderr if it
/// cannot.
pub fn dump() {
    let Some(t) = timeline() else {
        return;
    };
    let text: String = match t.events.lock() {
        Ok(e) => e
            .iter()
            .map(|(ms, name, v)| format!("{ms:.3} {name} {v}\n"))
            .collect(),
        Err(_) => return,
    };
    if let Err(e) = crate::io::atomic::write(&t.path, text) {
        eprintln!("cannot write the timeline {}: {e}", t.path.display());
    }
}
