//! Fuzz target `shape_library`: [`fitstation::fuzz::shape_library`] on each input (see that function).
#![no_main]

libfuzzer_sys::fuzz_target!(
    init: fitstation_fuzz::init(),
    |data: &[u8]| {
        let _ = fitstation::fuzz::shape_library(data);
    }
);
