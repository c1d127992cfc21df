//! A dense, interleaved, row-major image of any sample type.

use crate::{Error, Result};

/// `height` rows of `width` pixels of `channels` interleaved samples each.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Image<T> {
    width: usize,
    height: usize,
    channels: usize,
    data: Vec<T>,
}

impl<T: Copy + Default> Image<T> {
    /// An image filled with `T::default()`.
    pub fn new(width: usize, height: usize, channels: usize) -> Self {
        Self { width, height, channels, data: vec![T::default(); width * height * channels] }
    }

    /// Make this image `width x height x channels`, keeping its buffer (and stale samples) when
    /// it already has that shape: lets per-frame work reuse memory instead of allocating.
    pub fn ensure_shape(&mut self, width: usize, height: usize, channels: usize) {
        if (self.width, self.height, self.channels) != (width, height, channels) {
            *self = Self::new(width, height, channels);
        }
    }
}

impl<T: Copy> Image<T> {
    /// An image over `data`, which must hold exactly `width * height * channels` samples.
    pub fn from_vec(width: usize, height: usize, channels: usize, data: Vec<T>) -> Result<Self> {
        let expected = width * height * channels;
        if data.len() != expected {
            return Err(Error::invalid(format!(
                "image of {width}x{height}x{channels} needs {expected} samples, got {}",
                data.len()
            )));
        }
        Ok(Self { width, height, channels, data })
    }

    /// Pixels per row.
    pub fn width(&self) -> usize {
        self.width
    }

    /// Rows.
    pub fn height(&self) -> usize {
        self.height
    }

    /// Samples per pixel.
    pub fn channels(&self) -> usize {
        self.channels
    }

    /// `(width, height)`.
    pub fn size(&self) -> (usize, usize) {
        (self.width, self.height)
    }

    /// All samples, row-major and interleaved.
    pub fn data(&self) -> &[T] {
        &self.data
    }

    /// All samples, mutable.
    pub fn data_mut(&mut self) -> &mut [T] {
        &mut self.data
    }

    /// The samples, giving up the image.
    pub fn into_vec(self) -> Vec<T> {
        self.data
    }

    /// The samples of pixel `(x, y)`.
    pub fn pixel(&self, x: usize, y: usize) -> &[T] {
        let start = (y * self.width + x) * self.channels;
        &self.data[start..start + self.channels]
    }

    /// The samples of pixel `(x, y)`, mutable.
    pub fn pixel_mut(&mut self, x: usize, y: usize) -> &mut [T] {
        let start = (y * self.width + x) * self.channels;
        &mut self.data[start..start + self.channels]
    }

    /// A new image with `f` applied to every sample.
    pub fn map<U: Copy>(&self, f: impl Fn(T) -> U) -> Image<U> {
        Image {
            width: self.width,
            height: self.height,
            channels: self.channels,
            data: self.data.iter().map(|&v| f(v)).collect(),
        }
    }

    /// One channel as a single-channel image.
    pub fn channel(&self, c: usize) -> Image<T> {
        assert!(c < self.channels, "channel {c} of a {}-channel image", self.channels);
        Image {
            width: self.width,
            height: self.height,
            channels: 1,
            data: self.data.iter().skip(c).step_by(self.channels).copied().collect(),
        }
    }

    /// Error unless `other` has the same width and height; `what` names the pair in the message.
    pub fn check_same_size<U>(&self, other: &Image<U>, what: &str) -> Result<()> {
        if (self.width, self.height) != (other.width, other.height) {
            return Err(Error::invalid(format!(
                "{what}: {}x{} and {}x{} differ in size",
                self.width, self.height, other.width, other.height
            )));
        }
        Ok(())
    }
}

impl<T: Copy> Image<T> {
    /// A single-channel image repeated into three channels.
    pub fn channel_to_rgb(&self) -> Image<T> {
        assert_eq!(self.channels, 1, "channel_to_rgb takes a one-channel image");
        Image {
            width: self.width,
            height: self.height,
            channels: 3,
            data: self.data.iter().flat_map(|&v| [v, v, v]).collect(),
        }
    }
}

impl Image<f32> {
    /// Per-pixel mean over channels, as a single-channel image.
    pub fn channel_mean(&self) -> Image<f32> {
        let c = self.channels;
        Image {
            width: self.width,
            height: self.height,
            channels: 1,
            data: self.data.chunks_exact(c).map(|p| p.iter().sum::<f32>() / c as f32).collect(),
        }
    }

    /// The first non-finite sample as `(x, y, channel)`, if any.
    pub fn first_non_finite(&self) -> Option<(usize, usize, usize)> {
        let i = self.data.iter().position(|v| !v.is_finite())?;
        let (p, c) = (i / self.channels, i % self.channels);
        Some((p % self.width, p / self.width, c))
    }
}

impl Image<f32> {
    /// The mean of each `factor x factor` block, channel by channel (the size rounded down): the
    /// image a sensor of `factor` times larger pixels would record.
    pub fn block_mean(&self, factor: usize) -> Image<f32> {
        let f = factor.max(1);
        let (w, h, c) = (self.width / f, self.height / f, self.channels);
        let mut out = Image::new(w, h, c);
        let norm = 1.0 / (f * f) as f32;
        for y in 0..h {
            for x in 0..w {
                for ch in 0..c {
                    let sum: f32 = (0..f * f).map(|k| self.pixel(x * f + k % f, y * f + k / f)[ch]).sum();
                    out.pixel_mut(x, y)[ch] = sum * norm;
                }
            }
        }
        out
    }
}

/// Square dilation of a `width x height` mask (row-major) by `r` pixels: a pixel is inside when
/// any pixel within `r` of it along both axes is (separable max, rows then columns).
pub fn dilate(mask: &[bool], width: usize, height: usize, r: usize) -> Vec<bool> {
    let (w, h) = (width, height);
    let mut rows = vec![false; w * h];
    for y in 0..h {
        for x in 0..w {
            let (a, b) = (x.saturating_sub(r), (x + r).min(w - 1));
            rows[y * w + x] = mask[y * w + a..=y * w + b].iter().any(|&m| m);
        }
    }
    let mut out = vec![false; w * h];
    for y in 0..h {
        let (a, b) = (y.saturating_sub(r), (y + r).min(h - 1));
        for x in 0..w {
            out[y * w + x] = (a..=b).any(|yy| rows[yy * w + x]);
        }
    }
    out
}

#[cfg(test)]
mod tests {
    #[test]
    fn dilation_grows_a_pixel_into_a_square_clipped_at_the_border() {
        let (w, h) = (7, 5);
        let mut mask = vec![false; w * h];
        mask[2 * w + 1] = true;
        let grown = super::dilate(&mask, w, h, 2);
        for y in 0..h {
            for x in 0..w {
                assert_eq!(grown[y * w + x], x <= 3 && y <= 4, "({x}, {y})");
            }
        }
        assert_eq!(super::dilate(&mask, w, h, 0), mask);
    }
}
