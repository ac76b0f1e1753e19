//! Papercuts a new user hit (issue 21 item 5), through the real binary: `bench deform`
//! with no arguments on a fresh machine, no temporary data path in the sources,
//! progress without carriage returns when stderr is not a terminal, and an output path
//! that is an existing file said in words.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn exe() -> &'static str {
    env!("CARGO_BIN_EXE_fitstation")
}

fn repo() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

/// A fresh scratch folder (a machine with nothing in its cache).
fn scratch(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("fitstation-papercut-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).expect("scratch folder");
    d
}

/// Runs the binary in `cwd` as a new user would: no backtraces, an empty cache.
fn run_in(cwd: &Path, args: &[&str]) -> Output {
    Command::new(exe())
        .current_dir(cwd)
        .args(args)
        .env_remove("RUST_BACKTRACE")
        .env("FITSTATION_CACHE", cwd.join("cache"))
        .output()
        .expect("run fitstation")
}

fn text(b: &[u8]) -> String {
    String::from_utf8_lossy(b).into_owned()
}

#[test]
fn bench_deform_runs_with_no_arguments_on_a_fresh_machine() {
    let d = scratch("bench");
    let o = run_in(&d, &["bench", "deform"]);
    let out = text(&o.stdout);
    assert!(o.status.success(), "{out}\n{}", text(&o.stderr));
    assert!(
        out.contains("mesh: 13380 vertices"),
        "not the template: {out}"
    );
    assert!(out.contains("fast decode (rest)"), "{out}");
    // The peer's files go to the cache directory, not a hard-coded temporary path.
    assert!(d.join("cache/bench-deform/mesh.obj").is_file(), "{out}");
    // The raw MakeHuman file is optional and its absence is said in one line.
    let o = run_in(&d, &["bench", "deform", "--makehuman", "missing/base.obj"]);
    assert!(!o.status.success());
    let err = text(&o.stderr);
    assert!(
        err.contains("reading the raw MakeHuman mesh missing/base.obj"),
        "{err}"
    );
    let _ = std::fs::remove_dir_all(&d);
}

/// Every `.rs` file under `dir`.
fn rust_files(dir: &Path, out: &mut Vec<PathBuf>) {
    for e in std::fs::read_dir(dir).expect("read src").flatten() {
        let p = e.path();
        if p.is_dir() {
            rust_files(&p, out);
        } else if p.extension().is_some_and(|x| x == "rs") {
            out.push(p);
        }
    }
}

#[test]
fn no_source_file_hard_codes_a_temporary_data_path() {
    let mut files = Vec::new();
    rust_files(&repo().join("src"), &mut files);
    assert!(files.len() > 50);
    let mut hits = Vec::new();
    for f in files {
        let s = std::fs::read_to_string(&f).expect("read source");
        for (n, line) in s.lines().enumerate() {
            if line.contains("\"/tmp") {
                hits.push(format!("{}:{}: {}", f.display(), n + 1, line.trim()));
            }
        }
    }
    assert!(
        hits.is_empty(),
        "temporary paths in src/:\n{}",
        hits.join("\n")
    );
}

#[test]
fn progress_prints_plain_lines_when_stderr_is_not_a_terminal() {
    let d = scratch("progress");
    let demo = repo().join("recordings/demo");
    let demo = demo.to_str().expect("utf-8 path");
    // stderr is a pipe here.
    let o = run_in(&d, &["replay", demo]);
    assert!(o.status.success(), "{}", text(&o.stderr));
    let err = text(&o.stderr);
    assert!(
        !err.contains('\r'),
        "carriage return in piped replay progress: {err:?}"
    );
    assert!(err.lines().any(|l| l.starts_with("frame")), "{err}");
    // The station masks `eval` scores go to a scratch folder it removes.
    let tmp = d.join("tmp");
    std::fs::create_dir_all(&tmp).expect("temp folder");
    let o = Command::new(exe())
        .current_dir(&d)
        .args(["eval", demo, demo])
        .env_remove("RUST_BACKTRACE")
        .env("FITSTATION_CACHE", d.join("cache"))
        .env("TMPDIR", &tmp)
        .output()
        .expect("run fitstation");
    let left: Vec<_> = std::fs::read_dir(&tmp)
        .expect("temp folder")
        .flatten()
        .map(|e| e.file_name())
        .collect();
    assert!(left.is_empty(), "eval left {left:?} in its temp folder");
    let err = text(&o.stderr);
    assert!(
        !err.contains('\r'),
        "carriage return in piped eval progress: {err:?}"
    );
    assert!(err.contains("] 2/2"), "no progress lines: {err}");
    let _ = std::fs::remove_dir_all(&d);
}

/// The command failed with one line naming the file as a file.
fn says_existing_file(o: &Output, what: &str) {
    assert!(!o.status.success(), "{what}: succeeded");
    let err = text(&o.stderr);
    let lines: Vec<&str> = err.lines().filter(|l| !l.trim().is_empty()).collect();
    assert_eq!(lines.len(), 1, "{what}: not one line: {err}");
    assert!(
        lines[0].contains("is an existing file, not a folder"),
        "{what}: {err}"
    );
}

#[test]
fn an_output_path_that_is_an_existing_file_is_said_in_words() {
    let d = scratch("outfile");
    std::fs::write(d.join("taken"), b"a file").expect("file");
    let demo = repo().join("recordings/demo");
    let demo = demo.to_str().expect("utf-8 path");
    says_existing_file(
        &run_in(&d, &["replay", demo, "--out", "taken"]),
        "replay --out",
    );
    says_existing_file(
        &run_in(&d, &["replay", demo, "--record", "taken/rec"]),
        "replay --record",
    );
    says_existing_file(
        &run_in(
            &d,
            &[
                "fit", "--front", "f.png", "--side", "s.png", "--calib", "c.yaml", "--out", "taken",
            ],
        ),
        "fit --out",
    );
    says_existing_file(&run_in(&d, &["synth", "--out", "taken"]), "synth --out");
    says_existing_file(
        &run_in(&d, &["bench", "deform", "--out", "taken"]),
        "bench deform --out",
    );
    // A recording folder that already holds a recording is not overwritten.
    std::fs::create_dir_all(d.join("rec")).expect("rec");
    std::fs::write(d.join("rec/station.yaml"), b"%YAML:1.0\n").expect("station");
    let o = run_in(&d, &["replay", demo, "--record", "rec"]);
    assert!(!o.status.success());
    assert!(
        text(&o.stderr).contains("already holds a recording"),
        "{}",
        text(&o.stderr)
    );
    let _ = std::fs::remove_dir_all(&d);
}

/// Runs the binary with no display and an empty cache in `cwd`.
fn run_headless(cwd: &Path, args: &[&str]) -> Output {
    Command::new(exe())
        .current_dir(cwd)
        .args(args)
        .env_remove("RUST_BACKTRACE")
        .env_remove("DISPLAY")
        .env_remove("WAYLAND_DISPLAY")
        .env("FITSTATION_CACHE", cwd.join("cache"))
        .output()
        .expect("run fitstation")
}

#[test]
fn every_command_runs_with_its_defaults_or_says_in_one_line_what_it_needs() {
    let d = scratch("commands");
    let commands: &[&[&str]] = &[
        &["replay"],
        &["fit"],
        &["landmarks"],
        &["measure"],
        &["templates"],
        &["templates", "import"],
        &["templates", "body"],
        &["synth"],
        &["synth-set"],
        &["eval"],
        &["bench"],
        &["version"],
        &["calibrate"],
        &["demo-ui"],
        &["live"],
        &["replay", "no-such-recording"],
    ];
    for args in commands {
        let o = run_headless(&d, args);
        let err = text(&o.stderr);
        if o.status.success() {
            continue;
        }
        let lines: Vec<&str> = err.lines().filter(|l| !l.trim().is_empty()).collect();
        let usage = err.contains("Usage: fitstation");
        assert!(
            usage || (lines.len() == 1 && lines[0].starts_with("Error: ")),
            "{args:?}: neither ran nor said in one line what it needs:\n{err}"
        );
    }
    // The MakeHuman import names the missing folder and how to fill it.
    let o = run_headless(&d, &["templates", "import"]);
    assert!(
        text(&o.stderr).contains("no MakeHuman assets in"),
        "{}",
        text(&o.stderr)
    );
    let _ = std::fs::remove_dir_all(&d);
}
