//! `fitstation edit DIR --at X,Y,Z --by DX,DY,DZ [--reach-mm R]` and `fitstation edit DIR
//! --undo`: a hand edit of a fit's output folder (`avatar.obj`, `report.json`), the
//! operator screen's edit without the screen.
//!
//! The fitted avatar is kept beside the edited one as `avatar.fit.obj` (byte for byte)
//! and the report lists the edits (`hand_edits`), so every run starts from the fitted
//! avatar, makes the listed edits again (they are deterministic) and adds or takes back
//! one. When the last edit is taken back, `avatar.obj` and the report's values are the
//! fit's again, exactly.

use super::{AvatarEditor, DEFAULT_REACH_M};
use crate::io::atomic;
use anyhow::{bail, Context};
use glam::DVec3;
use serde_json::Value;
use std::path::{Path, PathBuf};

/// The fitted avatar kept beside an edited one.
pub const FIT_AVATAR: &str = "avatar.fit.obj";

/// Arguments of `fitstation edit`.
#[derive(Debug, Clone, clap::Args)]
pub struct EditArgs {
    /// A fit's output folder (`avatar.obj` and `report.json`, as `replay --out` writes them).
    pub dir: PathBuf,
    /// The handle: the avatar's vertex nearest to this point (metres, station frame: x,y,z).
    #[arg(long, value_parser = parse_vec3, allow_hyphen_values = true, conflicts_with = "vertex")]
    pub at: Option<DVec3>,
    /// The handle: this vertex of the avatar (0-based, the template's order).
    #[arg(long)]
    pub vertex: Option<u32>,
    /// Move the handle by this much (millimetres, station frame: dx,dy,dz).
    #[arg(long, value_parser = parse_vec3, allow_hyphen_values = true)]
    pub by: Option<DVec3>,
    /// How far along the surface the edit reaches (millimetres).
    #[arg(long, default_value_t = DEFAULT_REACH_M * 1e3)]
    pub reach_mm: f64,
    /// Take the last hand edit back.
    #[arg(long, conflicts_with_all = ["at", "vertex", "by"])]
    pub undo: bool,
}

fn parse_vec3(s: &str) -> Result<DVec3, String> {
    let v: Vec<f64> = s
        .split(',')
        .map(|c| c.trim().parse::<f64>().map_err(|e| format!("{c:?}: {e}")))
        .collect::<Result<_, _>>()?;
    match v[..] {
        [x, y, z] if v.iter().all(|c| c.is_finite()) => Ok(DVec3::new(x, y, z)),
        _ => Err(format!("expected three finite numbers x,y,z, got {s:?}")),
    }
}

/// An edit listed in a report: vertex, offset and reach (metres).
fn listed_edit(e: &Value) -> Option<(u32, DVec3, f64)> {
    let vertex = u32::try_from(e.get("vertex")?.as_u64()?).ok()?;
    let o = e.get("offset_m")?.as_array()?;
    let c = |i: usize| o.get(i).and_then(Value::as_f64);
    let offset = DVec3::new(c(0)?, c(1)?, c(2)?);
    let reach = e.get("reach_m")?.as_f64()?;
    Some((vertex, offset, reach))
}

