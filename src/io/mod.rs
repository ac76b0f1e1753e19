//! File utilities shared by every stage that writes or caches files: atomic writes
//! ([`atomic`]), the one documented cache directory for downloaded data ([`cache`]) and
//! progress output that knows whether stderr is a terminal ([`progress`]), and the C
//! allocator's statistics and trimming between shoppers ([`heap`]).
//!
//! Every file the station writes goes through [`atomic`]: a reader (or the next run
//! after a crash or a kill) sees either the old file, no file, or the complete new one.

pub mod atomic;
pub mod cache;
pub mod heap;
pub mod progress;
