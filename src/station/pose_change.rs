//! When the subject's library body is chosen again.
//!
//! The first fit chooses the library body (the candidate) whose girths the later frames
//! only refine, so the frame it is chosen on counts for the whole session. A shopper who
//! is still settling into the A-pose there (arms not yet out, feet not yet apart) gets a
//! body chosen on silhouettes with the hands over the trunk: on the evaluation set with
//! its first three subject frames at arms -10 deg / legs -3 deg, one subject's hip came
//! out 67 mm large. So the station watches the limb joints: once the last
//! [`STILL_FRAMES`] frames agree within [`STILL_TOL_M`] (the subject holds a pose) and
//! that pose differs from the one the body was chosen on by more than [`MOVED_TOL_M`],
//! the body is chosen again on the held pose. A subject who held still from the start is
//! never re-chosen.
//!
//! Units: metres, station frame.

use crate::landmarks::{LandmarkName, NamedPoint};
use glam::DVec3;
use std::collections::VecDeque;

/// The joints whose positions define the pose: the arms' joints, the knees and the
/// crotch (where the subject stands). Not the ankles: lifted at the feet, where the
/// floor's shadow meets the shoes, a still subject's ankle can jump by 7 cm.
pub const POSE_LANDMARKS: [LandmarkName; 7] = [
    LandmarkName::Crotch,
    LandmarkName::ElbowLeft,
    LandmarkName::ElbowRight,
    LandmarkName::WristLeft,
    LandmarkName::WristRight,
    LandmarkName::KneeLeft,
    LandmarkName::KneeRight,
];
/// Frames that must agree for the pose to count as held.
pub const STILL_FRAMES: usize = 3;
/// Largest joint displacement between held frames, metres (a still subject's joints
/// move by a few millimetres from frame to frame; a wrist 3 cm is a moving arm).
pub const STILL_TOL_M: f64 = 0.03;
/// Joint displacement from the chosen pose that has the body chosen again, metres (an
/// arm turned by 10 deg moves the wrist by about 10 cm).
pub const MOVED_TOL_M: f64 = 0.06;

/// One frame's pose: each of [`POSE_LANDMARKS`] if found.
type Pose = [Option<DVec3>; POSE_LANDMARKS.len()];

fn pose_of(points: &[NamedPoint]) -> Pose {
    POSE_LANDMARKS.map(|name| {
        points
            .iter()
            .find(|p| p.landmark == name)
            .map(|p| p.station)
    })
}

/// The second largest displacement of the joints both poses have (one joint lifted
/// wrongly in one frame does not make a pose change; a moved arm moves two joints, both
/// arms four). None when they share fewer than half of them.
fn displacement(a: &Pose, b: &Pose) -> Option<f64> {
    let mut d: Vec<f64> = a
        .iter()
        .zip(b)
        .filter_map(|(p, q)| Some((p.as_ref()? - q.as_ref()?).length()))
        .collect();
    if 2 * d.len() < POSE_LANDMARKS.len() || d.len() < 2 {
        return None;
    }
    d.sort_by(|x, y| y.total_cmp(x));
    Some(d[1])
}

/// Tracks the pose of the fitted frames against the pose the body was chosen on.
#[derive(Debug, Clone, Default)]
pub struct PoseTracker {
    chosen: Option<Pose>,
    recent: VecDeque<Pose>,
}

impl PoseTracker {
    /// Records the pose of a frame about to be fitted. True when the body should be
    /// chosen again on it: the last [`STILL_FRAMES`] poses (this one included) agree and
    /// differ from the chosen pose by more than [`MOVED_TOL_M`].
    pub fn observe(&mut self, points: &[NamedPoint]) -> bool {
        if self.recent.len() == STILL_FRAMES {
            self.recent.pop_front();
        }
        self.recent.push_back(pose_of(points));
        let (Some(chosen), Some(now)) = (&self.chosen, self.recent.back()) else {
            return false;
        };
        let held = self.recent.len() == STILL_FRAMES
            && self
                .recent
                .iter()
                .all(|p| displacement(p, now).is_some_and(|d| d <= STILL_TOL_M));
        held && displacement(chosen, now).is_some_and(|d| d > MOVED_TOL_M)
    }

    /// The body was chosen on the last observed frame.
    pub fn chosen_now(&mut self) {
        self.chosen = self.recent.back().copied();
    }

    pub fn clear(&mut self) {
        self.chosen = None;
        self.recent.clear();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A pose with every joint at `base` plus `offset` on the wrists.
    fn frame(wrist_offset: f64) -> Vec<NamedPoint> {
        POSE_LANDMARKS
            .iter()
            .enumerate()
            .map(|(k, &name)| {
                let mut p = DVec3::new(0.1 * k as f64, 1.0, 0.0);
                if matches!(name, LandmarkName::WristLeft | LandmarkName::WristRight) {
                    p.x += wrist_offset;
                }
                NamedPoint {
                    name: name.as_str().to_string(),
                    landmark: name,
                    station: p,
                    front_px: None,
                    side_px: None,
                }
            })
            .collect()
    }

    #[test]
    fn the_body_is_chosen_again_once_a_new_pose_is_held() {
        let mut t = PoseTracker::default();
        // Chosen while the arms were still coming out (wrists 12 cm off).
        assert!(!t.observe(&frame(-0.12)));
        t.chosen_now();
        // Moving: the last three frames do not agree yet.
        assert!(!t.observe(&frame(-0.06)));
        assert!(!t.observe(&frame(0.0)));
        assert!(!t.observe(&frame(0.004)));
        // Held for three frames (a few mm of jitter): choose again, once.
        assert!(t.observe(&frame(-0.003)));
        t.chosen_now();
        assert!(!t.observe(&frame(0.002)));
        assert!(!t.observe(&frame(0.0)));
    }

    #[test]
    fn a_subject_still_from_the_start_keeps_its_body() {
        let mut t = PoseTracker::default();
        assert!(!t.observe(&frame(0.0)));
        t.chosen_now();
        for k in 0..20 {
            let jitter = if k % 2 == 0 { 0.01 } else { -0.01 };
            assert!(!t.observe(&frame(jitter)), "frame {k}");
        }
        // One joint alone jumping (a wrist lifted wrongly) is not a pose change.
        let mut odd = frame(0.0);
        odd[3].station.x += 0.2;
        for _ in 0..3 {
            assert!(!t.observe(&odd));
        }
        // Without landmarks nothing is decided; after clear nothing was chosen.
        assert!(!t.observe(&[]));
        t.clear();
        assert!(!t.observe(&frame(0.2)));
    }
}
