//! The aggregates of a set of scored fits ([`EvalTable`]): per measurement MAE, bias
//! and worst error, the worst single girth error, landmark and timing summaries, and
//! the plain-text table of `fitstation eval`.

use super::{EvalRow, FrameTally, LandmarkSource, LandmarkSummary, StageTiming};
use serde::Serialize;
use std::collections::BTreeMap;

/// Per-measurement aggregate over subjects, millimetres.
#[derive(Debug, Clone, Serialize)]
pub struct MeasurementSummary {
    pub name: String,
    pub subjects: usize,
    pub mean_abs_error_mm: f64,
    pub mean_bias_mm: f64,
    /// The error of largest magnitude (signed).
    pub worst_error_mm: f64,
    pub worst_subject: String,
    /// Of the subjects whose report gives this measurement's `±` (`uncertainty_mm`):
    /// how many, how many errors lie within it, and its median (mm).
    pub with_pm: usize,
    pub within_pm: usize,
    pub median_pm_mm: Option<f64>,
    /// How far the MAE would move on another draw of as many subjects: the 5th and 95th
    /// percentiles of the MAE over [`RESAMPLES`] draws of the set's own errors with
    /// replacement (a percentile bootstrap, seeded: the same errors give the same
    /// interval). None with fewer than [`MIN_RESAMPLED`] subjects.
    pub mae_interval_mm: Option<(f64, f64)>,
}

/// Draws of the subjects for [`MeasurementSummary::mae_interval_mm`].
pub const RESAMPLES: usize = 2000;
/// Fewest subjects a set needs for an MAE interval.
pub const MIN_RESAMPLED: usize = 5;
/// Seed of the resampling (any fixed value: the interval is a function of the errors).
const RESAMPLE_SEED: u64 = 0x5EED_B007;

/// The 5th and 95th percentiles of the mean absolute value of `errors` over
/// [`RESAMPLES`] draws of as many of them with replacement; None with fewer than
/// [`MIN_RESAMPLED`].
pub fn mae_interval(errors: &[f64]) -> Option<(f64, f64)> {
    let n = errors.len();
    if n < MIN_RESAMPLED {
        return None;
    }
    let mut rng = crate::synth::rng::SplitMix64::new(RESAMPLE_SEED);
    let mut maes: Vec<f64> = (0..RESAMPLES)
        .map(|_| {
            let sum: f64 = (0..n)
                .map(|_| errors[(rng.next_u64() % n as u64) as usize].abs())
                .sum();
            sum / n as f64
        })
        .collect();
    maes.sort_by(|a, b| a.total_cmp(b));
    let at = |q: f64| maes[((q * (RESAMPLES - 1) as f64).round() as usize).min(RESAMPLES - 1)];
    Some((at(0.05), at(0.95)))
}

/// The single tape-girth error of largest magnitude in a set of fits: which girth
/// ([`crate::measure::GIRTH_KEYS`]; stature and the informational `hip_girth_max` are
/// not girths a tape reports), whose, and by how much.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct WorstGirth {
    pub name: String,
    pub subject: String,
    /// fitted - true, millimetres.
    pub error_mm: f64,
    pub true_mm: f64,
    pub fitted_mm: f64,
}

impl WorstGirth {
    /// One line for the text table and the HTML report.
    pub fn describe(&self) -> String {
        format!(
            "worst single girth error of the set: {:+.1} mm ({}, subject {}: fitted {:.1} mm, true {:.1} mm)",
            self.error_mm, self.name, self.subject, self.fitted_mm, self.true_mm
        )
    }
}

/// How well the fit read the shoppers' turns on the mark over a set.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct TurnSummary {
    pub subjects: usize,
    /// Subjects whose turn was read.
    pub read: usize,
    /// Of the read: mean and mean absolute error (read - true), degrees.
    pub mean_error_deg: f64,
    pub mean_abs_error_deg: f64,
    /// The largest error and whose.
    pub worst_error_deg: f64,
    pub worst_subject: String,
    /// Of the read turned more than a degree: how many, and with the right sign.
    pub turned: usize,
    pub sign_right: usize,
}

impl TurnSummary {
    /// One line for the text table.
    pub fn describe(&self) -> String {
        format!(
            "turn on the mark read on {} of {} subjects: error mean {:+.2}, MAE {:.2}, worst {:+.2} deg (subject {}); sign right on {} of {} turned over a degree",
            self.read,
            self.subjects,
            self.mean_error_deg,
            self.mean_abs_error_deg,
            self.worst_error_deg,
            self.worst_subject,
            self.sign_right,
            self.turned
        )
    }
}

