//! The `fitstation eval` command: its arguments, the named sets of `--set NAME=DIR`,
//! scoring each recording's fit, and printing (and writing) the tables.

use super::table::{clip, interval_cell};
use super::{evaluate, html, EvalTable, FitResult, MeasurementSummary};
use std::path::{Path, PathBuf};

/// `fitstation eval`: score fits of recordings against their ground truth.
#[derive(Debug, Clone, clap::Args)]
pub struct EvalArgs {
    /// Recording folders (each with its `<recording>.truth/` beside it).
    #[arg(required_unless_present = "sets")]
    pub recordings: Vec<PathBuf>,
    /// A whole evaluation set, `NAME=DIR`: every recording in DIR that has its truth
    /// folder beside it. Repeat for several sets: each set gets its own table, then one
    /// table puts the sets side by side (MAE, bias and worst single error per girth).
    #[arg(long = "set", value_name = "NAME=DIR")]
    pub sets: Vec<String>,
    /// Print JSON instead of the table.
    #[arg(long)]
    pub json: bool,
    /// Fit results to score: a folder with avatar.obj + report.json (one recording), or
    /// a folder holding one such folder per recording name.
    #[arg(long)]
    pub result: Option<PathBuf>,
    /// Also write an HTML report (index.html) into this folder.
    #[arg(long)]
    pub report: Option<PathBuf>,
}

/// A way to obtain a fit for a recording (the lead plugs `replay` in here).
pub type FitSource<'a> = dyn FnMut(&Path) -> anyhow::Result<FitResult> + 'a;

/// The result folder of `recording` under `--result DIR`.
pub fn result_dir_for(result: &Path, recording: &Path) -> PathBuf {
    if result.join("avatar.obj").is_file() {
        return result.to_path_buf();
    }
    result.join(recording.file_name().unwrap_or_default())
}

/// Runs `fitstation eval` with results from `--result`.
pub fn run(args: EvalArgs) -> anyhow::Result<()> {
    let Some(result) = args.result.clone() else {
        anyhow::bail!("no fit to score: pass --result DIR (a folder with avatar.obj and report.json); replaying recordings through the fit is not wired in yet");
    };
    let mut source = |rec: &Path| -> anyhow::Result<FitResult> {
        Ok(FitResult::load(&result_dir_for(&result, rec))?)
    };
    run_with(&args, &mut source)
}

/// One named evaluation set of `--set NAME=DIR`.
#[derive(Debug, Clone, PartialEq)]
pub struct EvalSet {
    pub name: String,
    pub recordings: Vec<PathBuf>,
}

/// Parses `NAME=DIR` and lists DIR's recordings: its sub-folders (sorted by name) that
/// have a truth folder beside them.
pub fn parse_set(spec: &str) -> anyhow::Result<EvalSet> {
    let (name, dir) = spec
        .split_once('=')
        .filter(|(n, d)| !n.is_empty() && !d.is_empty())
        .ok_or_else(|| anyhow::anyhow!("--set takes NAME=DIR, got '{spec}'"))?;
    let dir = Path::new(dir);
    let entries = std::fs::read_dir(dir)
        .map_err(|e| anyhow::anyhow!("--set {name}: cannot read {}: {e}", dir.display()))?;
    let mut recordings: Vec<PathBuf> = entries
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.is_dir() && crate::synth::truth_dir(p).is_dir())
        .collect();
    recordings.sort();
    anyhow::ensure!(
        !recordings.is_empty(),
        "--set {name}: {} holds no recording with a truth folder beside it",
        dir.display()
    );
    Ok(EvalSet {
        name: name.to_string(),
        recordings,
    })
}

/// Width of a set's column in [`sets_side_by_side`].
const COL: usize = 24;

/// One block of [`sets_side_by_side`]: a header of the set names under `title`, then per
/// measurement of `names` that `keep` keeps a row of `cell` for each set (`-` where the set
/// lacks the measurement or `cell` gives nothing).
fn measurement_block(
    s: &mut String,
    title: &str,
    sets: &[(String, EvalTable)],
    names: &[&String],
    keep: impl Fn(&str) -> bool,
    summaries: &[Vec<MeasurementSummary>],
    cell: impl Fn(&MeasurementSummary) -> Option<String>,
) {
    s.push_str(&format!("{:<20}", title));
    for (n, _) in sets {
        s.push_str(&format!(" {:>COL$}", clip(n, COL)));
    }
    s.push('\n');
    for name in names.iter().filter(|n| keep(n.as_str())) {
        s.push_str(&format!("{:<20}", clip(name, 20)));
        for sum in summaries {
            let c = sum
                .iter()
                .find(|m| &m.name == *name)
                .and_then(&cell)
                .unwrap_or_else(|| "-".into());
            s.push_str(&format!(" {c:>COL$}"));
        }
        s.push('\n');
    }
}

