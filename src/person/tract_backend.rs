//! The inference engine of the person models: `tract-onnx` (pure Rust, one thread).
//! The networks' own code ([`super::networks`]) sees only [`Net`] and [`Outputs`].

use super::prep::resample_roi;
use super::{FrameRef, PersonError, Roi, INPUT_SIZE};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use tract_onnx::prelude::*;

fn inference_err(e: impl std::fmt::Display) -> PersonError {
    PersonError::Inference(format!("{e:#}"))
}

/// One loaded network: the optimised plan, its reusable state and input tensor.
pub(super) struct Net {
    path: PathBuf,
    state: TypedSimpleState,
    /// NHWC [1, 256, 256, 3] input, filled in place each frame (the plan drops its own
    /// reference after each run, so the buffer is reused).
    input: Arc<Tensor>,
}

impl Net {
    /// Loads the ONNX file at `path`, checks its one NHWC [1, 256, 256, 3] input and the
    /// shapes of its outputs, and builds the optimised plan.
    pub(super) fn load(path: &Path, expect_outputs: &[&[usize]]) -> Result<Net, PersonError> {
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

    /// The model file.
    pub(super) fn path(&self) -> &Path {
        &self.path
    }

    /// Fills the input from `roi` of `frame` (a valid ROI) and runs the plan.
    pub(super) fn run(&mut self, frame: FrameRef<'_>, roi: Roi) -> Result<Outputs, PersonError> {
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
        self.state
            .run(tvec!(input))
            .map(Outputs)
            .map_err(inference_err)
    }
}

/// The outputs of one run, in the network's output order.
pub(super) struct Outputs(TVec<TValue>);

impl Outputs {
    /// Output `k` as f32 values (row-major).
    pub(super) fn get(&self, k: usize) -> Result<&[f32], PersonError> {
        let v = self
            .0
            .get(k)
            .ok_or_else(|| PersonError::Inference(format!("no output {k}")))?;
        v.try_as_plain_ram()
            .map_err(inference_err)?
            .as_slice::<f32>()
            .map_err(inference_err)
    }
}
