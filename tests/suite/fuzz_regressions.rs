//! Every input the fuzz targets (`fuzz/`, `tools/fuzz.sh`) found crashing, hanging or
//! exhausting memory, saved under `tests/fuzz_cases/<target>/`, runs here through the
//! same entry point (`fitstation::fuzz::run`) under plain `cargo test`: none may panic,
//! and each must be refused with an error, except the cases whose file name starts with
//! `ok-` (inputs that are valid and used to crash a later stage).

use std::path::Path;
use std::time::{Duration, Instant};

/// Longest any one saved case may take (the fuzz runs allow 10 s; a fixed case is fast).
const MAX_CASE_TIME: Duration = Duration::from_secs(5);

#[test]
fn saved_fuzz_cases_are_refused_without_panic() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fuzz_cases");
    let mut ran = 0;
    let mut failures = Vec::new();
    for target in fitstation::fuzz::TARGETS {
        let Ok(dir) = std::fs::read_dir(root.join(target)) else {
            continue;
        };
        let mut files: Vec<_> = dir.filter_map(|e| e.ok()).map(|e| e.path()).collect();
        files.sort();
        for file in files.iter().filter(|f| f.is_file()) {
            let name = file
                .file_name()
                .unwrap_or_default()
                .to_string_lossy()
                .into_owned();
            if name.starts_with('.') || name.ends_with(".md") {
                continue;
            }
            let data = std::fs::read(file).expect("a committed case file reads");
            let started = Instant::now();
            let outcome = std::panic::catch_unwind(|| fitstation::fuzz::run(target, &data));
            let took = started.elapsed();
            ran += 1;
            let case = format!("{target}/{name}");
            match outcome {
                Err(_) => failures.push(format!("{case}: panicked")),
                Ok(Ok(())) if !name.starts_with("ok-") => {
                    failures.push(format!("{case}: accepted, expected an error"))
                }
                Ok(Err(e)) if name.starts_with("ok-") => {
                    failures.push(format!("{case}: refused ({e}), expected accepted"))
                }
                Ok(r) => eprintln!("{case}: {r:?} in {took:?}"),
            }
            if took > MAX_CASE_TIME {
                failures.push(format!("{case}: took {took:?}"));
            }
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
    eprintln!("{ran} saved fuzz case(s) ran");
}

#[test]
fn every_fuzz_target_has_an_entry_point() {
    for target in fitstation::fuzz::TARGETS {
        assert!(
            Path::new(env!("CARGO_MANIFEST_DIR"))
                .join(format!("fuzz/fuzz_targets/{target}.rs"))
                .is_file(),
            "{target}"
        );
        // An empty input is refused, never a panic.
        let _ = fitstation::fuzz::run(target, b"");
    }
    assert!(fitstation::fuzz::run("no_such_target", b"").is_err());
}
