//! `fitstation synth` and `fitstation synth-set`: their arguments, the subjects of an
//! evaluation set, and rendering them.

use super::{
    ansur, ansur_body, render_recording, scene, stance, subject, CameraOptions, SynthConfig,
    SynthError, SynthSummary,
};
use crate::recording::FrameFormat;
use std::path::PathBuf;
use subject::SubjectParams;

/// Subject parameters on the command line (each unset one is drawn from the seed).
#[derive(Debug, Clone, Default, clap::Args)]
pub struct SubjectOptions {
    /// 0 = female .. 1 = male, or "female"/"male".
    #[arg(long)]
    pub gender: Option<String>,
    /// Age in years (the library's adults: 25 to 90; younger is taken as 25).
    #[arg(long)]
    pub age_years: Option<f64>,
    /// 0..1.
    #[arg(long)]
    pub muscle: Option<f64>,
    /// 0..1 (0.5 average).
    #[arg(long)]
    pub weight: Option<f64>,
    /// MakeHuman's height slider, 0..1 (0.5 average; its ends are extreme).
    #[arg(long)]
    pub height: Option<f64>,
    /// 0..1 (0 uncommon .. 1 ideal proportions).
    #[arg(long)]
    pub proportions: Option<f64>,
    /// Rescale the body uniformly to this stature, metres.
    #[arg(long)]
    pub stature_m: Option<f64>,
}

impl SubjectOptions {
    fn apply(&self, mut p: SubjectParams) -> anyhow::Result<SubjectParams> {
        if let Some(g) = &self.gender {
            p.shape.gender = match g.to_ascii_lowercase().as_str() {
                "female" | "f" => 0.0,
                "male" | "m" => 1.0,
                v => v
                    .parse::<f64>()
                    .ok()
                    .filter(|x| (0.0..=1.0).contains(x))
                    .ok_or_else(|| {
                        anyhow::anyhow!(
                            "--gender must be female, male or a number in 0..1, got '{v}'"
                        )
                    })?,
            };
        }
        let unit = |name: &str, v: Option<f64>, into: &mut f64| -> anyhow::Result<()> {
            if let Some(v) = v {
                anyhow::ensure!(
                    (0.0..=1.0).contains(&v),
                    "--{name} must be in 0..1, got {v}"
                );
                *into = v;
            }
            Ok(())
        };
        unit("muscle", self.muscle, &mut p.shape.muscle)?;
        unit("weight", self.weight, &mut p.shape.weight)?;
        unit("height", self.height, &mut p.shape.height)?;
        unit("proportions", self.proportions, &mut p.shape.proportions)?;
        if let Some(a) = self.age_years {
            anyhow::ensure!(
                (1.0..=100.0).contains(&a),
                "--age-years must be in 1..100, got {a}"
            );
            p.shape.age_years = a;
        }
        if let Some(s) = self.stature_m {
            anyhow::ensure!(
                (1.2..=2.2).contains(&s),
                "--stature-m must be in 1.2..2.2 m, got {s}"
            );
            p.stature_m = Some(s);
        }
        Ok(p)
    }
}

/// `fitstation synth`: render one synthetic recording with its ground truth.
#[derive(Debug, Clone, clap::Args)]
pub struct SynthArgs {
    /// Recording folder to write (the truth goes to `<out>.truth/`).
    #[arg(long)]
    pub out: PathBuf,
    /// Seed: subject, cameras, scene, noise.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    #[command(flatten)]
    pub subject: SubjectOptions,
    #[command(flatten)]
    pub cameras: CameraOptions,
    /// Frame pairs of the empty scene at the start (>= 10).
    #[arg(long, default_value_t = 12)]
    pub empty_frames: usize,
    /// Frame pairs with the subject.
    #[arg(long, default_value_t = 12)]
    pub subject_frames: usize,
    #[arg(long, default_value_t = 30.0)]
    pub fps: f64,
    /// Frame storage.
    #[arg(long, value_enum, default_value_t = FrameFormat::Mp4)]
    pub format: FrameFormat,
    /// Do not write the truth folder.
    #[arg(long)]
    pub no_truth: bool,
    /// Turn the subject on the mark by this many degrees beyond its drawn placement
    /// (positive: its front toward the side camera), in the rest stance otherwise: the
    /// same body and scene at several turns (issue 19, item 4).
    #[arg(long, allow_hyphen_values = true)]
    pub turn_deg: Option<f64>,
}

