//! Decoding through an installed ffmpeg (a raw-video pipe) for what OpenH264 cannot.

use super::*;

/// Frames of a video decoded by an installed `ffmpeg` into raw RGB, read sequentially
/// from its output (going back restarts it).
pub(super) struct FfmpegPipe {
    pub(super) path: PathBuf,
    pub(super) width: u32,
    pub(super) height: u32,
    pub(super) child: Option<std::process::Child>,
    /// Index of the next frame the pipe gives.
    pub(super) next: usize,
}

impl FfmpegPipe {
    pub(super) fn new(path: &Path, width: u32, height: u32) -> Result<FfmpegPipe, String> {
        if width == 0 || height == 0 {
            return Err("the track header gives no frame size".into());
        }
        let mut p = FfmpegPipe {
            path: path.to_path_buf(),
            width,
            height,
            child: None,
            next: 0,
        };
        p.restart()?;
        Ok(p)
    }

    pub(super) fn restart(&mut self) -> Result<(), String> {
        self.stop();
        let child = std::process::Command::new("ffmpeg")
            .args(["-v", "error", "-nostdin", "-i"])
            .arg(&self.path)
            .args([
                "-fps_mode",
                "passthrough",
                "-f",
                "rawvideo",
                "-pix_fmt",
                "rgb24",
                "-",
            ])
            .stdin(std::process::Stdio::null())
            .stdout(std::process::Stdio::piped())
            .stderr(std::process::Stdio::null())
            .spawn()
            .map_err(|e| format!("cannot run ffmpeg: {e}"))?;
        self.child = Some(child);
        self.next = 0;
        Ok(())
    }

    pub(super) fn stop(&mut self) {
        if let Some(mut c) = self.child.take() {
            let _ = c.kill();
            let _ = c.wait();
        }
    }

    pub(super) fn frame(&mut self, k: usize) -> Result<RgbImage, String> {
        if k < self.next || self.child.is_none() {
            self.restart()?;
        }
        let mut img = RgbImage::new(self.width, self.height);
        loop {
            let out = self
                .child
                .as_mut()
                .and_then(|c| c.stdout.as_mut())
                .ok_or("no ffmpeg output")?;
            out.read_exact(&mut img)
                .map_err(|e| format!("frame {}: {e} (stream ended?)", self.next))?;
            self.next += 1;
            if self.next == k + 1 {
                return Ok(img);
            }
        }
    }
}

impl Drop for FfmpegPipe {
    fn drop(&mut self) {
        self.stop();
    }
}
