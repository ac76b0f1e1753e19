//! Shared set-up of the fuzz targets.

/// Runs once per fuzz process: hides an installed `ffmpeg` (the MP4 reader's fallback
/// for streams OpenH264 cannot decode), so every run stays in-process and deterministic.
pub fn init() {
    std::env::set_var("PATH", "");
}