/// Largest `--turn-deg`: a shopper on the mark faces the front camera.
const MAX_TURN_DEG: f64 = 30.0;

/// Runs `fitstation synth`.
pub fn run(args: SynthArgs) -> anyhow::Result<()> {
    if let Some(d) = args.cameras.distance_m {
        anyhow::ensure!(
            (1.0..=8.0).contains(&d),
            "--distance-m {d} is not a station distance (1 to 8 m)"
        );
    }
    if let Some(h) = args.cameras.camera_height_m {
        anyhow::ensure!(
            (0.2..=2.6).contains(&h),
            "--camera-height-m {h} is not a camera height (0.2 to 2.6 m)"
        );
    }
    anyhow::ensure!(
        args.fps > 0.0 && args.fps <= 240.0,
        "--fps {} is not a frame rate",
        args.fps
    );
    anyhow::ensure!(
        args.subject_frames > 0,
        "--subject-frames must be at least 1"
    );
    let mut subject = args.subject.apply(SubjectParams::sample(args.seed))?;
    if let Some(turn) = args.turn_deg {
        anyhow::ensure!(
            turn.is_finite() && turn.abs() <= MAX_TURN_DEG,
            "--turn-deg {turn} is not a turn on the mark (at most {MAX_TURN_DEG} degrees either way)"
        );
        subject.stance = Some(stance::Stance::turned(turn));
    }
    let cfg = SynthConfig {
        seed: args.seed,
        subject,
        cameras: args.cameras.clone(),
        empty_frames: args.empty_frames,
        subject_frames: args.subject_frames,
        fps: args.fps,
        format: args.format,
        truth: !args.no_truth,
        clothing: scene::Clothing::Drawn,
        passer_by: false,
    };
    let s = render_recording(&cfg, &args.out)?;
    print_summary(&s);
    Ok(())
}

fn print_summary(s: &SynthSummary) {
    println!(
        "{}: {} frame pairs; setup {:.0} ms, render {:.1} ms/pair, write {:.1} ms/pair{}",
        s.recording.display(),
        s.frame_pairs,
        s.setup_ms,
        s.render_ms_per_pair,
        s.write_ms_per_pair,
        s.truth
            .as_ref()
            .map(|t| format!("; truth in {}", t.display()))
            .unwrap_or_default()
    );
}