/// Rows and their summary.
#[derive(Debug, Clone, Serialize, Default)]
pub struct EvalTable {
    pub rows: Vec<EvalRow>,
    pub failures: Vec<String>,
}

/// Per measurement name: each subject's (error mm, subject, ± mm when known).
type ErrorsByMeasurement<'a> = BTreeMap<String, Vec<(f64, &'a str, Option<f64>)>>;

impl EvalTable {
    /// Per-measurement MAE, bias and worst error (subjects whose report has it).
    pub fn summary(&self) -> Vec<MeasurementSummary> {
        let mut by: ErrorsByMeasurement = BTreeMap::new();
        for r in &self.rows {
            for m in &r.measurements {
                if let Some(e) = m.error_mm {
                    by.entry(m.name.clone())
                        .or_default()
                        .push((e, &r.subject, m.pm_mm));
                }
            }
        }
        by.into_iter()
            .map(|(name, es)| {
                let mut pms: Vec<f64> = es.iter().filter_map(|e| e.2).collect();
                pms.sort_by(|a, b| a.total_cmp(b));
                let within_pm = es
                    .iter()
                    .filter(|e| e.2.is_some_and(|pm| e.0.abs() <= pm))
                    .count();
                let n = es.len() as f64;
                let worst = es
                    .iter()
                    .max_by(|a, b| a.0.abs().total_cmp(&b.0.abs()))
                    .map(|e| (e.0, e.1))
                    .unwrap_or((0.0, ""));
                MeasurementSummary {
                    name,
                    subjects: es.len(),
                    mean_abs_error_mm: es.iter().map(|e| e.0.abs()).sum::<f64>() / n,
                    mean_bias_mm: es.iter().map(|e| e.0).sum::<f64>() / n,
                    worst_error_mm: worst.0,
                    worst_subject: worst.1.to_string(),
                    with_pm: pms.len(),
                    within_pm,
                    median_pm_mm: (!pms.is_empty()).then(|| pms[pms.len() / 2]),
                    mae_interval_mm: mae_interval(&es.iter().map(|e| e.0).collect::<Vec<_>>()),
                }
            })
            .collect()
    }

    /// The turns read against the truth's (None without rows).
    pub fn turn_summary(&self) -> Option<TurnSummary> {
        if self.rows.is_empty() {
            return None;
        }
        let read: Vec<(f64, f64, &str)> = self
            .rows
            .iter()
            .filter_map(|r| {
                r.turn
                    .read_deg
                    .map(|d| (d, r.turn.true_deg, r.subject.as_str()))
            })
            .collect();
        let n = read.len().max(1) as f64;
        let worst = read
            .iter()
            .max_by(|a, b| (a.0 - a.1).abs().total_cmp(&(b.0 - b.1).abs()));
        let turned: Vec<_> = read.iter().filter(|t| t.1.abs() > 1.0).collect();
        Some(TurnSummary {
            subjects: self.rows.len(),
            read: read.len(),
            mean_error_deg: read.iter().map(|t| t.0 - t.1).sum::<f64>() / n,
            mean_abs_error_deg: read.iter().map(|t| (t.0 - t.1).abs()).sum::<f64>() / n,
            worst_error_deg: worst.map_or(0.0, |t| t.0 - t.1),
            worst_subject: worst.map_or(String::new(), |t| t.2.to_string()),
            turned: turned.len(),
            sign_right: turned.iter().filter(|t| t.0 * t.1 > 0.0).count(),
        })
    }

    /// The worst single girth error over every subject and tape girth of the set
    /// (`None` when no row reports a girth).
    pub fn worst_girth(&self) -> Option<WorstGirth> {
        self.rows
            .iter()
            .flat_map(|r| r.measurements.iter().map(move |m| (r, m)))
            .filter(|(_, m)| crate::measure::GIRTH_KEYS.contains(&m.name.as_str()))
            .filter_map(|(r, m)| {
                Some(WorstGirth {
                    name: m.name.clone(),
                    subject: r.subject.clone(),
                    error_mm: m.error_mm?,
                    true_mm: m.true_mm,
                    fitted_mm: m.fitted_mm?,
                })
            })
            .max_by(|a, b| a.error_mm.abs().total_cmp(&b.error_mm.abs()))
    }

