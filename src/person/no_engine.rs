//! The inference engine of a build without the `person-model` feature (the fuzz targets'
//! build, which has no use for `tract-onnx`): loading a network fails with a message that
//! says so, and the station segments with the backdrop model alone, as it does when a
//! model file is missing.

use super::{FrameRef, PersonError, Roi};
use std::path::Path;

/// No network can be loaded: the type has no values.
pub(super) enum Net {}

/// No run has outputs.
pub(super) enum Outputs {}

impl Net {
    /// Always [`PersonError::Load`]: this build has no inference engine.
    pub(super) fn load(path: &Path, _expect_outputs: &[&[usize]]) -> Result<Net, PersonError> {
        Err(PersonError::Load {
            path: path.to_path_buf(),
            msg: "this build of fitstation has no inference engine (built without the \
                  `person-model` feature)"
                .into(),
        })
    }

    pub(super) fn path(&self) -> &Path {
        match *self {}
    }

    pub(super) fn run(&mut self, _frame: FrameRef<'_>, _roi: Roi) -> Result<Outputs, PersonError> {
        match *self {}
    }
}

impl Outputs {
    pub(super) fn get(&self, _k: usize) -> Result<&[f32], PersonError> {
        match *self {}
    }
}
