//! Every integration test of the station in one binary: one link of the library instead of
//! one for each file, and the tests of all the files share the cores as they run.
//! `cargo test --release --test suite FILE::` runs one file's tests (`soak::`, say).
//! `tests/fuzz_seeds.rs` stays its own binary: `tools/fuzz.sh` builds and runs it alone.

mod common;
mod silhouette_common;
mod xvfb_common;

mod armpit_pockets;
mod calibrate_cli;
mod calibrate_errors;
mod calibrate_opencv;
mod calibrate_station;
mod cli_pipe;
mod deform_libigl;
mod deform_properties;
mod eval_truth;
mod fault_injection;
mod fit_survey;
mod fit_true_silhouettes;
mod fusion_camouflage;
mod fuzz_regressions;
mod handle_edit;
mod hip_level;
mod kill_outputs;
mod measure_body;
mod measure_python;
mod measure_shapes;
mod measure_template;
mod one_camera;
mod papercuts;
mod passer_by;
mod person_models;
mod recording_roundtrip;
mod side_view_lost;
mod silhouette_mesh;
mod silhouette_opencv;
mod silhouette_still;
mod silhouette_synth;
mod silhouette_synthetic;
mod silhouette_verdicts;
mod soak;
mod station_replay;
mod synth_projection;
mod synth_truth;
mod turn_on_the_mark;
mod ui_calibration_wizard;
mod ui_faults;
mod ui_handle_edit;
mod ui_kiosk_flow;
mod ui_xvfb;
