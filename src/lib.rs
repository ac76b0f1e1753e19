//! fitstation: a two-camera capture-and-fit station. Two cameras at right angles see a
//! shopper in an A-pose; the station segments both silhouettes, finds anthropometric
//! landmarks, refits a body template with mean value deformation and reports tape-measure
//! girths. See `ARCHITECTURE.md` for the data flow and the module table.
//!
//! Stages, dependencies in one direction:
//! `camera` (model, calibration files) and `imgproc` (image containers such as `Mask`)
//! -> `segment` -> `contour` -> `landmarks`, which `silhouette` runs on each frame pair
//! (a frame walks down those stages and back up once) -> `deform` -> `fit` -> `measure`;
//! `mesh`, `body` (template, shape library) underneath; `app` wires them together with
//! capture and the screen.

// Negated comparisons such as `!(x >= 0.0)` are deliberate: they reject NaN as well.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

#[cfg(feature = "gui")]
pub mod app;
pub mod body;
pub mod calibrate;
pub mod camera;
pub mod capture;
pub mod cli;
pub mod contour;
pub mod deform;
pub mod edit;
pub mod eval;
pub mod fit;
pub mod fuzz;
pub mod imgproc;
pub mod io;
pub mod landmarks;
pub mod measure;
pub mod mesh;
pub mod person;
pub mod pipeline;
pub mod recording;
pub mod segment;
pub mod silhouette;
pub mod soak;
pub mod station;
pub mod synth;
