//! `fitstation fit`: one front (and side) still through the station.

use super::*;

/// `fitstation fit --front F --side S --calib station.yaml --out DIR`.
#[derive(Debug, Clone, clap::Args)]
pub struct FitArgs {
    #[arg(long)]
    pub front: PathBuf,
    /// The side photo; without it the fit is made from the front view alone (give
    /// --stature-mm: the stature from one view is less sure).
    #[arg(long)]
    pub side: Option<PathBuf>,
    #[arg(long)]
    pub calib: PathBuf,
    /// Empty-scene image of the front camera.
    #[arg(long)]
    pub front_bg: Option<PathBuf>,
    /// Empty-scene image of the side camera.
    #[arg(long)]
    pub side_bg: Option<PathBuf>,
    #[arg(long)]
    pub out: PathBuf,
    #[command(flatten)]
    pub fit: FitCliOptions,
}

use crate::silhouette::cli::load_rgb;

/// `fitstation fit` on two stills (with optional empty-scene images).
pub fn run_fit(args: &FitArgs) -> anyhow::Result<()> {
    check_outputs(Some(&args.out), None)?;
    let calib = StationCalibration::load(&args.calib)
        .with_context(|| format!("cannot read calibration {}", args.calib.display()))?;
    let front = load_rgb(&args.front)?;
    calib.check_frame_size(crate::camera::View::Front, front.width(), front.height())?;
    let mut opts = args.fit.station_options()?;
    let Some(side_path) = &args.side else {
        // A front photo alone: the side frames are empty (not seen).
        if args.side_bg.is_some() {
            bail!("--side-bg without --side");
        }
        opts.views = ViewSet::Front;
        opts.backdrop_frames = 1;
        let fb = match &args.front_bg {
            Some(fb) => load_rgb(fb)?,
            None => {
                opts.silhouette.segment.adapt_rate = 0.0;
                crate::segment::backdrop_from_border(&front)
            }
        };
        let none = || image::RgbImage::new(0, 0);
        let pairs = vec![
            FramePair {
                index: 0,
                timestamp_s: 0.0,
                front: fb.into(),
                side: none().into(),
            },
            FramePair {
                index: 1,
                timestamp_s: 0.0,
                front: front.into(),
                side: none().into(),
            },
        ];
        let mut proc_ = StationProcessor::new(calib, default_library()?, opts)?;
        let mut source = VecSource {
            pairs: pairs.into_iter(),
        };
        let summary = run_offline(&mut source, &mut proc_, None, false);
        return finish(summary, Some(&args.out), args.fit.json);
    };
    let side = load_rgb(side_path)?;
    calib.check_frame_size(crate::camera::View::Side, side.width(), side.height())?;
    let pairs: Vec<FramePair> = match (&args.front_bg, &args.side_bg) {
        (Some(fb), Some(sb)) => {
            opts.backdrop_frames = 1;
            vec![
                FramePair {
                    index: 0,
                    timestamp_s: 0.0,
                    front: load_rgb(fb)?.into(),
                    side: load_rgb(sb)?.into(),
                },
                FramePair {
                    index: 1,
                    timestamp_s: 0.0,
                    front: front.into(),
                    side: side.into(),
                },
            ]
        }
        (None, None) => {
            // The paper's case: a plain backdrop, keyed out from the frame's own border.
            opts.backdrop_frames = 1;
            opts.silhouette.segment.adapt_rate = 0.0;
            let (fb, sb) = (
                crate::segment::backdrop_from_border(&front),
                crate::segment::backdrop_from_border(&side),
            );
            vec![
                FramePair {
                    index: 0,
                    timestamp_s: 0.0,
                    front: fb.into(),
                    side: sb.into(),
                },
                FramePair {
                    index: 1,
                    timestamp_s: 0.0,
                    front: front.into(),
                    side: side.into(),
                },
            ]
        }
        _ => bail!("give both --front-bg and --side-bg, or neither"),
    };
    let mut proc_ = StationProcessor::new(calib, default_library()?, opts)?;
    let mut source = VecSource {
        pairs: pairs.into_iter(),
    };
    let summary = run_offline(&mut source, &mut proc_, None, false);
    finish(summary, Some(&args.out), args.fit.json)
}

struct VecSource {
    pairs: std::vec::IntoIter<FramePair>,
}

impl FrameSource for VecSource {
    fn next_pair(&mut self) -> Result<Option<FramePair>, SourceError> {
        Ok(self.pairs.next())
    }
    fn calibration(&self) -> Option<&StationCalibration> {
        None
    }
    fn describe(&self) -> String {
        "stills".into()
    }
}
