//! Fuzz target `template_sidecar`: [`fitstation::fuzz::template_sidecar`] on each input (see that function).
#![no_main]

libfuzzer_sys::fuzz_target!(
    init: fitstation_fuzz::init(),
    |data: &[u8]| {
        let _ = fitstation::fuzz::template_sidecar(data);
    }
);
