//! Files that cannot be half-written.
//!
//! A file is written to a temporary file in the same folder (`.NAME.tmp-PID`), flushed
//! and fsynced, then renamed over its final name (rename is atomic within a file system
//! on POSIX), and the folder is fsynced so the rename itself survives a power cut. A
//! process killed at any point leaves the old file (or none) and at worst a hidden
//! temporary, which the next write of the same name removes once its writer is gone.
//!
//! Recordings are not rewritten whole: their frames are each written atomically and
//! appended under new names (an MP4 stream is recovered from its media data when cut
//! before its index, see `recording::h264`), so a cut recording replays up to the cut.

use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

/// Why an output could not be written.
#[derive(Debug, thiserror::Error)]
pub enum AtomicError {
    /// The output path names an existing file where a folder is needed.
    #[error("{0} is an existing file, not a folder: give a folder path (or remove the file)")]
    FileNotFolder(PathBuf),
    /// The output path names an existing folder where a file is needed.
    #[error("{0} is an existing folder, not a file: give a file path")]
    FolderNotFile(PathBuf),
    #[error("{path}: {source}")]
    Io {
        path: PathBuf,
        source: std::io::Error,
    },
}

impl AtomicError {
    /// The reason without the path (for errors that print the path themselves).
    pub fn cause(&self) -> String {
        match self {
            AtomicError::Io { source, .. } => source.to_string(),
            other => other.to_string(),
        }
    }
}

impl From<AtomicError> for std::io::Error {
    fn from(e: AtomicError) -> Self {
        match e {
            AtomicError::Io { path, source } => {
                std::io::Error::new(source.kind(), format!("{}: {source}", path.display()))
            }
            other => std::io::Error::other(other.to_string()),
        }
    }
}

fn io_err(path: &Path) -> impl FnOnce(std::io::Error) -> AtomicError + '_ {
    move |source| AtomicError::Io {
        path: path.to_path_buf(),
        source,
    }
}

/// Prefix of the temporary name of `path`'s file: `.NAME.tmp-`.
fn temp_prefix(path: &Path) -> String {
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| "out".into());
    format!(".{name}.tmp-")
}

/// The folder a file path lives in (`.` for a bare name).
fn parent_of(path: &Path) -> &Path {
    path.parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."))
}

/// True when a temporary name is one this module made (`.NAME.tmp-PID` or
/// `.NAME.tmp-PID-N`).
pub fn is_temporary(name: &str) -> bool {
    name.starts_with('.') && name.contains(".tmp-")
}

/// Checks that `dir` can be an output folder: neither it nor a parent is a file.
///
/// # Errors
/// [`AtomicError::FileNotFolder`] naming the file.
pub fn check_dir(dir: &Path) -> Result<(), AtomicError> {
    for a in dir.ancestors() {
        if a.as_os_str().is_empty() {
            break;
        }
        if a.is_file() {
            return Err(AtomicError::FileNotFolder(a.to_path_buf()));
        }
    }
    Ok(())
}

/// Creates a folder for outputs (and its parents); an existing file there is said in
/// words instead of the system's "File exists".
///
/// # Errors
/// [`AtomicError::FileNotFolder`] when `dir` or one of its parents is a file; any other
/// I/O error with the path.
pub fn create_dir(dir: &Path) -> Result<(), AtomicError> {
    check_dir(dir)?;
    std::fs::create_dir_all(dir).map_err(io_err(dir))
}

/// Checks that `path` can be an output file: not an existing folder, and its folder
/// not a file. Creates the folder.
///
/// # Errors
/// [`AtomicError::FolderNotFile`] or [`AtomicError::FileNotFolder`], or the I/O error.
pub fn prepare_file(path: &Path) -> Result<(), AtomicError> {
    if path.is_dir() {
        return Err(AtomicError::FolderNotFile(path.to_path_buf()));
    }
    create_dir(parent_of(path))
}

/// Whether a process id is still running (Linux `/proc`; elsewhere assumed running).
fn process_alive(pid: u32) -> bool {
    if !Path::new("/proc/self").exists() {
        return true;
    }
    Path::new("/proc").join(pid.to_string()).exists()
}

/// Removes the temporaries left in `path`'s folder by writers that are gone (killed
/// mid-write), once per folder and process (a recording writes thousands of frames into
/// one folder: one scan, not one per frame).
fn remove_stale_temporaries(path: &Path) {
    static SWEPT: std::sync::Mutex<Vec<PathBuf>> = std::sync::Mutex::new(Vec::new());
    let dir = parent_of(path).to_path_buf();
    match SWEPT.lock() {
        Ok(mut swept) if !swept.contains(&dir) => swept.push(dir.clone()),
        _ => return,
    }
    let Ok(entries) = std::fs::read_dir(&dir) else {
        return;
    };
    for e in entries.flatten() {
        let name = e.file_name().to_string_lossy().into_owned();
        if !is_temporary(&name) {
            continue;
        }
        let pid = name
            .rsplit_once(".tmp-")
            .and_then(|(_, rest)| rest.split('-').next())
            .and_then(|p| p.parse::<u32>().ok());
        if pid.is_some_and(|p| p != std::process::id() && !process_alive(p)) {
            let _ = std::fs::remove_file(e.path());
        }
    }
}