/// `fitstation synth-set`: a deterministic evaluation set of subjects across genders and
/// builds (seeds `first-seed .. first-seed + count`). Bodies from the fit's own shape
/// library (default, the regression set) or following real ANSUR II people
/// (`--population ansur`); in the rest A-pose or a stance drawn per subject (`--stance
/// varied`). Seeds 30000 and above are kept unseen for final judgements. A member whose
/// body cannot be analysed is drawn again from its seed, said on stderr: first its stance
/// (varied), then its ANSUR II person (same sex), at most 4 times each.
#[derive(Debug, Clone, clap::Args)]
pub struct SynthSetArgs {
    /// Folder receiving `subject_NN` recordings and their truth folders.
    #[arg(long)]
    pub out: PathBuf,
    #[arg(long, default_value_t = 12)]
    pub count: usize,
    #[arg(long, default_value_t = 1000)]
    pub first_seed: u64,
    #[arg(long, value_enum, default_value_t = FrameFormat::Mp4)]
    pub format: FrameFormat,
    /// Arms turned from the library's rest A-pose, degrees (positive: away from the body).
    #[arg(long, default_value_t = 0.0, allow_hyphen_values = true)]
    pub arms_deg: f64,
    /// Legs turned from the rest pose, degrees (positive: apart).
    #[arg(long, default_value_t = 0.0, allow_hyphen_values = true)]
    pub legs_deg: f64,
    /// Bodies outside the shape library: trunk and legs this much wider (fraction, e.g.
    /// 0.06) about `--warp-at`.
    #[arg(long, default_value_t = 0.0, allow_hyphen_values = true)]
    pub warp_width: f64,
    /// ... and this much deeper, front to back (fraction).
    #[arg(long, default_value_t = 0.0, allow_hyphen_values = true)]
    pub warp_depth: f64,
    /// Height of the warp, fraction of stature (0.52 hips, 0.6 waist, 0.72 chest).
    #[arg(long, default_value_t = 0.6)]
    pub warp_at: f64,
    /// Where the bodies come from: `library` (the fit's own shape library: the
    /// regression set) or `ansur` (each subject one real ANSUR II person, a shape the
    /// library cannot make).
    #[arg(long, value_enum, default_value_t = Population::Library)]
    pub population: Population,
    /// `rest` (the library's A-pose) or `varied` (arms, elbows, legs and a turn of the
    /// whole body drawn per subject).
    #[arg(long, value_enum, default_value_t = StanceKind::Rest)]
    pub stance: StanceKind,
    /// Folder of the ANSUR II CSV files (default ../shared/data/ansur2 from the current
    /// folder, else beside the source tree).
    #[arg(long)]
    pub ansur_dir: Option<PathBuf>,
    /// Shirt and leggings in the backdrop's colour, 15 to 40 levels off (the case a
    /// backdrop model cannot see); the other draws of each seed are the plain set's.
    #[arg(long)]
    pub camouflage: bool,
    /// A second person walks behind each subject while it stands on the mark (behind it
    /// in the front view, beside it in the side view); not part of the truth.
    #[arg(long)]
    pub passer_by: bool,
}

/// Where the bodies of an evaluation set come from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum Population {
    /// The shape library's macro model (the fit's own candidates).
    Library,
    /// Real people: ANSUR II, the library body warped to each person.
    Ansur,
}

/// The stance of an evaluation set's subjects.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum StanceKind {
    /// The library's rest A-pose.
    Rest,
    /// Drawn per subject: arms -12..+10 deg at the shoulders, elbows bent 0..15 deg
    /// (forearms forward), legs -3..+4 deg, the whole body turned up to 4 deg.
    Varied,
}

/// The subject of member `i` of an evaluation set: alternating genders, builds spread
/// over the weight range, other parameters (age, muscle, height, proportions) drawn by
/// the shape library from the seed.
pub fn set_member(first_seed: u64, i: usize, count: usize) -> SynthConfig {
    let seed = first_seed + i as u64;
    let mut cfg = SynthConfig::from_seed(seed);
    cfg.subject.shape.gender = if i.is_multiple_of(2) { 0.0 } else { 1.0 };
    let pairs = count.div_ceil(2).max(1);
    cfg.subject.shape.weight = 0.1 + 0.8 * ((i / 2) as f64 + 0.5) / pairs as f64;
    cfg
}

/// Member `i` of an ANSUR II evaluation set: seed `first_seed + i`, women at even `i`
/// and men at odd, the person's row drawn from the seed, the library body nearest in
/// gender, stature and build as the start ([`ansur_body::macro_params`]), the local
/// shape drawn from the seed.
pub fn ansur_member(table: &ansur::AnsurTable, first_seed: u64, i: usize) -> SynthConfig {
    let seed = first_seed + i as u64;
    let mut cfg = SynthConfig::from_seed(seed);
    set_ansur_person(table, &mut cfg, seed, member_sex(i));
    cfg
}

/// The sex of member `i` of an ANSUR II set: women at even `i`, men at odd.
fn member_sex(i: usize) -> ansur::Sex {
    if i.is_multiple_of(2) {
        ansur::Sex::Female
    } else {
        ansur::Sex::Male
    }
}

