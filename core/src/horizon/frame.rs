//! A borrowed view of one video frame: 8-bit grey or interleaved 8-bit RGB rows.

/// The pixel bytes of a frame, row after row, each row `stride` bytes apart.
#[derive(Clone, Copy, Debug)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Pixels<'a> {
    /// One byte a pixel.
    Grey(&'a [u8]),
    /// Three bytes a pixel, in R, G, B order.
    Rgb(&'a [u8]),
}

/// Why a frame view could not be made.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum FrameError {
    /// Width or height is zero, or the frame is smaller than the 3×3 gradient needs.
    TooSmall,
    /// A row (`width` pixels) does not fit in `stride` bytes.
    StrideTooShort,
    /// The slice ends before the last row does.
    BufferTooShort { needed: usize, got: usize },
}

/// One frame: size, row stride (bytes) and pixels. Made only through [`Frame::new`], which
/// checks that every pixel it promises is inside the slice.
#[derive(Clone, Copy, Debug)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Frame<'a> {
    width: usize,
    height: usize,
    stride: usize,
    pixels: Pixels<'a>,
}

impl<'a> Frame<'a> {
    /// Smallest frame side the detector works on.
    pub const MIN_SIDE: usize = 16;

    pub fn new(
        width: usize,
        height: usize,
        stride: usize,
        pixels: Pixels<'a>,
    ) -> Result<Self, FrameError> {
        if width < Self::MIN_SIDE || height < Self::MIN_SIDE {
            return Err(FrameError::TooSmall);
        }
        let (bytes_per_pixel, data) = match pixels {
            Pixels::Grey(d) => (1, d),
            Pixels::Rgb(d) => (3, d),
        };
        let row_bytes = width.saturating_mul(bytes_per_pixel);
        if stride < row_bytes {
            return Err(FrameError::StrideTooShort);
        }
        let needed = stride.saturating_mul(height - 1).saturating_add(row_bytes);
        if data.len() < needed {
            return Err(FrameError::BufferTooShort {
                needed,
                got: data.len(),
            });
        }
        Ok(Frame {
            width,
            height,
            stride,
            pixels,
        })
    }

    /// A tightly packed grey frame.
    pub fn grey(width: usize, height: usize, data: &'a [u8]) -> Result<Self, FrameError> {
        Self::new(width, height, width, Pixels::Grey(data))
    }

    /// A tightly packed RGB frame.
    pub fn rgb(width: usize, height: usize, data: &'a [u8]) -> Result<Self, FrameError> {
        Self::new(width, height, width.saturating_mul(3), Pixels::Rgb(data))
    }

    pub fn width(&self) -> usize {
        self.width
    }

    pub fn height(&self) -> usize {
        self.height
    }

    pub fn stride(&self) -> usize {
        self.stride
    }

    pub fn pixels(&self) -> Pixels<'a> {
        self.pixels
    }

    pub fn is_colour(&self) -> bool {
        matches!(self.pixels, Pixels::Rgb(_))
    }

    /// Row `y` as bytes (3 per pixel for RGB); empty past the last row.
    pub(crate) fn row(&self, y: usize) -> &'a [u8] {
        let (bytes_per_pixel, data) = match self.pixels {
            Pixels::Grey(d) => (1, d),
            Pixels::Rgb(d) => (3, d),
        };
        let start = y.saturating_mul(self.stride);
        data.get(start..start.saturating_add(self.width * bytes_per_pixel))
            .unwrap_or(&[])
    }

    /// `(R, G, B)` at a pixel (grey repeated for a grey frame); black outside the frame.
    pub(crate) fn rgb_at(&self, x: usize, y: usize) -> (u8, u8, u8) {
        let row = self.row(y);
        match self.pixels {
            Pixels::Grey(_) => {
                let g = row.get(x).copied().unwrap_or(0);
                (g, g, g)
            }
            Pixels::Rgb(_) => match row.get(x * 3..x * 3 + 3) {
                Some(&[r, g, b]) => (r, g, b),
                _ => (0, 0, 0),
            },
        }
    }
}

/// Luma of an RGB pixel (BT.601 weights in 8-bit fixed point).
#[inline]
pub(crate) fn luma(r: u8, g: u8, b: u8) -> u8 {
    ((77 * r as u32 + 150 * g as u32 + 29 * b as u32 + 128) >> 8) as u8
}
