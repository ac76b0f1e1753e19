//! Extrinsics: each camera's pose in the station frame from the placement board at the
//! mark (procedure in `calib/README.md`, issue 7 item 5).
//!
//! The board stands upright on the mark, turned 45 degrees so that its printed side
//! faces the corner between the cameras: its normal (out of the printed side) is
//! (+X+Z)/sqrt 2; its rows run downward; its lowest row of inner corners is `H` above the
//! floor; the grid is centred horizontally over the mark. Hence, with the board frame of
//! [`super::board`] (x along rows, y down the rows, z into the board):
//! - board x = (+X -Z)/sqrt 2 (to the right as seen from the printed side),
//! - board y = -Y (down), board z = x × y = (-X -Z)/sqrt 2 (into the board),
//! - the grid centre is at (0, H + (rows-1)/2 * square, 0) in the station frame.
//!
//! Each camera's `camera_from_board` comes from its corners by a homography on
//! undistorted normalised coordinates (Zhang's eq. (2)) refined by Levenberg-Marquardt
//! with the intrinsics fixed; then `camera_from_station = camera_from_board *
//! board_from_station`. The numbering of the corners is resolved physically in
//! [`super::corners`] (printed side toward the camera, rows downward).

use super::board::BoardSpec;
use super::bundle::{refine, IntrinsicsMode, ViewObservations};
use super::zhang::{homography, pose_from_homography};
use super::CalibError;
use crate::camera::{Intrinsics, Rigid, View};
use glam::{DMat3, DVec2, DVec3};

/// Rows of the placement board must advance within 45 degrees of straight down in
/// each image (cosine): cameras are mounted upright, the board stands upright.
pub const MIN_ROWS_DOWNWARD_COS: f64 = std::f64::consts::FRAC_1_SQRT_2;
/// A camera whose placement-board RMS exceeds this is reported, pixels.
pub const MAX_PLACEMENT_RMS_PX: f64 = 1.0;

/// How the placement board stands at the mark.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Placement {
    pub board: BoardSpec,
    /// Height of the lowest row of inner corners above the floor, metres.
    pub lowest_row_height_m: f64,
}

impl Placement {
    /// `station_from_board` of the default placement (module docs).
    pub fn station_from_board(&self) -> Rigid {
        let s = std::f64::consts::FRAC_1_SQRT_2;
        let x = DVec3::new(s, 0.0, -s);
        let y = DVec3::new(0.0, -1.0, 0.0);
        let z = x.cross(y);
        let rotation = DMat3::from_cols(x, y, z);
        let c = self.board.grid_centre();
        let centre_in_station = DVec3::new(0.0, self.lowest_row_height_m + c.y, 0.0);
        // p_station = R (p_board - centre_board) + centre_station
        Rigid {
            rotation,
            translation: centre_in_station - rotation * DVec3::new(c.x, c.y, 0.0),
        }
    }
}

/// One camera placed in the station frame.
#[derive(Debug, Clone, PartialEq)]
pub struct CameraPlacement {
    pub view: View,
    pub camera_from_station: Rigid,
    /// RMS reprojection error of the placement board, pixels.
    pub rms_px: f64,
    /// Distance from the camera to the grid centre, metres.
    pub board_distance_m: f64,
    pub warnings: Vec<String>,
}

