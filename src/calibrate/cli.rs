//! `fitstation calibrate`: intrinsics from folders of board photos, extrinsics from the
//! placement board at the mark, operator checks, and a safe write of `station.yaml`
//! (the previous file is kept as `<out>.bak`; a worse calibration goes to
//! `<out stem>.new.yaml` unless `--force`).
//!
//! Units on the command line: millimetres (`--square-mm`, `--board-height-mm`).

use super::board::{BoardSpec, Target};
use super::checks::check_station;
use super::corners::CornerDetector;
use super::extrinsics::{place_camera, CameraPlacement, Placement};
use super::intrinsics::{calibrate_intrinsics, detect_views, read_gray, IntrinsicsCalibration};
use super::{CalibError, Progress};
use crate::camera::{Camera, Intrinsics, Rigid, StationCalibration, View};
use anyhow::{bail, Context};
use std::path::{Path, PathBuf};
use std::time::Instant;

/// A new calibration counts as worse when its RMS exceeds the old one's by this factor.
pub const WORSE_RMS_FACTOR: f64 = 1.10;
/// Nominal kiosk geometry used only when no extrinsics exist yet (flagged in the file).
const NOMINAL_DISTANCE_M: f64 = 3.0;
const NOMINAL_HEIGHT_M: f64 = 1.2;
const NOMINAL_AIM_M: f64 = 1.05;

/// Arguments of `fitstation calibrate`.
#[derive(clap::Args, Debug)]
pub struct CalibrateArgs {
    #[command(subcommand)]
    pub action: Option<CalibrateAction>,
    /// Inner corners of the chessboard, COLSxROWS (e.g. 9x6).
    #[arg(long)]
    pub board: Option<String>,
    /// Side of one printed square (circle grid: centre spacing) in millimetres.
    #[arg(long)]
    pub square_mm: Option<f64>,
    /// The printed target: a chessboard (COLSxROWS inner corners) or a symmetric grid
    /// of dark circles (COLSxROWS circles).
    #[arg(long, value_enum, default_value_t = TargetArg::Chessboard)]
    pub target: TargetArg,
    /// Folder of the front camera's board photos (omit to keep the intrinsics of --out).
    #[arg(long)]
    pub front: Option<PathBuf>,
    /// Folder of the side camera's board photos (omit to keep the intrinsics of --out).
    #[arg(long)]
    pub side: Option<PathBuf>,
    /// Front camera's image of the placement board at the mark.
    #[arg(long)]
    pub station_front: Option<PathBuf>,
    /// Side camera's image of the placement board at the mark.
    #[arg(long)]
    pub station_side: Option<PathBuf>,
    /// Height of the placement board's lowest row of inner corners above the floor, mm.
    #[arg(long)]
    pub board_height_mm: Option<f64>,
    /// The calibration file to write.
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Print the operator checks of an existing station.yaml and exit.
    #[arg(long, value_name = "STATION_YAML")]
    pub check: Option<PathBuf>,
    /// Overwrite --out even when the new calibration is worse than the old one.
    #[arg(long)]
    pub force: bool,
}

/// `--target` values.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum TargetArg {
    Chessboard,
    Circles,
}

impl From<TargetArg> for Target {
    fn from(t: TargetArg) -> Target {
        match t {
            TargetArg::Chessboard => Target::Chessboard,
            TargetArg::Circles => Target::Circles,
        }
    }
}

#[derive(clap::Subcommand, Debug)]
pub enum CalibrateAction {
    /// Print the operator checks of a station.yaml.
    Check { station_yaml: PathBuf },
}

