//! Landmarks, contour parts, skeleton joints and frame verdicts from the two calibrated
//! views (issue 4, steps 4-5; method.md section 1). The silhouette stage
//! ([`crate::silhouette`]) runs the steps below on each frame pair; this module holds the
//! landmark geometry and imports neither it nor `segment` (the `cli` path only forwards
//! the `landmarks` command, which moved there, for `src/main.rs`).
//!
//! Per view: segmentation (`segment`), the largest component's outer contour (`contour`)
//! refined to sub-pixel and resampled evenly, then undistorted point by point and mapped
//! onto a vertical plane through the mark (front: z = 0, side: x = 0) where the paper's
//! zones are applied in metres (`zones`). Landmarks found in the front view are lifted to
//! the station frame with perspective rays (`lift`): the front ray of a landmark is cut
//! by the plane z = z_side(height), where z_side is the side contour's axis at that
//! height (computed on the plane x = the landmark's x), iterated so both views agree.
//! The crotch and the head top are the exceptions: the ray through the leg gap's apex
//! grazes the trough under the crotch and passes the body axis below the perineum, the
//! ray over the head grazes its dome and passes the axis above the top; both are moved
//! by the template's section for that ray's slope (`graze`).
//!
//! # Conventions
//! - Station frame (`shared/spec/formats.md`): metres, +Y up, +Z toward the front camera,
//!   +X the subject's left, origin on the floor at the mark; soles on y = 0, so the
//!   stature is the height of the head top.
//! - Pixels are each frame's own distorted pixels (origin at the centre of the top-left
//!   pixel). The front camera faces the subject: the subject's left (+X) is on the image's
//!   right. The side camera on +X looks toward -X: the subject's front (+Z) is on the
//!   image's left (checked by `tests::image_orientation_of_the_nominal_station`).
//! - `h`, the paper's head length, is stature / 7.
//! - "Left"/"right" are the subject's.

pub mod analysis;
pub mod graze;
pub mod lift;
pub mod phantom;
pub mod zones;

pub use analysis::{analyse_front, analyse_side, FrontFeatures, SideFeatures};

use crate::camera::View;
use glam::{DVec2, DVec3};

/// Names of landmarks and skeleton joints.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum LandmarkName {
    HeadTop,
    Crotch,
    ArmpitLeft,
    ArmpitRight,
    AcromionLeft,
    AcromionRight,
    // Skeleton joints, first table (on the body axis).
    Hip,
    Abdomen,
    Waist,
    Chest,
    Neck,
    Head,
    ThighRootLeft,
    ThighRootRight,
    // Limb joints, second table.
    KneeLeft,
    KneeRight,
    AnkleLeft,
    AnkleRight,
    ShoulderLeft,
    ShoulderRight,
    ElbowLeft,
    ElbowRight,
    WristLeft,
    WristRight,
    HandLeft,
    HandRight,
}

impl LandmarkName {
    /// Stable snake_case name (used in JSON).
    pub fn as_str(self) -> &'static str {
        use LandmarkName::*;
        match self {
            HeadTop => "head_top",
            Crotch => "crotch",
            ArmpitLeft => "armpit_left",
            ArmpitRight => "armpit_right",
            AcromionLeft => "acromion_left",
            AcromionRight => "acromion_right",
            Hip => "hip",
            Abdomen => "abdomen",
            Waist => "waist",
            Chest => "chest",
            Neck => "neck",
            Head => "head",
            ThighRootLeft => "thigh_root_left",
            ThighRootRight => "thigh_root_right",
            KneeLeft => "knee_left",
            KneeRight => "knee_right",
            AnkleLeft => "ankle_left",
            AnkleRight => "ankle_right",
            ShoulderLeft => "shoulder_left",
            ShoulderRight => "shoulder_right",
            ElbowLeft => "elbow_left",
            ElbowRight => "elbow_right",
            WristLeft => "wrist_left",
            WristRight => "wrist_right",
            HandLeft => "hand_left",
            HandRight => "hand_right",
        }
    }
    /// True for skeleton joints (as opposed to surface landmarks).
    pub fn is_joint(self) -> bool {
        !matches!(
            self,
            LandmarkName::HeadTop
                | LandmarkName::Crotch
                | LandmarkName::ArmpitLeft
                | LandmarkName::ArmpitRight
                | LandmarkName::AcromionLeft
                | LandmarkName::AcromionRight
        )
    }
}

