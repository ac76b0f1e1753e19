//! A file cut before its index: pictures recovered from the media data alone.

use super::*;

/// Where a picture's NAL units are in the file (recovery without an index).
#[derive(Debug, Clone)]
pub(super) struct RawPicture {
    /// (offset, length) of each NAL unit belonging to this picture, file order.
    pub(super) nals: Vec<(u64, u32)>,
    /// An IDR picture (decoding may start here).
    pub(super) idr: bool,
}

/// Walks the top-level boxes to the `mdat` payload and splits it into pictures: NAL
/// units are 4-byte length-prefixed; a picture ends with its slice (one slice per
/// picture, as written here). Stops at the first NAL that runs past the end.
pub(super) fn scan_mdat(path: &Path, size: u64) -> Result<Vec<RawPicture>, VideoError> {
    let io = |source| VideoError::Io {
        file: path.to_path_buf(),
        source,
    };
    let mut f = BufReader::new(File::open(path).map_err(io)?);
    let mut pos = 0u64;
    let mut head = [0u8; 8];
    while size >= 8 && pos <= size - 8 {
        f.seek(SeekFrom::Start(pos)).map_err(io)?;
        f.read_exact(&mut head).map_err(io)?;
        let mut box_size = u32::from_be_bytes([head[0], head[1], head[2], head[3]]) as u64;
        let kind = &head[4..8];
        let mut header = 8u64;
        if box_size == 1 {
            let mut big = [0u8; 8];
            f.read_exact(&mut big).map_err(io)?;
            box_size = u64::from_be_bytes(big);
            header = 16;
        }
        if kind == b"mdat" {
            // An unfinished file still holds the placeholder size of an empty mdat (the
            // mp4 crate writes the real size last): then the media data run to the end.
            let end = if box_size <= header + 8 || box_size > size - pos {
                size
            } else {
                pos + box_size
            };
            let mut payload = pos + header;
            // The mp4 crate reserves 8 bytes for a 64-bit size as a `wide` box inside.
            let mut wide = [0u8; 8];
            if payload + 8 <= end && f.read_exact(&mut wide).is_ok() && &wide[4..8] == b"wide" {
                payload += 8;
            }
            return scan_nals(&mut f, payload, end, path);
        }
        // A size below the header's would not move on; one past the end ends the walk
        // (a 64-bit size can be anything).
        match pos.checked_add(box_size) {
            Some(next) if box_size >= 8 => pos = next,
            _ => break,
        }
    }
    Err(verr(
        path,
        "no media data (mdat) found: not an MP4 file or cut before any frame",
    ))
}

pub(super) fn scan_nals(
    f: &mut BufReader<File>,
    start: u64,
    end: u64,
    path: &Path,
) -> Result<Vec<RawPicture>, VideoError> {
    let io = |source| VideoError::Io {
        file: path.to_path_buf(),
        source,
    };
    let mut pictures = Vec::new();
    let mut current = RawPicture {
        nals: Vec::new(),
        idr: false,
    };
    let mut pos = start;
    let mut len4 = [0u8; 4];
    let mut first = [0u8; 1];
    while pos + 5 <= end {
        f.seek(SeekFrom::Start(pos)).map_err(io)?;
        f.read_exact(&mut len4).map_err(io)?;
        let n = u32::from_be_bytes(len4);
        if n == 0 || pos + 4 + n as u64 > end {
            break;
        }
        f.read_exact(&mut first).map_err(io)?;
        current.nals.push((pos + 4, n));
        let kind = first[0] & 0x1f;
        if kind == NAL_IDR || kind == NAL_SLICE {
            current.idr = kind == NAL_IDR;
            pictures.push(std::mem::replace(
                &mut current,
                RawPicture {
                    nals: Vec::new(),
                    idr: false,
                },
            ));
        }
        pos += 4 + n as u64;
    }
    Ok(pictures)
}