/// Runs `fitstation calibrate`: each camera's lens from its board photos (or kept from
/// the existing station.yaml), the cameras' positions from the placement board at the
/// mark (or kept), the operator checks, and a safe write.
pub fn run(args: CalibrateArgs) -> anyhow::Result<()> {
    if let Some(CalibrateAction::Check { station_yaml }) = &args.action {
        return print_checks(station_yaml);
    }
    if let Some(path) = &args.check {
        return print_checks(path);
    }
    let (Some(board_text), Some(square_mm), Some(out)) = (&args.board, args.square_mm, &args.out)
    else {
        bail!("usage: fitstation calibrate --board COLSxROWS --square-mm S --front DIR --side DIR [--station-front IMG --station-side IMG --board-height-mm H] --out station.yaml\n   or: fitstation calibrate check station.yaml");
    };
    let board = BoardSpec::parse(board_text, square_mm).map_err(anyhow::Error::msg)?;
    let target = Target::from(args.target);
    let previous = load_previous(out);
    let mut progress = |p: &Progress| match p {
        Progress::ViewSearched {
            camera,
            index,
            total,
            name,
            outcome,
        } => eprintln!("  [{camera} {}/{total}] {name}: {outcome}", index + 1),
        Progress::Stage(s) => eprintln!("{s}"),
    };
    let total = Instant::now();
    println!("Board: {board} ({})", target.name());

    // 1. Intrinsics.
    let (calibs, [front_intr, side_intr]) =
        calibrate_lenses(&args, &board, target, previous.as_ref(), out, &mut progress)?;
    // 2. Extrinsics.
    let (poses, extra) = camera_poses(
        &args,
        board,
        target,
        [front_intr, side_intr],
        previous.as_ref(),
        out,
    )?;
    let station = assemble_station(
        [front_intr, side_intr],
        poses,
        (board, square_mm, target),
        &calibs,
        previous.as_ref(),
        extra,
    );

    // 3. Checks.
    let checks = check_station(&station);
    println!("{checks}");

    // 4. Safe write.
    let written = write_safely(&station, previous.as_ref(), out, args.force)?;
    println!(
        "wrote {} (total {:.1} s)",
        written.display(),
        total.elapsed().as_secs_f64()
    );
    Ok(())
}

/// The station.yaml already at `out`, if any can be read (one that cannot is kept as a
/// backup by the write).
fn load_previous(out: &Path) -> Option<StationCalibration> {
    if out.exists() {
        match StationCalibration::load(out) {
            Ok(p) => Some(p),
            Err(e) => {
                eprintln!(
                    "note: the existing {} cannot be read ({e}); it will be kept as a backup",
                    out.display()
                );
                None
            }
        }
    } else {
        None
    }
}

/// Each camera's lens: calibrated from its folder of board photos, or kept from the
/// previous calibration; returns the calibrations made and both cameras' intrinsics.
fn calibrate_lenses(
    args: &CalibrateArgs,
    board: &BoardSpec,
    target: Target,
    previous: Option<&StationCalibration>,
    out: &Path,
    progress: &mut dyn FnMut(&Progress),
) -> anyhow::Result<(Vec<Option<IntrinsicsCalibration>>, [Intrinsics; 2])> {
    let mut calibs: Vec<Option<IntrinsicsCalibration>> = Vec::new();
    let mut intr: Vec<Intrinsics> = Vec::new();
    for (view, dir) in [(View::Front, &args.front), (View::Side, &args.side)] {
        match dir {
            Some(dir) => {
                let t = Instant::now();
                let views = detect_views(dir, view.name(), board, target, progress)?;
                let detect_ms = t.elapsed().as_secs_f64() * 1e3;
                let t = Instant::now();
                let c = calibrate_intrinsics(&views, board, progress)?;
                println!("{c}");
                println!(
                    "  timings: detection {:.0} ms ({:.1} ms per image), optimisation {:.0} ms",
                    detect_ms,
                    detect_ms / views.views.len().max(1) as f64,
                    t.elapsed().as_secs_f64() * 1e3
                );
                intr.push(c.intrinsics);
                calibs.push(Some(c));
            }
            None => {
                let Some(prev) = previous else {
                    bail!("no --{} folder and no existing {} to take that camera's lens calibration from: pass --{} DIR with 10-15 board photos", view.name(), out.display(), view.name());
                };
                println!(
                    "{} camera: keeping the lens calibration of {}",
                    view.name(),
                    out.display()
                );
                intr.push(prev.camera(view).intrinsics);
                calibs.push(None);
            }
        }
    }
    Ok((calibs, [intr[0], intr[1]]))
}

/// Both cameras' poses and the (key, value) notes that record how they were found.
type PosesAndNotes = ([Rigid; 2], Vec<(String, String)>);

