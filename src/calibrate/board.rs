//! The calibration target: a chessboard counted by its INNER corners.
//!
//! # Conventions
//! Board frame (OpenCV's object points): inner corner (col c, row r) sits at
//! `(c * square, r * square, 0)` metres; +x runs along a row (columns increase), +y runs
//! down the rows, +z = x × y points INTO the board, away from whoever reads the printed
//! side. The outer squares extend one square beyond the inner corners on every side; the
//! square touching corner (0, 0) from outside (x < 0, y < 0) is black.

use glam::{DVec2, DVec3};

/// Size of the chessboard: inner corners per row (`cols`) and per column (`rows`), and
/// the side of one square in metres.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BoardSpec {
    pub cols: usize,
    pub rows: usize,
    pub square_m: f64,
}

/// What is printed on the calibration sheet.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Target {
    /// A chessboard; the grid points are its inner corners.
    #[default]
    Chessboard,
    /// A symmetric grid of dark circles on white; the grid points are the circle
    /// centres, `square_m` apart.
    Circles,
}

impl Target {
    pub fn name(self) -> &'static str {
        match self {
            Target::Chessboard => "chessboard",
            Target::Circles => "circles",
        }
    }
}

/// Fewest inner corners along either side of a usable board.
pub const MIN_INNER_CORNERS: usize = 3;

impl BoardSpec {
    /// Parses `"COLSxROWS"` (inner corners) with the square side in millimetres.
    pub fn parse(text: &str, square_mm: f64) -> Result<BoardSpec, String> {
        let (c, r) = text.trim().split_once(['x', 'X']).ok_or_else(|| {
            format!("board '{text}' should read COLSxROWS, e.g. 9x6 (inner corners)")
        })?;
        let cols = c
            .trim()
            .parse::<usize>()
            .map_err(|_| format!("board '{text}': '{c}' is not a count of inner corners"))?;
        let rows = r
            .trim()
            .parse::<usize>()
            .map_err(|_| format!("board '{text}': '{r}' is not a count of inner corners"))?;
        if cols < MIN_INNER_CORNERS || rows < MIN_INNER_CORNERS || cols > 100 || rows > 100 {
            return Err(format!("board '{text}': count inner corners (where four squares meet), at least {MIN_INNER_CORNERS} each way"));
        }
        if !(square_mm.is_finite() && square_mm > 1.0 && square_mm < 1000.0) {
            return Err(format!("square size {square_mm} mm is not plausible: measure one printed square with a ruler"));
        }
        Ok(BoardSpec {
            cols,
            rows,
            square_m: square_mm / 1000.0,
        })
    }

    /// Number of inner corners.
    pub fn corner_count(&self) -> usize {
        self.cols * self.rows
    }

    /// Board-frame position of inner corner (col, row), metres.
    pub fn object_point(&self, col: usize, row: usize) -> DVec3 {
        DVec3::new(col as f64 * self.square_m, row as f64 * self.square_m, 0.0)
    }

    /// All inner corners in OpenCV's order (row-major: row 0 left to right, then row 1...).
    pub fn object_points(&self) -> Vec<DVec3> {
        (0..self.rows)
            .flat_map(|r| (0..self.cols).map(move |c| self.object_point(c, r)))
            .collect()
    }

    /// Centre of the inner-corner grid in the board frame.
    pub fn grid_centre(&self) -> DVec2 {
        DVec2::new(
            (self.cols - 1) as f64 * self.square_m * 0.5,
            (self.rows - 1) as f64 * self.square_m * 0.5,
        )
    }

    /// True when the board point (x, y) in metres lies on a black square (outside the
    /// squares: false).
    pub fn is_black(&self, x: f64, y: f64) -> bool {
        let i = (x / self.square_m).floor();
        let j = (y / self.square_m).floor();
        if i < -1.0 || j < -1.0 || i > self.cols as f64 - 1.0 || j > self.rows as f64 - 1.0 {
            return false;
        }
        (i as i64 + j as i64).rem_euclid(2) == 0
    }

    /// True when (x, y) lies on the printed sheet: the squares plus a white margin of
    /// `margin_squares` squares.
    pub fn on_sheet(&self, x: f64, y: f64, margin_squares: f64) -> bool {
        let m = (1.0 + margin_squares) * self.square_m;
        x >= -m
            && y >= -m
            && x <= (self.cols - 1) as f64 * self.square_m + m
            && y <= (self.rows - 1) as f64 * self.square_m + m
    }
}

impl std::fmt::Display for BoardSpec {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{}x{} inner corners, {:.1} mm squares",
            self.cols,
            self.rows,
            self.square_m * 1000.0
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_and_rejects() {
        let b = BoardSpec::parse("9x6", 25.0).unwrap();
        assert_eq!((b.cols, b.rows), (9, 6));
        assert!((b.square_m - 0.025).abs() < 1e-12);
        for bad in ["9", "ax6", "2x6", "9x6x2"] {
            assert!(BoardSpec::parse(bad, 25.0).is_err(), "{bad}");
        }
        assert!(BoardSpec::parse("9x6", -3.0).is_err());
    }

    #[test]
    fn squares_alternate_around_an_inner_corner() {
        let b = BoardSpec::parse("5x4", 30.0).unwrap();
        let e = 0.001;
        let p = b.object_point(2, 1);
        let q = [
            b.is_black(p.x - e, p.y - e),
            b.is_black(p.x + e, p.y - e),
            b.is_black(p.x + e, p.y + e),
            b.is_black(p.x - e, p.y + e),
        ];
        assert_eq!(q, [q[0], !q[0], q[0], !q[0]]);
        assert!(b.is_black(-e, -e));
    }
}
