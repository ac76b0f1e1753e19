//! Fuzz target `mp4`: [`fitstation::fuzz::mp4`] on each input (see that function).
#![no_main]

libfuzzer_sys::fuzz_target!(
    init: fitstation_fuzz::init(),
    |data: &[u8]| {
        let _ = fitstation::fuzz::mp4(data);
    }
);