/// Runs `fitstation edit`.
pub fn run(args: &EditArgs) -> anyhow::Result<()> {
    let dir = &args.dir;
    let report_path = dir.join("report.json");
    let avatar_path = dir.join("avatar.obj");
    let fit_path = dir.join(FIT_AVATAR);
    let mut report: Value =
        serde_json::from_str(&std::fs::read_to_string(&report_path).with_context(|| {
            format!("{}: a fit's output folder has report.json", dir.display())
        })?)
        .with_context(|| format!("{} is not JSON", report_path.display()))?;
    let base_path = if fit_path.exists() {
        &fit_path
    } else {
        &avatar_path
    };
    let base_bytes =
        std::fs::read(base_path).with_context(|| format!("reading {}", base_path.display()))?;
    let base = crate::mesh::io::parse_obj(&base_bytes[..], base_path, None)
        .with_context(|| format!("reading {}", base_path.display()))?;
    let vertex_count = base.vertex_count();
    let mut editor = AvatarEditor::new(base).context("the fitted avatar")?;
    let mut listed: Vec<(u32, DVec3, f64)> = Vec::new();
    for (i, e) in report
        .get("hand_edits")
        .and_then(Value::as_array)
        .into_iter()
        .flatten()
        .enumerate()
    {
        listed.push(listed_edit(e).with_context(|| {
            format!(
                "hand edit {} in {} is damaged",
                i + 1,
                report_path.display()
            )
        })?);
    }
    if args.undo && listed.pop().is_none() {
        bail!("{} has no hand edit to undo", dir.display());
    }
    for (k, &(v, o, r)) in listed.iter().enumerate() {
        editor
            .apply(v, o, r)
            .with_context(|| format!("making hand edit {} again", k + 1))?;
    }
    if !args.undo {
        let by = args
            .by
            .context("say how far to move the handle: --by dx,dy,dz (mm)")?;
        let vertex = match (args.vertex, args.at) {
            (Some(v), _) => v,
            (None, Some(p)) => editor
                .nearest_vertex(p)
                .context("the avatar has no vertices")?,
            (None, None) => bail!("say which point to move: --at x,y,z (m) or --vertex N"),
        };
        if vertex as usize >= vertex_count {
            bail!("vertex {vertex} is not on the avatar ({vertex_count} vertices)");
        }
        let edit = editor.apply(vertex, by / 1e3, args.reach_mm / 1e3)?;
        print_edit(edit);
    }
    write(dir, &mut report, &editor, &base_bytes)?;
    println!("{} hand edit(s) on {}", editor.edits().len(), dir.display());
    for (k, d) in editor.changes_mm() {
        println!("  {k}: {d:+.1} mm from the fit");
    }
    Ok(())
}

fn print_edit(e: &super::HandleEdit) {
    println!(
        "moved vertex {} ({}, at {:.3},{:.3},{:.3} m) by {:.1} mm; {} vertices moved",
        e.vertex,
        e.near,
        e.at_m.x,
        e.at_m.y,
        e.at_m.z,
        e.offset_m.length() * 1e3,
        e.moved_vertices
    );
    for (k, d) in &e.changes_mm {
        println!("  {k} {d:+.1} mm");
    }
}

/// Writes the edited avatar and report (or the fit's again when no edit is left).
fn write(
    dir: &Path,
    report: &mut Value,
    editor: &AvatarEditor,
    base_bytes: &[u8],
) -> anyhow::Result<()> {
    let avatar_path = dir.join("avatar.obj");
    let fit_path = dir.join(FIT_AVATAR);
    let report_path = dir.join("report.json");
    if let Some(obj) = report.as_object_mut() {
        if let Some(fitted) = obj.remove("measurements_fit_mm") {
            obj.insert("measurements_mm".into(), fitted);
        }
        for k in ["edited_by_hand", "hand_edits"] {
            obj.remove(k);
        }
    }
    if editor.edits().len() == 0 {
        let text = serde_json::to_string_pretty(report)? + "\n";
        atomic::write_all(&[(&avatar_path, base_bytes), (&report_path, text.as_bytes())])?;
        if fit_path.exists() {
            std::fs::remove_file(&fit_path)
                .with_context(|| format!("removing {}", fit_path.display()))?;
        }
        return Ok(());
    }
    editor.mark_report(report);
    let mut obj = Vec::new();
    crate::mesh::io::write_obj_to(&mut obj, editor.mesh())?;
    let text = serde_json::to_string_pretty(report)? + "\n";
    // The report last: it lists the edits, and a run always starts from it.
    atomic::write_all(&[
        (&fit_path, base_bytes),
        (&avatar_path, &obj),
        (&report_path, text.as_bytes()),
    ])?;
    Ok(())
}
