//! The binary mask, the image container the segmentation writes and the contour stage
//! reads (below both).
//!
//! # Conventions
//! Pixels (column, row), origin at the top-left pixel; full frame resolution; row-major
//! `u8` values, 0 (background) or 255 (foreground, [`super::MASK_ON`]).

/// A binary mask, full frame resolution, 0 (background) or 255 (person).
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct Mask {
    pub width: u32,
    pub height: u32,
    /// Row-major, `width * height` values, 0 or 255.
    pub data: Vec<u8>,
}

impl Mask {
    pub fn new(width: u32, height: u32) -> Self {
        Mask {
            width,
            height,
            data: vec![0; (width * height) as usize],
        }
    }
    /// True for a foreground pixel; false outside the image.
    #[inline]
    pub fn get(&self, x: i64, y: i64) -> bool {
        if x < 0 || y < 0 || x >= self.width as i64 || y >= self.height as i64 {
            return false;
        }
        self.data[(y as usize) * self.width as usize + x as usize] != 0
    }
    /// Foreground pixels.
    pub fn area(&self) -> u64 {
        self.data.iter().filter(|&&v| v != 0).count() as u64
    }
    /// Intersection over union with another mask of the same size (1 when both empty).
    pub fn iou(&self, other: &Mask) -> f64 {
        let (mut i, mut u) = (0u64, 0u64);
        for (&a, &b) in self.data.iter().zip(&other.data) {
            let (a, b) = (a != 0, b != 0);
            i += (a && b) as u64;
            u += (a || b) as u64;
        }
        if u == 0 {
            1.0
        } else {
            i as f64 / u as f64
        }
    }
    pub(crate) fn reset(&mut self, width: u32, height: u32) {
        self.width = width;
        self.height = height;
        self.data.clear();
        self.data.resize((width * height) as usize, 0);
    }
}
