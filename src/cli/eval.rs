//! `fitstation eval`: each recording replayed through the station (or given results)
//! and scored against its truth.

use super::*;

/// `fitstation eval`: replays each recording through the station (or scores given
/// results) and compares with the ground truth.
#[derive(Debug, Clone, clap::Args)]
pub struct EvalCmd {
    #[command(flatten)]
    pub eval: crate::eval::EvalArgs,
    /// Score "no fitting at all" instead: the average library body scaled to the true
    /// stature (the baseline the fit must beat).
    #[arg(long, conflicts_with = "result")]
    pub baseline: bool,
    /// Correspondence of the fit: the paper's slice extremes or perspective rims.
    #[arg(long, value_enum, default_value = "perspective-rim")]
    pub correspondence: Variant,
    /// Do not run the learned pose model on the side view.
    #[arg(long)]
    pub no_person_model: bool,
    /// Fit on each recording's true silhouettes (its truth folder's masks) instead of the
    /// segmentation's: what is left is the fit's own error, the rest the segmentation's.
    #[arg(long, conflicts_with = "baseline")]
    pub truth_masks: bool,
    /// Views to fit from: both cameras, or the front camera alone (one-camera fitting,
    /// scored against the same truth).
    #[arg(long, value_enum, default_value = "both")]
    pub views: ViewSet,
    /// Deformer of the fit: mean value (the paper's) or Laplacian.
    #[arg(long, value_enum, default_value = "mvc")]
    pub deformer: DeformerKind,
}

/// The scratch folder of a recording's station masks during `fitstation eval`.
fn eval_masks_dir(rec: &Path) -> PathBuf {
    // The set's folder and the recording's name: sets share subject names.
    let name = |p: Option<&Path>| {
        p.and_then(|p| p.file_name())
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default()
    };
    eval_masks_root()
        .join(name(rec.parent()))
        .join(name(Some(rec)))
}

/// This process's scratch folder of station masks (removed when `eval` ends).
fn eval_masks_root() -> PathBuf {
    std::env::temp_dir().join(format!("fitstation-eval-masks-{}", std::process::id()))
}

/// Removes the masks' scratch folder when dropped: `eval` leaves nothing behind, on
/// success, error or panic.
struct ScratchGuard(PathBuf);

impl Drop for ScratchGuard {
    fn drop(&mut self) {
        if self.0.exists() {
            if let Err(e) = std::fs::remove_dir_all(&self.0) {
                eprintln!("cannot remove the scratch folder {}: {e}", self.0.display());
            }
        }
    }
}

/// Runs `fitstation eval`.
pub fn run_eval(cmd: &EvalCmd) -> anyhow::Result<()> {
    if cmd.eval.result.is_some() {
        return crate::eval::run(cmd.eval.clone());
    }
    let library = default_library()?;
    if cmd.baseline {
        let mut source = |rec: &Path| -> anyhow::Result<crate::eval::FitResult> {
            let truth = crate::synth::load_truth(&crate::synth::truth_dir(rec))?;
            let stature = truth
                .measurements_mm
                .get("stature")
                .copied()
                .context("truth has no stature")?
                / 1000.0;
            let mut avatar = library.template().mesh.clone();
            let h = avatar.bounds().map(|b| b.size().y).unwrap_or(1.0).max(1e-6);
            avatar.map_positions(|p| p * (stature / h));
            let m = crate::measure::measure(&avatar)?;
            let report = serde_json::json!({ "measurements_mm": m.to_report_map() });
            Ok(crate::eval::FitResult {
                avatar,
                report_json: report,
                masks_dir: None,
            })
        };
        return crate::eval::run_with(&cmd.eval, &mut source);
    }
    let _scratch = ScratchGuard(eval_masks_root());
    let mut opts = StationOptions::default();
    opts.fit.variant = cmd.correspondence;
    opts.person_model = !cmd.no_person_model;
    opts.views = cmd.views;
    opts.fit.deformer = cmd.deformer;
    let changed = crate::fit::FitSwitches::of(&opts.fit).changed();
    if !changed.is_empty() {
        eprintln!(
            "eval: the fit runs with {} from the environment",
            changed.join(" ")
        );
    }
    let mut source = |rec: &Path| -> anyhow::Result<crate::eval::FitResult> {
        let mut src = RecordingSource::open(rec)?;
        let calib = src.recording().calibration().clone();
        let mut o = opts.clone();
        if o.stature_m.is_none() {
            o.stature_m = src.recording().metadata().stature_m;
        }
        if cmd.truth_masks {
            o.truth_masks = Some(crate::synth::truth_dir(rec).join("masks"));
        }
        // The station's masks, for the mask IoU (a scratch folder per recording).
        let masks = eval_masks_dir(rec);
        if masks.exists() {
            std::fs::remove_dir_all(&masks)
                .with_context(|| format!("cannot clear {}", masks.display()))?;
        }
        o.masks_out = Some(masks.clone());
        let mut proc_ = StationProcessor::new(calib, library.clone(), o)?;
        let summary = run_offline(&mut src, &mut proc_, None, false);
        let avatar = summary
            .avatar
            .with_context(|| format!("no frame could be fitted: {}", summary.report["messages"]))?;
        Ok(crate::eval::FitResult {
            avatar,
            report_json: summary.report,
            masks_dir: masks.is_dir().then_some(masks),
        })
    };
    crate::eval::run_with(&cmd.eval, &mut source)
}
