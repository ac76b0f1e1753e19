//! Progress lines on stderr: a line redrawn in place (`\r`) on a terminal, plain lines
//! when stderr is a file or a pipe (a log must not fill with carriage returns).

use std::io::{IsTerminal, Write};

/// How progress is shown.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ProgressStyle {
    /// Redraw one line in place (stderr is a terminal).
    InPlace,
    /// One plain line per update (stderr is a file or a pipe).
    Lines,
}

impl ProgressStyle {
    /// The style for this process's stderr.
    pub fn for_stderr() -> ProgressStyle {
        if std::io::stderr().is_terminal() {
            ProgressStyle::InPlace
        } else {
            ProgressStyle::Lines
        }
    }
}

/// Prints one progress update in `style`; `last` ends the in-place line.
pub fn show(style: ProgressStyle, text: &str, last: bool) {
    let mut e = std::io::stderr().lock();
    let _ = match style {
        ProgressStyle::InPlace if last => writeln!(e, "\r{text}"),
        ProgressStyle::InPlace => write!(e, "\r{text}"),
        ProgressStyle::Lines => writeln!(e, "{}", text.trim_end()),
    };
    let _ = e.flush();
}
