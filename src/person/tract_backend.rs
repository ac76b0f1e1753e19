//! The person models over `tract-onnx` (pure Rust, one thread).

use super::prep::resample_roi;
use super::{
    find_model, sigmoid, FrameRef, Keypoint, PersonError, PersonModel, PersonOutput, Roi,
    INPUT_SIZE, POSE_AUX_POINTS, POSE_KEYPOINTS, POSE_MODEL_FILE, SELFIE_MODEL_FILE,
};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use tract_onnx::prelude::*;

/// Values per pose landmark in the network's first output: x, y, z, visibility logit,
/// presence logit.
const LANDMARK_VALUES: usize = 5;

fn inference_err(e: impl std::fmt::Display) -> PersonError {
    PersonError::Inference(format!("{e:#}"))
}

/// One loaded network: the optimised plan, its reusable state and input tensor.
struct Net {
    path: PathBuf,
    state: TypedSimpleState,
    /// NHWC [1, 256, 256, 3] input, filled in place each frame (the plan drops its own
    /// reference after each run, so the buffer is reused).
    input: Arc<Tensor>,
}

impl Net {
    fn load(path: &Path, expect_outputs: &[&[usize]]) -> Result<Net, PersonError> {
        let load_err = |e: TractError| PersonError::Load {
            path: path.to_path_buf(),
            msg: format!("{e:#}"),
        };
        let model = tract_onnx::onnx()
            .model_for_path(path)
            .map_err(load_err)?
            .into_typed()
            .map_err(load_err)?;
        // Check the graph's interface before optimising it.
        let shape = [1, INPUT_SIZE, INPUT_SIZE, 3];
        let in_fact = model.input_fact(0).map_err(load_err)?;
        let in_shape = in_fact.shape.as_concrete().map(|s| s.to_vec());
        if model.inputs.len() != 1 || in_shape.as_deref() != Some(&shape[..]) {
            return Err(PersonError::Load {
                path: path.to_path_buf(),
                msg: format!("expected one input of shape {shape:?}, found {in_fact:?}"),
            });
        }
        let outs = model.output_outlets().map_err(load_err)?.len();
        if outs != expect_outputs.len() {
            return Err(PersonError::Load {
                path: path.to_path_buf(),
                msg: format!("expected {} outputs, found {outs}", expect_outputs.len()),
            });
        }
        for (k, want) in expect_outputs.iter().enumerate() {
            let fact = model.output_fact(k).map_err(load_err)?;
            if fact.shape.as_concrete() != Some(*want) {
                return Err(PersonError::Load {
                    path: path.to_path_buf(),
                    msg: format!("output {k}: expected shape {want:?}, found {fact:?}"),
                });
            }
        }
        let plan = model
            .into_optimized()
            .map_err(load_err)?
            .into_runnable()
            .map_err(load_err)?;
        let state = TypedSimpleState::new(&plan).map_err(load_err)?;
        let input = Arc::new(Tensor::zero::<f32>(&shape).map_err(load_err)?);
        Ok(Net {
            path: path.to_path_buf(),
            state,
            input,
        })
    }

    /// Fills the input from `roi` of `frame` and runs the plan.
    fn run(&mut self, frame: FrameRef<'_>, roi: Roi) -> Result<TVec<TValue>, PersonError> {
        if !roi.is_valid() {
            return Err(PersonError::EmptyRoi(roi));
        }
        if Arc::get_mut(&mut self.input).is_none() {
            // Still shared (should not happen: the plan releases its inputs after a run).
            let fresh = Tensor::zero::<f32>(self.input.shape()).map_err(inference_err)?;
            self.input = Arc::new(fresh);
        }
        let Some(tensor) = Arc::get_mut(&mut self.input) else {
            return Err(PersonError::Inference("input tensor still shared".into()));
        };
        {
            let mut view = tensor.try_as_plain_ram_mut().map_err(inference_err)?;
            let buf = view.as_slice_mut::<f32>().map_err(inference_err)?;
            resample_roi(frame, roi, buf);
        }
        let input = TValue::from_const(Arc::clone(&self.input));
        self.state.run(tvec!(input)).map_err(inference_err)
    }
}

fn output_slice(v: &TValue) -> Result<&[f32], PersonError> {
    v.try_as_plain_ram()
        .map_err(inference_err)?
        .as_slice::<f32>()
        .map_err(inference_err)
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
        &self.net.path
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
        let outputs = self.net.run(frame, roi)?;
        let prob = output_slice(&outputs[0])?;
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
        &self.net.path
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
        let outputs = self.net.run(frame, roi)?;
        let lm = output_slice(&outputs[0])?;
        let presence = output_slice(&outputs[1])?;
        let seg = output_slice(&outputs[2])?;
        let world = output_slice(&outputs[4])?;

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
