//! Fuzz target `recording_layout`: [`fitstation::fuzz::recording_layout`] on each input (see that function).
#![no_main]

libfuzzer_sys::fuzz_target!(
    init: fitstation_fuzz::init(),
    |data: &[u8]| {
        let _ = fitstation::fuzz::recording_layout(data);
    }
);
