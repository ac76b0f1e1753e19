//! A reader that goes away early (`fitstation measure M --json | head`) ends the command
//! quietly, as with any Unix tool, instead of a panic on the closed pipe.

use std::io::Read;
use std::process::{Command, Stdio};

#[test]
fn a_closed_pipe_ends_the_command_without_a_panic() {
    let template = concat!(env!("CARGO_MANIFEST_DIR"), "/templates/makehuman-adult.obj");
    let mut child = Command::new(env!("CARGO_BIN_EXE_fitstation"))
        .args(["measure", template, "--json"])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("fitstation runs");
    // The reader goes away at once, long before the mesh is read and measured (tens of
    // milliseconds): the report's first line has nowhere to go.
    drop(child.stdout.take());
    let mut stderr = String::new();
    child
        .stderr
        .take()
        .expect("stderr")
        .read_to_string(&mut stderr)
        .expect("stderr readable");
    let status = child.wait().expect("fitstation ends");
    assert!(!stderr.contains("panicked"), "{stderr}");
    assert!(!status.success(), "a report nobody read is not a success");
}