    /// Per landmark of one source, over the rows that report it: mean 3-D distance,
    /// mean and worst |height error|, millimetres (truth's names, sorted).
    pub fn landmark_summary(&self, source: LandmarkSource) -> Vec<LandmarkSummary> {
        let mut by: BTreeMap<&String, (Vec<f64>, Vec<f64>)> = BTreeMap::new();
        for r in &self.rows {
            let l = match source {
                LandmarkSource::Silhouettes => &r.landmarks,
                LandmarkSource::FittedBody => &r.body_landmarks,
            };
            for (k, d) in &l.distance_mm {
                let e = by.entry(k).or_default();
                e.0.push(*d);
                e.1.extend(l.height_mm.get(k).map(|h| h.abs()));
            }
        }
        let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len().max(1) as f64;
        by.into_iter()
            .map(|(k, (d, h))| LandmarkSummary {
                name: k.clone(),
                subjects: d.len(),
                mean_distance_mm: mean(&d),
                mean_abs_height_mm: mean(&h),
                worst_abs_height_mm: h.iter().copied().fold(0.0, f64::max),
            })
            .collect()
    }

    /// Stage timings over subjects: median of the medians and the largest p95.
    pub fn timing_summary(&self) -> BTreeMap<String, StageTiming> {
        let mut by: BTreeMap<String, Vec<StageTiming>> = BTreeMap::new();
        for r in &self.rows {
            for (s, t) in &r.timings_ms {
                by.entry(s.clone()).or_default().push(*t);
            }
        }
        by.into_iter()
            .map(|(s, mut ts)| {
                ts.sort_by(|a, b| a.median.total_cmp(&b.median));
                let median = ts[ts.len() / 2].median;
                let p95 = ts.iter().map(|t| t.p95).fold(f64::NEG_INFINITY, f64::max);
                (s, StageTiming { median, p95 })
            })
            .collect()
    }

    /// The rows, their summary, stage timings and failures as JSON (`eval --json`).
    pub fn to_json(&self) -> serde_json::Value {
        serde_json::json!({ "rows": self.rows, "summary": self.summary(),
            "worst_girth": self.worst_girth(),
            "timings_ms": self.timing_summary(), "failures": self.failures })
    }

    /// Frame pairs refused of those with a subject, and the mean mask IoU per view
    /// (over the subjects that have it).
    pub fn refusals_line(&self) -> (Option<(u64, u64)>, Option<f64>, Option<f64>) {
        let tallies: Vec<FrameTally> = self.rows.iter().filter_map(|r| r.frames).collect();
        let refused = (!tallies.is_empty()).then(|| {
            (
                tallies.iter().map(|t| t.refused()).sum(),
                tallies.iter().map(|t| t.with_subject).sum(),
            )
        });
        let iou = |v: &str| {
            let x: Vec<f64> = self
                .rows
                .iter()
                .filter_map(|r| r.mask_iou.get(v).copied())
                .collect();
            (!x.is_empty()).then(|| x.iter().sum::<f64>() / x.len() as f64)
        };
        (refused, iou("front"), iou("side"))
    }

    /// The refusals and mean mask IoU as text lines (empty when the rows lack both).
    fn refusals_and_iou(&self) -> String {
        let (refused, f, s) = self.refusals_line();
        let mut out = String::new();
        if let Some((r, n)) = refused {
            out.push_str(&format!(
                "\nframes refused (subject in view, not fitted): {r} of {n}\n"
            ));
        }
        if let (Some(f), Some(s)) = (f, s) {
            out.push_str(&format!("mean mask IoU: front {f:.3}, side {s:.3}\n"));
        }
        out
    }

