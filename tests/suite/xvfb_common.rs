//! What the window tests under Xvfb share.

use std::process::{Command, Stdio};

/// True when `tool` is on the PATH.
pub fn have(tool: &str) -> bool {
    Command::new("sh")
        .arg("-c")
        .arg(format!("command -v {tool}"))
        .stdout(Stdio::null())
        .status()
        .map(|s| s.success())
        .unwrap_or(false)
}

/// Runs the `fitstation` binary `bin` with `args` in a window under `xvfb-run` (a
/// 1600x900 screen) and waits for it, at most `timeout`: a run still going then is ended
/// with its Xvfb (the window runs in its own process group) and is an error. The output,
/// whatever the exit status.
///
/// One window at a time: the window tests share one test binary, and two `xvfb-run -a`
/// started together can pick the same display number.
pub fn run_in_xvfb(
    bin: &str,
    args: &[std::ffi::OsString],
    timeout: std::time::Duration,
) -> Result<std::process::Output, String> {
    use std::os::unix::process::CommandExt;
    static ONE_WINDOW: std::sync::Mutex<()> = std::sync::Mutex::new(());
    // A window test that panicked while holding the lock leaves nothing to repair.
    let _window = ONE_WINDOW.lock().unwrap_or_else(|e| e.into_inner());
    let mut child = Command::new("xvfb-run")
        .args(["-a", "-s", "-screen 0 1600x900x24", bin])
        .args(args)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .process_group(0)
        .spawn()
        .map_err(|e| format!("cannot start xvfb-run: {e}"))?;
    let start = std::time::Instant::now();
    loop {
        match child.try_wait() {
            Ok(Some(_)) => break,
            Ok(None) if start.elapsed() > timeout => {
                let _ = Command::new("kill")
                    .arg("-TERM")
                    .arg(format!("-{}", child.id()))
                    .status();
                let _ = child.kill();
                let _ = child.wait();
                return Err(format!("the window did not finish within {timeout:?}"));
            }
            Ok(None) => std::thread::sleep(std::time::Duration::from_millis(200)),
            Err(e) => return Err(e.to_string()),
        }
    }
    child.wait_with_output().map_err(|e| e.to_string())
}
