//! The two MediaPipe networks over the inference engine ([`super::engine`]): input and
//! output shapes, and the outputs turned into a person mask and keypoints.

use super::engine::{Net, Outputs};
use super::{
    find_model, sigmoid, FrameRef, Keypoint, PersonError, PersonModel, PersonOutput, Roi,
    INPUT_SIZE, POSE_AUX_POINTS, POSE_KEYPOINTS, POSE_MODEL_FILE, SELFIE_MODEL_FILE,
};
use std::path::Path;

/// Values per pose landmark in the network's first output: x, y, z, visibility logit,
/// presence logit.
const LANDMARK_VALUES: usize = 5;

/// Runs `net` on `roi` of `frame`; an empty ROI is refused.
fn run(net: &mut Net, frame: FrameRef<'_>, roi: Roi) -> Result<Outputs, PersonError> {
    if !roi.is_valid() {
        return Err(PersonError::EmptyRoi(roi));
    }
    net.run(frame, roi)
}

/// MediaPipe's selfie segmentation (general model, 256x256): a person probability map.
pub struct SelfieSegmenter {
    net: Net,
}

impl SelfieSegmenter {
    /// Loads `models/selfie_segmentation.onnx` (see [`super::find_model`]).
    ///
    /// # Errors
    /// The file is missing, unreadable, or not the expected network.
    pub fn load_default() -> Result<Self, PersonError> {
        Self::load(&find_model(SELFIE_MODEL_FILE)?)
    }

    /// Loads the model at `path` and builds its plan.
    ///
    /// # Errors
    /// The file is unreadable or not the expected network.
    pub fn load(path: &Path) -> Result<Self, PersonError> {
        Ok(SelfieSegmenter {
            net: Net::load(path, &[&[1, INPUT_SIZE, INPUT_SIZE, 1]])?,
        })
    }

    /// The model file this segmenter runs.
    pub fn path(&self) -> &Path {
        self.net.path()
    }
}

impl PersonModel for SelfieSegmenter {
    fn name(&self) -> &'static str {
        "selfie_segmentation"
    }

    fn infer(
        &mut self,
        frame: FrameRef<'_>,
        roi: Roi,
        out: &mut PersonOutput,
    ) -> Result<(), PersonError> {
        let outputs = run(&mut self.net, frame, roi)?;
        let prob = outputs.get(0)?;
        out.mask.prob.copy_from_slice(prob);
        out.mask.roi = roi;
        out.keypoints.clear();
        out.aux.clear();
        out.presence = None;
        Ok(())
    }
}

/// MediaPipe's BlazePose GHUM landmark network (full): 33 keypoints, a person mask and a
/// presence score for a person crop (a square ROI around the person, e.g. the backdrop
/// silhouette's box enlarged by 1.25, or the previous frame's keypoints).
pub struct PoseLandmarker {
    net: Net,
    /// World landmarks of the last run (metres, hip-centred), 33 points.
    world: Vec<[f32; 3]>,
}

/// Output shapes of the pose network, in its output order: landmarks, presence, mask
/// logits, heatmap, world landmarks.
const POSE_OUTPUTS: [&[usize]; 5] = [
    &[1, (POSE_KEYPOINTS + POSE_AUX_POINTS) * LANDMARK_VALUES],
    &[1, 1],
    &[1, INPUT_SIZE, INPUT_SIZE, 1],
    &[1, 64, 64, POSE_KEYPOINTS + POSE_AUX_POINTS],
    &[1, (POSE_KEYPOINTS + POSE_AUX_POINTS) * 3],
];

impl PoseLandmarker {
    /// Loads `models/pose_landmark_full.onnx` (see [`super::find_model`]).
    ///
    /// # Errors
    /// The file is missing, unreadable, or not the expected network.
    pub fn load_default() -> Result<Self, PersonError> {
        Self::load(&find_model(POSE_MODEL_FILE)?)
    }

    /// Loads the model at `path` and builds its plan.
    ///
    /// # Errors
    /// The file is unreadable or not the expected network.
    pub fn load(path: &Path) -> Result<Self, PersonError> {
        Ok(PoseLandmarker {
            net: Net::load(path, &POSE_OUTPUTS)?,
            world: Vec::with_capacity(POSE_KEYPOINTS),
        })
    }

    /// The model file this landmarker runs.
    pub fn path(&self) -> &Path {
        self.net.path()
    }

    /// The last run's world landmarks: metres, origin between the hips, y down (the
    /// network's convention), 33 points in keypoint order.
    pub fn world_landmarks(&self) -> &[[f32; 3]] {
        &self.world
    }
}

impl PersonModel for PoseLandmarker {
    fn name(&self) -> &'static str {
        "pose_landmark_full"
    }

    fn infer(
        &mut self,
        frame: FrameRef<'_>,
        roi: Roi,
        out: &mut PersonOutput,
    ) -> Result<(), PersonError> {
        let outputs = run(&mut self.net, frame, roi)?;
        let lm = outputs.get(0)?;
        let presence = outputs.get(1)?;
        let seg = outputs.get(2)?;
        let world = outputs.get(4)?;

        let z_scale = roi.width / INPUT_SIZE as f32;
        out.keypoints.clear();
        out.aux.clear();
        for (k, v) in lm.chunks_exact(LANDMARK_VALUES).enumerate() {
            let (x, y) = roi.to_frame(v[0], v[1]);
            let p = Keypoint {
                x,
                y,
                z: v[2] * z_scale,
                visibility: sigmoid(v[3]),
                presence: sigmoid(v[4]),
            };
            if k < POSE_KEYPOINTS {
                out.keypoints.push(p);
            } else {
                out.aux.push(p);
            }
        }
        out.presence = presence.first().copied();
        for (o, &l) in out.mask.prob.iter_mut().zip(seg) {
            *o = sigmoid(l);
        }
        out.mask.roi = roi;
        self.world.clear();
        self.world.extend(
            world
                .chunks_exact(3)
                .take(POSE_KEYPOINTS)
                .map(|w| [w[0], w[1], w[2]]),
        );
        Ok(())
    }
}