/// Both cameras' poses: placed from one image each of the placement board at the mark,
/// or kept from the previous calibration, or nominal placeholders; with the notes that
/// record how they were found.
fn camera_poses(
    args: &CalibrateArgs,
    board: BoardSpec,
    target: Target,
    [front_intr, side_intr]: [Intrinsics; 2],
    previous: Option<&StationCalibration>,
    out: &Path,
) -> anyhow::Result<PosesAndNotes> {
    let mut extra: Vec<(String, String)> = Vec::new();
    let poses: [Rigid; 2] = match (&args.station_front, &args.station_side) {
        (Some(sf), Some(ss)) => {
            let Some(h_mm) = args.board_height_mm else {
                bail!("--board-height-mm is needed with the station images: measure the height of the board's lowest row of inner corners above the floor");
            };
            if !(0.0..3000.0).contains(&h_mm) {
                bail!("--board-height-mm {h_mm} is not plausible (0-3000 mm)");
            }
            let placement = Placement { board, lowest_row_height_m: h_mm / 1000.0 };
            let placed = place_both(&placement, target, [(sf.as_path(), front_intr), (ss.as_path(), side_intr)])?;
            for p in &placed {
                println!("{} camera placed: placement board RMS {:.3} px at {:.2} m", p.view.name(), p.rms_px, p.board_distance_m);
                for w in &p.warnings {
                    println!("  WARNING: {w}");
                }
                extra.push((format!("{}_placement_rms_px", p.view.name()), format!("{:.4}", p.rms_px)));
            }
            extra.push(("board_height_mm".into(), format!("{h_mm}")));
            extra.push(("extrinsics".into(), "placement board at the mark".into()));
            [placed[0].camera_from_station, placed[1].camera_from_station]
        }
        (None, None) => match previous {
            Some(prev) => {
                println!("no station images: keeping the camera positions of {}", out.display());
                extra.push(("extrinsics".into(), "kept from the previous calibration".into()));
                // Keep the record of how those positions were measured.
                for (k, v) in &prev.extra {
                    if k == "board_height_mm" || k.ends_with("_placement_rms_px") {
                        extra.push((k.clone(), v.clone()));
                    }
                }
                [prev.front.camera_from_station, prev.side.camera_from_station]
            }
            None => {
                println!("WARNING: no station images and no previous {}: camera positions are NOMINAL placeholders. Run again with --station-front, --station-side and --board-height-mm before measuring anyone.", out.display());
                extra.push(("extrinsics".into(), "NOMINAL placeholder, not calibrated".into()));
                let n = StationCalibration::nominal(front_intr.width, front_intr.height, front_intr.fx, NOMINAL_DISTANCE_M, NOMINAL_HEIGHT_M, NOMINAL_AIM_M);
                [n.front.camera_from_station, n.side.camera_from_station]
            }
        },
        _ => bail!("give both --station-front and --station-side (one image of the placement board from each camera)"),
    };
    Ok((poses, extra))
}

/// The station calibration from the cameras' lenses and poses, with its notes: the
/// board, each lens's RMS and views (kept ones from the previous calibration), how the
/// poses were found, and when.
fn assemble_station(
    [front_intr, side_intr]: [Intrinsics; 2],
    poses: [Rigid; 2],
    (board, square_mm, target): (BoardSpec, f64, Target),
    calibs: &[Option<IntrinsicsCalibration>],
    previous: Option<&StationCalibration>,
    extra: Vec<(String, String)>,
) -> StationCalibration {
    let mut station = StationCalibration {
        front: Camera {
            intrinsics: front_intr,
            camera_from_station: poses[0],
        },
        side: Camera {
            intrinsics: side_intr,
            camera_from_station: poses[1],
        },
        extra: Vec::new(),
    };
    station
        .extra
        .push(("board".into(), format!("{}x{}", board.cols, board.rows)));
    station
        .extra
        .push(("square_mm".into(), format!("{square_mm}")));
    station.extra.push(("target".into(), target.name().into()));
    for (view, c) in [View::Front, View::Side].iter().zip(calibs) {
        let (rms, n) = match c {
            Some(c) => (format!("{:.4}", c.rms_px), format!("{}", c.used_views)),
            None => (
                old_extra(previous, &format!("{}_rms_px", view.name())).unwrap_or_default(),
                old_extra(previous, &format!("{}_views", view.name())).unwrap_or_default(),
            ),
        };
        if !rms.is_empty() {
            station.extra.push((format!("{}_rms_px", view.name()), rms));
        }
        if !n.is_empty() {
            station.extra.push((format!("{}_views", view.name()), n));
        }
    }
    station.extra.extend(extra);
    let now = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map(|d| d.as_secs())
        .unwrap_or(0);
    station
        .extra
        .push(("calibrated_unix_s".into(), format!("{now}")));
    station
}