/// Places one camera from the placement board's corners (OpenCV order as returned by
/// [`super::corners::CornerDetector::detect`]).
///
/// # Errors
/// A wrong number of corners or a degenerate board image.
pub fn place_camera(
    view: View,
    intrinsics: &Intrinsics,
    corners: &[DVec2],
    placement: &Placement,
) -> Result<CameraPlacement, CalibError> {
    let board = &placement.board;
    let object = board.object_points();
    if corners.len() != object.len() {
        return Err(CalibError::Placement(format!(
            "{} camera: {} corners, the board has {}",
            view.name(),
            corners.len(),
            object.len()
        )));
    }
    // The numbering assumes rows run horizontally (item 5): a board stood on its side
    // would turn the whole station frame by 90 degrees.
    let first_col = [corners[0], corners[(board.rows - 1) * board.cols]];
    let row_dir = (first_col[1] - first_col[0]).normalize_or_zero();
    if row_dir.y < MIN_ROWS_DOWNWARD_COS {
        return Err(CalibError::Placement(format!(
            "{} camera: the board's rows do not run horizontally (rows advance {:.0} deg away from straight down in the image): stand the board upright with its long side horizontal, as in calib/README.md",
            view.name(),
            row_dir.y.clamp(-1.0, 1.0).acos().to_degrees()
        )));
    }
    let normalised: Vec<DVec2> = corners
        .iter()
        .map(|p| intrinsics.undistort_pixel(*p))
        .collect();
    let board_xy: Vec<DVec2> = object.iter().map(|p| p.truncate()).collect();
    let h = homography(&board_xy, &normalised).ok_or_else(|| {
        CalibError::Placement(format!("{} camera: degenerate board image", view.name()))
    })?;
    let start = pose_from_homography(&h, &DMat3::IDENTITY).ok_or_else(|| {
        CalibError::Placement(format!("{} camera: degenerate board image", view.name()))
    })?;
    let obs = [ViewObservations {
        object: object.clone(),
        image: corners.to_vec(),
    }];
    let fit = refine(intrinsics, &[start], &obs, IntrinsicsMode::Fixed);
    let camera_from_board = fit.poses.first().copied().unwrap_or(start);
    let board_from_station = placement.station_from_board().inverse();
    let camera_from_station = Rigid {
        rotation: camera_from_board.rotation * board_from_station.rotation,
        translation: camera_from_board.rotation * board_from_station.translation
            + camera_from_board.translation,
    };
    let centre = board.grid_centre();
    let board_distance_m = camera_from_board
        .apply(DVec3::new(centre.x, centre.y, 0.0))
        .length();
    let mut warnings = Vec::new();
    let centre_st = camera_from_station.inverse().translation;
    match view {
        View::Front if centre_st.z <= 0.0 => warnings.push(format!(
            "the front camera comes out at Z = {:.2} m (behind the mark): are --station-front and --station-side swapped, or is the board turned the wrong way?",
            centre_st.z
        )),
        View::Side if centre_st.x <= 0.0 => warnings.push(format!(
            "the side camera comes out at X = {:.2} m (on the subject's right): are --station-front and --station-side swapped, or is the board turned the wrong way?",
            centre_st.x
        )),
        _ => {}
    }
    if fit.rms_px > MAX_PLACEMENT_RMS_PX {
        warnings.push(format!("placement board fits poorly ({:.2} px RMS): is the board flat and still, and the lens calibration current?", fit.rms_px));
    }
    Ok(CameraPlacement {
        view,
        camera_from_station,
        rms_px: fit.rms_px,
        board_distance_m,
        warnings,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_board_on_its_side_is_refused() {
        let board = BoardSpec {
            cols: 4,
            rows: 3,
            square_m: 0.1,
        };
        let p = Placement {
            board,
            lowest_row_height_m: 0.6,
        };
        let intr = Intrinsics {
            width: 640,
            height: 480,
            fx: 500.0,
            fy: 500.0,
            cx: 320.0,
            cy: 240.0,
            dist: [0.0; 5],
        };
        // Corners whose rows advance to the right in the image.
        let corners: Vec<DVec2> = (0..3)
            .flat_map(|r| {
                (0..4).map(move |c| DVec2::new(300.0 + 20.0 * r as f64, 200.0 - 20.0 * c as f64))
            })
            .collect();
        let e = place_camera(View::Front, &intr, &corners, &p)
            .unwrap_err()
            .to_string();
        assert!(e.contains("rows do not run horizontally"), "{e}");
    }

    #[test]
    fn placement_frame_matches_the_procedure() {
        let p = Placement {
            board: BoardSpec {
                cols: 9,
                rows: 6,
                square_m: 0.1,
            },
            lowest_row_height_m: 0.6,
        };
        let sb = p.station_from_board();
        assert!((sb.rotation.determinant() - 1.0).abs() < 1e-12);
        // Lowest row at H, grid centred over the mark.
        let low_left = sb.apply(p.board.object_point(0, 5));
        assert!((low_left.y - 0.6).abs() < 1e-12);
        let c = p.board.grid_centre();
        let centre = sb.apply(DVec3::new(c.x, c.y, 0.0));
        assert!(centre.x.abs() < 1e-12 && centre.z.abs() < 1e-12);
        // The printed side (against board +z) faces (+X+Z)/sqrt 2.
        let out_of_print = -(sb.rotation * DVec3::Z);
        assert!((out_of_print - DVec3::new(1.0, 0.0, 1.0).normalize()).length() < 1e-12);
    }
}