/// Side of a contour part, as the fitter matches template slices to contour parts.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Status {
    Left,
    Right,
    Front,
    Back,
}

/// A run of contour points `start, start+1, ..., start+len-1` (mod n).
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
pub struct ContourRange {
    pub start: usize,
    pub len: usize,
}

impl ContourRange {
    /// The contour indices of the range.
    pub fn indices(&self, n: usize) -> impl Iterator<Item = usize> + '_ {
        let s = self.start;
        (0..self.len).map(move |k| (s + k) % n.max(1))
    }
}

/// A part of a view's contour (method.md section 1, steps 5-6).
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct ContourPart {
    /// "torso", "left_arm", "right_arm", "left_leg", "right_leg" (front);
    /// "side_torso", "side_leg" (side).
    pub name: String,
    pub status: Status,
    pub range: ContourRange,
}

/// Image edge of a frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum FrameEdge {
    Top,
    Bottom,
    Left,
    Right,
}

/// What is wrong with a frame pair, for the fit and the screen. Several can hold at once.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
#[serde(tag = "verdict", rename_all = "snake_case")]
pub enum Verdict {
    NoPerson,
    MultiplePeople,
    CutOff {
        view: View,
        edge: FrameEdge,
    },
    ArmsTouchingTorso {
        left: bool,
        right: bool,
    },
    LegsTogether,
    UnderExposed {
        view: View,
    },
    OverExposed {
        view: View,
    },
    OffMark {
        dx_m: f64,
        dz_m: f64,
    },
    /// The trunk's outline is lopsided beyond any body's asymmetry: part of the person
    /// matched the backdrop and is missing from the silhouette.
    BlendsIntoBackdrop {
        view: View,
    },
    /// The person's silhouette changed beyond a still shopper's sway since the last
    /// frame: someone walking behind the shopper and merging with the outline, or the
    /// shopper moving. Not measured; the station waits for a still picture.
    Moving {
        view: View,
    },
}

impl Verdict {
    /// True when the frame pair is not fitted under this verdict (all but being off the
    /// mark, which the fit's perspective rays absorb).
    pub fn blocks_fit(&self) -> bool {
        match self {
            Verdict::NoPerson
            | Verdict::MultiplePeople
            | Verdict::CutOff { .. }
            | Verdict::ArmsTouchingTorso { .. }
            | Verdict::LegsTogether
            | Verdict::UnderExposed { .. }
            | Verdict::OverExposed { .. }
            | Verdict::BlendsIntoBackdrop { .. }
            | Verdict::Moving { .. } => true,
            Verdict::OffMark { .. } => false,
        }
    }

    /// A sentence for the screen.
    pub fn message(&self) -> String {
        match *self {
            Verdict::NoPerson => "Nobody is on the mark.".into(),
            Verdict::MultiplePeople => {
                "More than one person is in view: only the shopper should stand in the booth."
                    .into()
            }
            Verdict::CutOff { view, edge } => {
                let e = match edge {
                    FrameEdge::Top => "top",
                    FrameEdge::Bottom => "bottom",
                    FrameEdge::Left => "left",
                    FrameEdge::Right => "right",
                };
                format!(
                    "The body is cut off at the {e} of the {} camera's picture.",
                    view.name()
                )
            }
            Verdict::ArmsTouchingTorso { left, right } => {
                let which = match (left, right) {
                    (true, true) => "both arms",
                    (true, false) => "the left arm",
                    _ => "the right arm",
                };
                format!("Hold {which} a little away from the body.")
            }
            Verdict::LegsTogether => "Stand with the feet a little apart.".into(),
            Verdict::UnderExposed { view } => {
                format!("The {} camera's picture is too dark.", view.name())
            }
            Verdict::OverExposed { view } => {
                format!("The {} camera's picture is too bright.", view.name())
            }
            // The station measures from the front view alone when the side view lost
            // part of the body (`station::StationProcessor`).
            Verdict::BlendsIntoBackdrop { view: View::Side } => {
                "Part of the body blends into the backdrop in the side camera's picture: \
                 measuring from the front camera alone (depths from the shape library, \
                 wider ±)."
                    .into()
            }
            Verdict::BlendsIntoBackdrop { view } => format!(
                "Part of the body blends into the backdrop in the {} camera's picture: \
                 clothing in a colour that stands out from the backdrop is needed to measure.",
                view.name()
            ),
            Verdict::Moving { view } => format!(
                "The outline moves in the {} camera's picture (someone walking behind, or \
                 the shopper moving): waiting for a still picture.",
                view.name()
            ),
            Verdict::OffMark { dx_m, dz_m } => {
                format!(
                    "Step onto the mark ({:+.0} cm sideways, {:+.0} cm forward off).",
                    dx_m * 100.0,
                    dz_m * 100.0
                )
            }
        }
    }
}

