//! Fuzz target `frame_image`: [`fitstation::fuzz::frame_image`] on each input (see that function).
#![no_main]

libfuzzer_sys::fuzz_target!(
    init: fitstation_fuzz::init(),
    |data: &[u8]| {
        let _ = fitstation::fuzz::frame_image(data);
    }
);