/// Fsyncs a folder so a rename in it is durable (best effort: not every platform can
/// open a folder).
fn sync_dir(dir: &Path) {
    if let Ok(d) = File::open(dir) {
        let _ = d.sync_all();
    }
}

/// A file being written under a temporary name; [`AtomicFile::commit`] puts it in place.
/// Dropped without a commit, the temporary is removed and the old file stays.
pub struct AtomicFile {
    path: PathBuf,
    temp: PathBuf,
    writer: Option<BufWriter<File>>,
}

/// Distinguishes temporaries of the same name made by one process.
static TEMP_COUNTER: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);

impl AtomicFile {
    /// Opens a temporary beside `path` (creating the folder).
    ///
    /// # Errors
    /// See [`prepare_file`]; the temporary cannot be created.
    pub fn create(path: &Path) -> Result<AtomicFile, AtomicError> {
        prepare_file(path)?;
        remove_stale_temporaries(path);
        let n = TEMP_COUNTER.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        let temp = parent_of(path).join(format!("{}{}-{n}", temp_prefix(path), std::process::id()));
        let file = File::create(&temp).map_err(io_err(&temp))?;
        Ok(AtomicFile {
            path: path.to_path_buf(),
            temp,
            writer: Some(BufWriter::new(file)),
        })
    }

    /// The final path.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// The writer of the temporary.
    pub fn writer(&mut self) -> &mut BufWriter<File> {
        self.writer
            .as_mut()
            .expect("AtomicFile writer taken only by commit")
    }

    /// Flushes and fsyncs the temporary (the data is on disk, not yet in place).
    fn sync(&mut self) -> Result<(), AtomicError> {
        let temp = self.temp.clone();
        let w = self.writer();
        w.flush().map_err(io_err(&temp))?;
        w.get_ref().sync_all().map_err(io_err(&temp))
    }

    /// Fsyncs the data and renames the temporary over the final path.
    ///
    /// # Errors
    /// Flush, fsync or rename failed (the old file is left as it was).
    pub fn commit(mut self) -> Result<(), AtomicError> {
        self.sync()?;
        self.writer = None;
        if let Err(e) = std::fs::rename(&self.temp, &self.path) {
            let _ = std::fs::remove_file(&self.temp);
            return Err(io_err(&self.path)(e));
        }
        sync_dir(parent_of(&self.path));
        Ok(())
    }
}

impl Write for AtomicFile {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        self.writer().write(buf)
    }
    fn flush(&mut self) -> std::io::Result<()> {
        self.writer().flush()
    }
}

impl std::io::Seek for AtomicFile {
    fn seek(&mut self, pos: std::io::SeekFrom) -> std::io::Result<u64> {
        self.writer().seek(pos)
    }
}

impl Drop for AtomicFile {
    fn drop(&mut self) {
        if self.writer.take().is_some() {
            let _ = std::fs::remove_file(&self.temp);
        }
    }
}

/// Writes `bytes` to `path` atomically.
///
/// # Errors
/// See [`AtomicFile::create`] and [`AtomicFile::commit`].
pub fn write(path: &Path, bytes: impl AsRef<[u8]>) -> Result<(), AtomicError> {
    let mut f = AtomicFile::create(path)?;
    let temp = f.temp.clone();
    f.write_all(bytes.as_ref()).map_err(io_err(&temp))?;
    f.commit()
}

/// Writes `path` atomically through `fill`, which writes the content into the
/// temporary (an encoder, a formatter). An error from `fill` leaves the old file.
///
/// # Errors
/// `fill`'s error, or see [`AtomicFile::create`] and [`AtomicFile::commit`].
pub fn write_with<E>(
    path: &Path,
    fill: impl FnOnce(&mut AtomicFile) -> Result<(), E>,
) -> Result<(), E>
where
    E: From<AtomicError>,
{
    let mut f = AtomicFile::create(path)?;
    fill(&mut f)?;
    f.commit()?;
    Ok(())
}

/// Copies `from` to `to` atomically (a backup that is whole or absent).
///
/// # Errors
/// `from` unreadable, or see [`write`].
pub fn copy(from: &Path, to: &Path) -> Result<(), AtomicError> {
    let bytes = std::fs::read(from).map_err(io_err(from))?;
    write(to, bytes)
}

