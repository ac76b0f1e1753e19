//! Fuzz target `station_yaml`: [`fitstation::fuzz::station_yaml`] on each input (see that function).
#![no_main]

libfuzzer_sys::fuzz_target!(
    init: fitstation_fuzz::init(),
    |data: &[u8]| {
        let _ = fitstation::fuzz::station_yaml(data);
    }
);
