//! Undistorted positions of a fixed grid of working pixels, kept from frame to frame.
//!
//! On a distorted camera every point a stage reads at a working pixel is undistorted first, by
//! Newton steps of the inverse radial model (a square root and a division each). Where the
//! pixels are a fixed grid, the sky/ground samples and the profiles' knots, the positions
//! depend on the camera and the working image alone: they are undistorted once, when either
//! changes, and read back. A kept point is what [`Camera::undistort_pixel`] gives there, to
//! the bit.

use super::camera::Camera;
use super::edges::Working;

/// Up to `N` points, row by row: `columns` per row, as many rows as fit.
pub(crate) struct UndistortedGrid<const N: usize> {
    /// The camera and working image the points were undistorted for; `None` before the
    /// first frame, or when the camera has no distortion (nothing to keep).
    view: Option<(Camera, Working)>,
    columns: usize,
    rows: usize,
    points: [Option<(f32, f32)>; N],
}

impl<const N: usize> UndistortedGrid<N> {
    pub(crate) const fn new() -> Self {
        UndistortedGrid {
            view: None,
            columns: 0,
            rows: 0,
            points: [None; N],
        }
    }

    /// Undistorts the grid for `camera` and `geo`, unless it is already: the working
    /// pixels `(column_at(i), row_at(j))` for `i < columns` and `j < rows` (the rows that
    /// fit in `N` points; the others are undistorted where they are read).
    pub(crate) fn prepare(
        &mut self,
        camera: &Camera,
        geo: Working,
        (columns, column_at): (usize, impl Fn(usize) -> usize),
        (rows, row_at): (usize, impl Fn(usize) -> usize),
    ) {
        if camera.k1 == 0.0 && camera.k2 == 0.0 {
            self.view = None;
            return;
        }
        if self.view == Some((*camera, geo)) {
            return;
        }
        self.columns = columns;
        self.rows = N.checked_div(columns).map_or(0, |fit| rows.min(fit));
        for (k, point) in self.points.iter_mut().enumerate() {
            let (j, i) = (k / columns.max(1), k % columns.max(1));
            if j >= self.rows {
                break;
            }
            let (u, v) = geo.to_frame(column_at(i) as f32, row_at(j) as f32);
            *point = camera.undistort_pixel(u, v);
        }
        self.view = Some((*camera, geo));
    }

    /// This grid if it was undistorted for `camera` and `geo`.
    pub(crate) fn for_view(&self, camera: &Camera, geo: Working) -> Option<&Self> {
        (self.view == Some((*camera, geo))).then_some(self)
    }

    /// The point in column `i` of row `j`, if kept: `Some` of what
    /// [`Camera::undistort_pixel`] gives there.
    #[inline]
    pub(crate) fn get(&self, i: usize, j: usize) -> Option<Option<(f32, f32)>> {
        if i >= self.columns || j >= self.rows {
            return None;
        }
        self.points.get(j * self.columns + i).copied()
    }
}