/// Writes several files so each is whole: all are written and fsynced under temporary
/// names first, then renamed into place one after another. A failure before the renames
/// leaves every old file; a kill during them leaves each file old or new, never cut.
///
/// # Errors
/// The first write, fsync or rename that failed.
pub fn write_all(files: &[(&Path, &[u8])]) -> Result<(), AtomicError> {
    let mut staged = Vec::with_capacity(files.len());
    for (path, bytes) in files {
        let mut f = AtomicFile::create(path)?;
        let temp = f.temp.clone();
        f.write_all(bytes).map_err(io_err(&temp))?;
        f.sync()?;
        staged.push(f);
    }
    for f in staged {
        f.commit()?;
    }
    Ok(())
}

/// Saves an image atomically, its format chosen by the extension (PNG, JPEG).
///
/// # Errors
/// An unknown extension, an encoder error, or see [`write_with`].
pub fn save_image<P, C>(path: &Path, img: &image::ImageBuffer<P, C>) -> Result<(), AtomicError>
where
    P: image::Pixel + image::PixelWithColorType,
    [P::Subpixel]: image::EncodableLayout,
    C: std::ops::Deref<Target = [P::Subpixel]>,
{
    let format = image::ImageFormat::from_path(path).map_err(|e| AtomicError::Io {
        path: path.to_path_buf(),
        source: std::io::Error::other(e.to_string()),
    })?;
    write_with(path, |f| {
        img.write_to(f, format).map_err(|e| AtomicError::Io {
            path: path.to_path_buf(),
            source: std::io::Error::other(e.to_string()),
        })
    })
}

/// Creates a file that is written as a stream and stays readable when cut (an MP4
/// whose media data is recovered without its index). Not atomic: use only for formats
/// whose readers recover a cut file.
///
/// # Errors
/// See [`prepare_file`]; the file cannot be created.
pub fn create_recoverable(path: &Path) -> Result<File, AtomicError> {
    prepare_file(path)?;
    File::create(path).map_err(io_err(path))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scratch(name: &str) -> PathBuf {
        let d =
            std::env::temp_dir().join(format!("fitstation-atomic-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d).expect("scratch folder");
        d
    }

    fn names(dir: &Path) -> Vec<String> {
        let mut v: Vec<String> = std::fs::read_dir(dir)
            .expect("read_dir")
            .flatten()
            .map(|e| e.file_name().to_string_lossy().into_owned())
            .collect();
        v.sort();
        v
    }

    #[test]
    fn write_replaces_and_leaves_no_temporary() {
        let d = scratch("write");
        let p = d.join("a.json");
        write(&p, b"old").unwrap();
        write(&p, b"new").unwrap();
        assert_eq!(std::fs::read(&p).unwrap(), b"new");
        assert_eq!(names(&d), vec!["a.json".to_string()]);
        std::fs::remove_dir_all(&d).ok();
    }

    #[test]
    fn failed_fill_keeps_the_old_file() {
        let d = scratch("fail");
        let p = d.join("a.txt");
        write(&p, b"old").unwrap();
        let r: Result<(), AtomicError> = write_with(&p, |f| {
            f.write_all(b"half").map_err(io_err(Path::new("x")))?;
            Err(AtomicError::Io {
                path: p.clone(),
                source: std::io::Error::other("encoder failed"),
            })
        });
        assert!(r.is_err());
        assert_eq!(std::fs::read(&p).unwrap(), b"old");
        assert_eq!(names(&d), vec!["a.txt".to_string()]);
        std::fs::remove_dir_all(&d).ok();
    }

    #[test]
    fn stale_temporaries_of_dead_writers_are_removed() {
        let d = scratch("stale");
        let p = d.join("r.json");
        // No process has pid 4000000000 (above Linux's pid_max).
        std::fs::write(d.join(".r.json.tmp-4000000000-0"), b"cut").unwrap();
        write(&p, b"x").unwrap();
        assert_eq!(names(&d), vec!["r.json".to_string()]);
        std::fs::remove_dir_all(&d).ok();
    }

    #[test]
    fn a_file_where_a_folder_is_needed_is_said_in_words() {
        let d = scratch("filedir");
        let f = d.join("out");
        std::fs::write(&f, b"i am a file").unwrap();
        let e = create_dir(&f.join("sub")).unwrap_err().to_string();
        assert!(e.contains("is an existing file, not a folder"), "{e}");
        let e = write(&d, b"x").unwrap_err().to_string();
        assert!(e.contains("is an existing folder, not a file"), "{e}");
        std::fs::remove_dir_all(&d).ok();
    }

    #[test]
    fn write_all_puts_every_file_in_place() {
        let d = scratch("all");
        let (a, b) = (d.join("a"), d.join("b"));
        write_all(&[(&a, b"1"), (&b, b"2")]).unwrap();
        assert_eq!(std::fs::read(&a).unwrap(), b"1");
        assert_eq!(std::fs::read(&b).unwrap(), b"2");
        assert_eq!(names(&d), vec!["a".to_string(), "b".to_string()]);
        std::fs::remove_dir_all(&d).ok();
    }
}