    /// The plain-text table.
    pub fn to_text(&self) -> String {
        let mut s = String::new();
        let names: Vec<String> = {
            let mut v: Vec<String> = self
                .rows
                .iter()
                .flat_map(|r| r.measurements.iter().map(|m| m.name.clone()))
                .collect();
            v.sort();
            v.dedup();
            v
        };
        s.push_str(&format!("{:<16}", "error (mm)"));
        for n in &names {
            s.push_str(&format!(" {:>12}", short(n)));
        }
        s.push_str(&format!(
            " {:>9} {:>9} {:>7} {:>7} {:>13}\n",
            "surf mean", "surf p95", "IoU f", "IoU s", "turn read/true"
        ));
        for r in &self.rows {
            s.push_str(&format!("{:<16}", clip(&r.subject, 16)));
            for n in &names {
                let e = r
                    .measurements
                    .iter()
                    .find(|m| &m.name == n)
                    .and_then(|m| m.error_mm);
                s.push_str(&format!(
                    " {:>12}",
                    e.map_or("-".into(), |e| format!("{e:+.1}"))
                ));
            }
            let sd = r.surface.map_or(("-".into(), "-".into()), |d| {
                (format!("{:.1}", d.mean_mm), format!("{:.1}", d.p95_mm))
            });
            let iou = |v: &str| r.mask_iou.get(v).map_or("-".into(), |x| format!("{x:.3}"));
            let turn = format!(
                "{}/{:+.1}",
                r.turn.read_deg.map_or("-".into(), |d| format!("{d:+.1}")),
                r.turn.true_deg
            );
            s.push_str(&format!(
                " {:>9} {:>9} {:>7} {:>7} {turn:>14}\n",
                sd.0,
                sd.1,
                iou("front"),
                iou("side")
            ));
        }
        if let Some(t) = self.turn_summary() {
            s.push_str(&format!("\n{}\n", t.describe()));
        }
        s.push_str("\nper measurement        subjects   MAE mm  MAE 90 %   bias mm  worst mm  median ± mm  within ±  (worst subject)\n");
        for m in self.summary() {
            let (pm, within) = match m.median_pm_mm {
                Some(pm) => (format!("{pm:.1}"), format!("{}/{}", m.within_pm, m.with_pm)),
                None => ("-".into(), "-".into()),
            };
            let interval = interval_cell(m.mae_interval_mm);
            s.push_str(&format!(
                "{:<22} {:>8} {:>8.1} {interval:>10} {:>8.1} {:>9.1} {pm:>12} {within:>9}  ({})\n",
                m.name,
                m.subjects,
                m.mean_abs_error_mm,
                m.mean_bias_mm,
                m.worst_error_mm,
                m.worst_subject
            ));
        }
        s.push_str(
            "(MAE 90 %: where the MAE would lie on 90 % of other draws of as many subjects, from the set's own errors resampled)\n",
        );
        if let Some(w) = self.worst_girth() {
            s.push_str(&w.describe());
            s.push('\n');
        }
        for source in LandmarkSource::ALL {
            let rows = self.landmark_summary(source);
            if rows.is_empty() {
                continue;
            }
            s.push_str(&format!(
                "\n{:<48} mean 3-D mm  height: mean |err| mm  worst |err| mm\n",
                format!("landmark, {}", source.title())
            ));
            for l in rows {
                s.push_str(&format!(
                    "{:<48} {:>11.1} {:>22.1} {:>15.1}\n",
                    l.name, l.mean_distance_mm, l.mean_abs_height_mm, l.worst_abs_height_mm
                ));
            }
        }
        let mut steps: BTreeMap<&String, (f64, f64, usize)> = BTreeMap::new();
        for r in &self.rows {
            for (k, v) in &r.settled_step_mm {
                let e = steps.entry(k).or_insert((0.0, 0.0, 0));
                e.0 = e.0.max(*v);
                e.1 += v;
                e.2 += 1;
            }
        }
        if !steps.is_empty() {
            s.push_str(
                "\nshown value, frame-to-frame change after settling   mean mm   worst mm\n",
            );
            for (k, (worst, sum, n)) in steps {
                s.push_str(&format!(
                    "{k:<50} {:>8.1} {worst:>9.1}\n",
                    sum / n.max(1) as f64
                ));
            }
        }
        s.push_str(&self.refusals_and_iou());
        let t = self.timing_summary();
        if !t.is_empty() {
            s.push_str("\nstage                  median ms   worst p95 ms\n");
            for (k, v) in t {
                s.push_str(&format!("{k:<22} {:>9.2} {:>8.2}\n", v.median, v.p95));
            }
        }
        for f in &self.failures {
            s.push_str(&format!("FAILED: {f}\n"));
        }
        s
    }
}

pub(super) fn short(name: &str) -> String {
    clip(
        &name
            .replace("_girth", "")
            .replace("thigh_left", "thigh_l")
            .replace("thigh_right", "thigh_r"),
        12,
    )
}

pub(super) fn clip(s: &str, n: usize) -> String {
    s.chars().take(n).collect()
}

/// `lo-hi` of an MAE interval, or `-`.
pub fn interval_cell(i: Option<(f64, f64)>) -> String {
    i.map_or("-".into(), |(lo, hi)| format!("{lo:.1}-{hi:.1}"))
}
