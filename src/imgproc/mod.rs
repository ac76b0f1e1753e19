//! Low-level image processing for the silhouette stage: undistortion (a remap table per
//! camera for display, point undistortion for the pipeline), binary morphology on
//! `0/255` masks ([`Mask`], the container the segmentation writes and the contour stage
//! reads), run-length connected components with hole filling, and Canny edges.
//!
//! # Conventions
//! - Pixels: (u, v) = (column, row), origin at the centre of the top-left pixel (as
//!   OpenCV); images are row-major, `width` columns by `height` rows.
//! - Binary images are `u8` with 0 = background and 255 = foreground (`MASK_ON`).
//! - Everything here is per-frame code: functions write into buffers they are given and
//!   do not allocate once those buffers have grown to the frame size.

pub mod canny;
pub mod mask;
pub mod morph;
pub mod remap;
pub mod runs;

pub use canny::{canny, CannyScratch};
pub use mask::Mask;
pub use morph::{dilate3x3, erode3x3, majority3x3};
pub use remap::{PointUndistorter, RemapTable};
pub use runs::{
    fill_holes, fill_holes_selective, find_run_edge, write_component, Component, Run, RunComponents,
};

/// Value of a foreground pixel in a binary mask.
pub const MASK_ON: u8 = 255;

/// Luma (ITU-R BT.601, integer weights summing to 256) of an RGB pixel.
#[inline]
pub fn luma(p: [u8; 3]) -> u8 {
    ((77 * p[0] as u32 + 150 * p[1] as u32 + 29 * p[2] as u32) >> 8) as u8
}

/// Converts an RGB image to a luma buffer (row-major, `width * height`).
pub fn to_gray(rgb: &image::RgbImage, out: &mut Vec<u8>) {
    out.clear();
    out.extend(rgb.pixels().map(|p| luma(p.0)));
}