/// Gives `cfg` the ANSUR II person of `sex` drawn from `person_seed` (row, start body
/// and local shape); the rest of the subject (scene, cameras, clothing) stays `cfg`'s.
fn set_ansur_person(
    table: &ansur::AnsurTable,
    cfg: &mut SynthConfig,
    person_seed: u64,
    sex: ansur::Sex,
) {
    let record = table.pick(person_seed, sex).clone();
    cfg.subject.shape = ansur_body::macro_params(&record);
    cfg.subject.ansur = Some(ansur_body::AnsurSubject {
        record,
        local: ansur_body::LocalShape::sample(person_seed),
    });
}

/// People drawn again for an ANSUR II member whose body cannot be analysed.
pub const MAX_PERSON_REDRAWS: u32 = 4;

/// The seed of the `k`-th ANSUR II person drawn again for a member of seed `seed`.
pub fn redrawn_person_seed(seed: u64, k: u32) -> u64 {
    seed ^ (u64::from(k) << 48)
}

/// Stances drawn again for a varied-stance member whose posed body cannot be analysed.
pub const MAX_STANCE_REDRAWS: u32 = 4;

/// The seed of the `k`-th stance drawn again for a member of seed `seed`.
pub fn redrawn_stance_seed(seed: u64, k: u32) -> u64 {
    seed ^ (u64::from(k) << 40)
}

/// Runs `fitstation synth-set`.
pub fn run_set(args: SynthSetArgs) -> anyhow::Result<()> {
    let table = match args.population {
        Population::Library => None,
        Population::Ansur => {
            let dir = ansur::resolve_dir(args.ansur_dir.as_deref())?;
            Some(ansur::AnsurTable::load(&dir)?)
        }
    };
    crate::io::atomic::create_dir(&args.out)?;
    for i in 0..args.count {
        let mut cfg = match &table {
            None => set_member(args.first_seed, i, args.count),
            Some(t) => ansur_member(t, args.first_seed, i),
        };
        if args.stance == StanceKind::Varied {
            cfg.subject.stance = Some(stance::Stance::sample(cfg.seed));
        }
        cfg.format = args.format;
        if args.camouflage {
            cfg.clothing = scene::Clothing::Camouflage;
        }
        cfg.passer_by = args.passer_by;
        cfg.subject.pose = subject::LimbPose {
            arms_deg: args.arms_deg,
            legs_deg: args.legs_deg,
        };
        cfg.subject.warp = subject::BodyWarp {
            width: args.warp_width,
            depth: args.warp_depth,
            at: args.warp_at,
        };
        let out = args.out.join(format!("subject_{i:02}"));
        let mut redraws = 0;
        let mut people = 0;
        let s = loop {
            match render_recording(&cfg, &out) {
                // A varied stance can press the thighs together so that no crotch is
                // left: the stance is drawn again from the seed (deterministically).
                Err(SynthError::Unanalysable(e))
                    if args.stance == StanceKind::Varied && redraws < MAX_STANCE_REDRAWS =>
                {
                    redraws += 1;
                    eprintln!(
                        "subject_{i:02} (seed {}): {e}; stance drawn again ({redraws})",
                        cfg.seed
                    );
                    cfg.subject.stance = Some(stance::Stance::sample(redrawn_stance_seed(
                        cfg.seed, redraws,
                    )));
                }
                // A person's body itself can defeat the analysis (a heavy arm that
                // cannot be traced below the armpit, seed 68010): another person of the
                // same sex is drawn from the seed (deterministically), in the first
                // stance again.
                Err(SynthError::Unanalysable(e))
                    if people < MAX_PERSON_REDRAWS && table.is_some() =>
                {
                    people += 1;
                    eprintln!(
                        "subject_{i:02} (seed {}): {e}; another ANSUR II person drawn ({people})",
                        cfg.seed
                    );
                    let person_seed = redrawn_person_seed(cfg.seed, people);
                    if let Some(t) = &table {
                        set_ansur_person(t, &mut cfg, person_seed, member_sex(i));
                    }
                    redraws = 0;
                    if args.stance == StanceKind::Varied {
                        cfg.subject.stance = Some(stance::Stance::sample(cfg.seed));
                    }
                }
                r => break r?,
            }
        };
        print_summary(&s);
    }
    Ok(())
}