/// The sets side by side: one row per measurement, per set `MAE / bias / worst` (mm), the
/// MAE's 90 % interval over other draws of as many subjects (resampled), then how many
/// subjects of each set were scored.
pub fn sets_side_by_side(sets: &[(String, EvalTable)]) -> String {
    let summaries: Vec<Vec<MeasurementSummary>> = sets.iter().map(|(_, t)| t.summary()).collect();
    let mut names: Vec<&String> = summaries.iter().flatten().map(|m| &m.name).collect();
    names.sort();
    names.dedup();
    let mut s = String::new();
    let every = |_: &str| true;
    measurement_block(
        &mut s,
        "MAE / bias / worst mm",
        sets,
        &names,
        every,
        &summaries,
        |m| {
            Some(format!(
                "{:.1} / {:+.1} / {:+.1}",
                m.mean_abs_error_mm, m.mean_bias_mm, m.worst_error_mm
            ))
        },
    );
    s.push('\n');
    measurement_block(
        &mut s,
        "MAE 90 % interval",
        sets,
        &names,
        every,
        &summaries,
        |m| Some(interval_cell(m.mae_interval_mm)),
    );
    s.push('\n');
    let girths = |n: &str| n != "stature";
    measurement_block(
        &mut s,
        "within ± / median ±",
        sets,
        &names,
        girths,
        &summaries,
        |m| {
            m.median_pm_mm
                .map(|pm| format!("{}/{} / {pm:.1}", m.within_pm, m.with_pm))
        },
    );
    s.push_str(&format!("{:<20}", "subjects fitted"));
    for (_, t) in sets {
        let cell = format!("{} of {}", t.rows.len(), t.rows.len() + t.failures.len());
        s.push_str(&format!(" {cell:>COL$}"));
    }
    s.push('\n');
    s.push_str(&format!("{:<20}", "frames refused"));
    for (_, t) in sets {
        let cell = match t.refusals_line().0 {
            Some((r, n)) => format!("{r} of {n}"),
            None => "-".into(),
        };
        s.push_str(&format!(" {cell:>COL$}"));
    }
    s.push('\n');
    s.push_str(&format!("{:<20}", "mask IoU front/side"));
    for (_, t) in sets {
        let cell = match t.refusals_line() {
            (_, Some(f), Some(si)) => format!("{f:.3} / {si:.3}"),
            _ => "-".into(),
        };
        s.push_str(&format!(" {cell:>COL$}"));
    }
    s.push('\n');
    s
}

/// Runs the evaluation with fits from `fit` (one call per recording): the recordings
/// given, or each `--set` in turn and then the sets side by side.
pub fn run_with(args: &EvalArgs, fit: &mut FitSource<'_>) -> anyhow::Result<()> {
    if args.sets.is_empty() {
        return run_one(args, &args.recordings, args.report.as_deref(), fit).map(|_| ());
    }
    let sets = args
        .sets
        .iter()
        .map(|s| parse_set(s))
        .collect::<anyhow::Result<Vec<_>>>()?;
    let mut tables = Vec::new();
    for set in &sets {
        if !args.json {
            println!("== set {} ({} recordings)", set.name, set.recordings.len());
        }
        let report = args.report.as_ref().map(|r| r.join(&set.name));
        let table = run_one(args, &set.recordings, report.as_deref(), fit)?;
        tables.push((set.name.clone(), table));
    }
    if args.json {
        let v: serde_json::Map<String, serde_json::Value> = tables
            .iter()
            .map(|(n, t)| (n.clone(), t.to_json()))
            .collect();
        println!(
            "{}",
            serde_json::to_string_pretty(&serde_json::json!({ "sets": v }))?
        );
    } else {
        println!("\n== sets side by side\n{}", sets_side_by_side(&tables));
    }
    Ok(())
}

/// Scores `recordings` and prints (and with `report`, writes) their table.
fn run_one(
    args: &EvalArgs,
    recordings: &[PathBuf],
    report: Option<&Path>,
    fit: &mut FitSource<'_>,
) -> anyhow::Result<EvalTable> {
    let mut table = EvalTable::default();
    let mut thumbs = Vec::new();
    let n = recordings.len();
    for (i, rec) in recordings.iter().enumerate() {
        progress(i, n, rec);
        let tdir = crate::synth::truth_dir(rec);
        let scored = fit(rec).and_then(|r| Ok((evaluate(&tdir, &r)?, r)));
        match scored {
            Ok((row, r)) => {
                if report.is_some() {
                    thumbs.push(
                        html::overlay_thumbnails(rec, &tdir, &r.avatar).unwrap_or_else(|e| {
                            table
                                .failures
                                .push(format!("{}: thumbnails: {e}", rec.display()));
                            Vec::new()
                        }),
                    );
                }
                table.rows.push(row);
            }
            Err(e) => table.failures.push(format!("{}: {e:#}", rec.display())),
        }
    }
    progress(n, n, Path::new(""));
    if args.json && args.sets.is_empty() {
        println!("{}", serde_json::to_string_pretty(&table.to_json())?);
    } else if !args.json {
        print!("{}", table.to_text());
    }
    if let Some(dir) = report {
        crate::io::atomic::create_dir(dir)?;
        let p = dir.join("index.html");
        crate::io::atomic::write(&p, html::report(&table, &thumbs))?;
        eprintln!("report: {}", p.display());
    }
    anyhow::ensure!(!table.rows.is_empty(), "no recording could be scored");
    Ok(table)
}

/// A stderr progress bar: redrawn in place on a terminal, one plain line per step
/// otherwise ([`crate::io::progress`]).
fn progress(i: usize, n: usize, current: &Path) {
    const WIDTH: usize = 30;
    if n < 2 {
        return;
    }
    let filled = WIDTH * i / n;
    let text = format!(
        "[{}{}] {i}/{n} {:<40}",
        "#".repeat(filled),
        " ".repeat(WIDTH - filled),
        current
            .file_name()
            .map(|f| f.to_string_lossy().into_owned())
            .unwrap_or_default()
    );
    crate::io::progress::show(
        crate::io::progress::ProgressStyle::for_stderr(),
        &text,
        i == n,
    );
}