/// Thresholds of the verdicts.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct VerdictOptions {
    /// A frame is dark when its mean luma is below this and below `exposure_ratio` of
    /// the learned empty scene's, or when its crushed-black fraction exceeds the empty
    /// scene's by `max_clipped_fraction`; bright likewise (mean above `over_mean_luma`
    /// and the empty scene's divided by `exposure_ratio`, or clipped white). Judged
    /// against the empty scene, a white or black backdrop is not itself an exposure fault.
    pub under_mean_luma: f32,
    pub over_mean_luma: f32,
    pub max_clipped_fraction: f32,
    pub exposure_ratio: f32,
    /// A second component at least this fraction of the largest is another person.
    pub second_person_ratio: f32,
    /// Distance from the mark beyond which the subject is off the mark, metres.
    pub off_mark_m: f64,
    /// Trunk asymmetry (front view, [`analysis::trunk_asymmetry`]) above which part of
    /// the body is taken to have blended into the backdrop. A standing trunk is
    /// symmetric about its axis to a few percent of its width; a missing side is tens.
    pub max_trunk_asymmetry: f64,
    /// The side view's trunk depth over the front view's trunk breadth
    /// ([`analysis::side_depth_ratio`]) under which the side view has lost part of the
    /// person to the backdrop. Real adults are deeper: over ANSUR II's 6,068 the least
    /// buttock depth over hip breadth is 0.544, waist depth over waist breadth 0.564.
    pub min_side_depth_ratio: f64,
}

impl Default for VerdictOptions {
    fn default() -> Self {
        VerdictOptions {
            under_mean_luma: 40.0,
            over_mean_luma: 225.0,
            max_clipped_fraction: 0.3,
            exposure_ratio: 0.7,
            second_person_ratio: 0.15,
            off_mark_m: 0.10,
            max_trunk_asymmetry: 0.15,
            min_side_depth_ratio: 0.45,
        }
    }
}

/// A landmark or joint in the station frame with its pixels in both views.
#[derive(Debug, Clone, PartialEq)]
pub struct NamedPoint {
    pub name: String,
    pub landmark: LandmarkName,
    pub station: DVec3,
    pub front_px: Option<DVec2>,
    pub side_px: Option<DVec2>,
}

/// All landmarks and joints in the station frame.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct StationLandmarks {
    pub points: Vec<NamedPoint>,
    /// Height of the head top (soles on y = 0), metres; 0 when no person.
    pub stature_m: f64,
    pub verdicts: Vec<Verdict>,
    /// Left-right asymmetry of the trunk in the front view (see
    /// [`analysis::trunk_asymmetry`]); None when it could not be measured.
    pub trunk_asymmetry: Option<f64>,
    /// The side view's trunk depth over the front view's breadth, lower quartile over
    /// the trunk's levels ([`analysis::side_depth_ratio`]); None when not measured.
    pub side_depth_ratio: Option<f64>,
}

impl StationLandmarks {
    pub fn get(&self, name: LandmarkName) -> Option<&NamedPoint> {
        self.points.iter().find(|p| p.landmark == name)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::camera::StationCalibration;

    #[test]
    fn image_orientation_of_the_nominal_station() {
        let s = StationCalibration::nominal(720, 1280, 1400.0, 2.6, 1.0, 0.9);
        let c = s.front.project(DVec3::new(0.0, 1.0, 0.0)).unwrap();
        // Subject's left (+X) on the front image's right.
        assert!(s.front.project(DVec3::new(0.2, 1.0, 0.0)).unwrap().x > c.x);
        // Subject's front (+Z) on the side image's left.
        let cs = s.side.project(DVec3::new(0.0, 1.0, 0.0)).unwrap();
        assert!(s.side.project(DVec3::new(0.0, 1.0, 0.2)).unwrap().x < cs.x);
        // Up is up in both.
        assert!(s.side.project(DVec3::new(0.0, 1.5, 0.0)).unwrap().y < cs.y);
    }
}
