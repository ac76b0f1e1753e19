//! Fuzz target `h264_sample`: [`fitstation::fuzz::h264_sample`] on each input (see that function).
#![no_main]

libfuzzer_sys::fuzz_target!(
    init: fitstation_fuzz::init(),
    |data: &[u8]| {
        let _ = fitstation::fuzz::h264_sample(data);
    }
);