fn old_extra(prev: Option<&StationCalibration>, key: &str) -> Option<String> {
    prev?
        .extra
        .iter()
        .find(|(k, _)| k == key)
        .map(|(_, v)| v.clone())
}

/// Detects the placement board in both station images and places both cameras.
fn place_both(
    placement: &Placement,
    target: Target,
    inputs: [(&Path, Intrinsics); 2],
) -> Result<Vec<CameraPlacement>, CalibError> {
    let mut detector = CornerDetector::for_target(target);
    let mut found = Vec::new();
    let mut errors = Vec::new();
    for ((path, intr), view) in inputs.iter().zip(View::BOTH) {
        let img = read_gray(path)?;
        if (img.width(), img.height()) != (intr.width, intr.height) {
            errors.push((
                view,
                path.to_path_buf(),
                format!(
                    "image is {}x{} but the {} lens calibration is for {}x{}",
                    img.width(),
                    img.height(),
                    view.name(),
                    intr.width,
                    intr.height
                ),
            ));
            continue;
        }
        match detector.detect(&img, &placement.board) {
            Ok(d) => found.push((view, *intr, d)),
            Err(e) => errors.push((view, path.to_path_buf(), e.to_string())),
        }
    }
    match (found.len(), errors.pop()) {
        (1, Some((missing, _, reason))) => {
            return Err(CalibError::SeenByOneCamera {
                seen: found[0].0.name().into(),
                missing: missing.name().into(),
                reason,
            });
        }
        (_, Some((view, path, reason))) => {
            return Err(CalibError::PlacementBoardNotFound {
                camera: view.name().into(),
                path,
                reason,
                advice: "Stand the board on the mark as in calib/README.md, light it evenly, and check --board".into(),
            });
        }
        _ => {}
    }
    found
        .iter()
        .map(|(view, intr, d)| place_camera(*view, intr, &d.corners, placement))
        .collect()
}

/// Writes `station` to `out` without silently replacing a better calibration.
fn write_safely(
    station: &StationCalibration,
    previous: Option<&StationCalibration>,
    out: &Path,
    force: bool,
) -> anyhow::Result<PathBuf> {
    if !out.exists() {
        station.save(out)?;
        return Ok(out.to_path_buf());
    }
    let mut worse = Vec::new();
    for view in View::BOTH {
        let key = format!("{}_rms_px", view.name());
        let new = old_extra(Some(station), &key).and_then(|v| v.parse::<f64>().ok());
        let old = old_extra(previous, &key).and_then(|v| v.parse::<f64>().ok());
        match (old, new) {
            (Some(o), Some(n)) => {
                println!(
                    "{} camera RMS: previous {o:.3} px, new {n:.3} px",
                    view.name()
                );
                if n > o * WORSE_RMS_FACTOR {
                    worse.push(format!("{} {n:.3} px vs {o:.3} px", view.name()));
                }
            }
            (None, Some(n)) => println!(
                "{} camera RMS: new {n:.3} px (the previous file records none)",
                view.name()
            ),
            _ => {}
        }
    }
    if !worse.is_empty() && !force {
        let new_path = out.with_extension("new.yaml");
        station.save(&new_path)?;
        println!(
            "NOT replacing {}: the new calibration is worse ({}). The new one is in {}; take more or sharper board photos, or rerun with --force to replace it anyway.",
            out.display(),
            worse.join(", "),
            new_path.display()
        );
        return Ok(new_path);
    }
    let backup = out.with_extension("yaml.bak");
    crate::io::atomic::copy(out, &backup)
        .with_context(|| format!("backing up {} to {}", out.display(), backup.display()))?;
    if !worse.is_empty() {
        println!(
            "replacing a better calibration because of --force ({})",
            worse.join(", ")
        );
    }
    println!("previous calibration kept as {}", backup.display());
    station.save(out)?;
    Ok(out.to_path_buf())
}

fn print_checks(path: &Path) -> anyhow::Result<()> {
    let station = StationCalibration::load(path)?;
    println!("{}", path.display());
    for (k, v) in &station.extra {
        println!("  {k}: {v}");
    }
    print!("{}", check_station(&station));
    Ok(())
}
