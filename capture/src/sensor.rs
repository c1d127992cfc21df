//! A model of the polarization sensor: light behind each micro-polarizer to raw counts, with
//! exposure, gain, shot noise, read noise, black level, quantization, saturation and the
//! polarizers' finite extinction ratio.

use crate::mosaic::{bayer_channel, SensorLayout, POLARIZER_OFFSETS};
use crate::{PixelFormat, RawFrame, Result};
use rayon::prelude::*;
use rmvp_dataset::io::json::{read_json, write_json};
use rmvp_dataset::polarization::POLARIZER_ANGLES_DEG;
use rmvp_dataset::rng::Rng;
use rmvp_dataset::{Image, Stokes};
use serde::{Deserialize, Serialize};
use std::path::Path;

/// Sensor parameters (defaults: Sony IMX250 as in the FLIR Blackfly S datasheet and EMVA
/// figures: 12 bits, about 10 500 e- full well, 2.3 e- read noise).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SensorModel {
    /// Mosaic of the sensor.
    #[serde(skip)]
    pub layout: SensorLayout,
    /// Output bits per sample.
    pub bits: u8,
    /// Electrons at saturation.
    pub full_well: f32,
    /// Fraction of the full well that unit radiance fills (exposure time x aperture).
    pub exposure: f32,
    /// Analog gain in dB.
    pub gain_db: f32,
    /// Read noise in electrons RMS.
    pub read_noise: f32,
    /// Poisson shot noise on/off.
    pub shot_noise: bool,
    /// Black level in counts.
    pub dark_offset: f32,
    /// Extinction ratio of the micro-polarizers (transmission along / across); `None` is ideal.
    pub extinction_ratio: Option<f32>,
}

impl Default for SensorModel {
    fn default() -> Self {
        Self {
            layout: SensorLayout::ColorPolarized,
            bits: 12,
            full_well: 10_500.0,
            exposure: 0.5,
            gain_db: 0.0,
            read_noise: 2.3,
            shot_noise: true,
            dark_offset: 16.0,
            extinction_ratio: None,
        }
    }
}

impl SensorModel {
    /// A noise-free sensor (quantization only): for exact round trips.
    pub fn noise_free(mut self) -> Self {
        self.read_noise = 0.0;
        self.shot_noise = false;
        self
    }

    /// Counts per electron.
    fn counts_per_electron(&self) -> f32 {
        ((1u32 << self.bits) - 1) as f32 / self.full_well * 10f32.powf(self.gain_db / 20.0)
    }

    /// Stokes of the processed frame (in units of full scale, black level removed) per unit of
    /// rendered Stokes: `exposure x gain`. Divide processed Stokes by it to compare.
    pub fn stokes_gain(&self) -> f32 {
        self.exposure * 10f32.powf(self.gain_db / 20.0)
    }

    /// Polarizer efficiency `(ER - 1) / (ER + 1)`: the fraction of S1, S2 a real polarizer sees.
    pub fn polarizer_efficiency(&self) -> f32 {
        self.extinction_ratio.map_or(1.0, |er| (er - 1.0) / (er + 1.0))
    }

    /// The raw frame the sensor records of linear Stokes images at half its resolution (one
    /// Stokes pixel per 2x2 polarizer cell; RGB for the colour sensor, one channel for mono).
    /// Noise is drawn from streams keyed by `seed` and `frame`: deterministic.
    pub fn expose(&self, stokes: &Stokes, seed: u64, frame: u32) -> RawFrame {
        self.digitize(&self.electrons(stokes), seed, frame)
    }

    /// Mean photo-electrons of every sensor pixel (behind its polarizer and colour filter) for
    /// linear Stokes images at half the sensor's resolution: the noise-free part of
    /// [`SensorModel::expose`].
    pub fn electrons(&self, stokes: &Stokes) -> Image<f32> {
        let (w, h) = stokes.s0.size();
        let c = stokes.s0.channels();
        let efficiency = self.polarizer_efficiency();
        let angles: [(f32, f32); 4] = POLARIZER_ANGLES_DEG.map(|d| {
            let t = 2.0 * (d as f32).to_radians();
            (t.cos(), t.sin())
        });
        let mut electrons = Image::new(2 * w, 2 * h, 1);
        electrons.data_mut().par_chunks_mut(2 * w).enumerate().for_each(|(y, row)| {
            for (x, out) in row.iter_mut().enumerate() {
                let angle = POLARIZER_OFFSETS.iter().position(|&o| o == (x % 2, y % 2)).expect("four offsets");
                let (cx, cy) = (x / 2, y / 2);
                let ch = match self.layout {
                    SensorLayout::ColorPolarized if c == 3 => bayer_channel(cx, cy),
                    _ => 0,
                };
                let k = (cy * w + cx) * c + ch;
                let (cos, sin) = angles[angle];
                let s = [stokes.s0.data()[k], stokes.s1.data()[k], stokes.s2.data()[k]];
                let intensity = 0.5 * (s[0] + efficiency * (s[1] * cos + s[2] * sin));
                *out = (intensity * self.exposure * self.full_well).max(0.0);
            }
        });
        electrons
    }

    /// One noisy frame of mean `electrons` (from [`SensorModel::electrons`]): shot noise, read
    /// noise, gain, black level, quantization and saturation. Deterministic in `seed`, `frame`.
    pub fn digitize(&self, electrons: &Image<f32>, seed: u64, frame: u32) -> RawFrame {
        let w = electrons.width();
        let full = ((1u32 << self.bits) - 1) as f32;
        let to_counts = self.counts_per_electron();
        let mut pixels = Image::new(w, electrons.height(), 1);
        pixels.data_mut().par_chunks_mut(w).zip(electrons.data().par_chunks(w)).enumerate().for_each(
            |(y, (row, mean))| {
                let mut rng = Rng::for_pixel(seed, frame, y as u64);
                for (out, &mean) in row.iter_mut().zip(mean) {
                    let mut e = mean;
                    if self.shot_noise {
                        e = poisson(&mut rng, e);
                    }
                    e += self.read_noise * rng.normal();
                    *out = (e * to_counts + self.dark_offset).round().clamp(0.0, full) as u16;
                }
            },
        );
        RawFrame { layout: self.layout, bits: self.bits, pixels }
    }

    /// The frame a capped lens gives: the black level (with read noise if enabled).
    pub fn dark_frame(&self, width: usize, height: usize, seed: u64) -> RawFrame {
        let black = Stokes {
            s0: Image::new(width, height, 3),
            s1: Image::new(width, height, 3),
            s2: Image::new(width, height, 3),
        };
        self.expose(&black, seed, u32::MAX)
    }
}

/// The description of simulated raw frames (`sensor.json` beside them): what the frames are
/// and how their processed Stokes relate to the rendered light.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SensorRecord {
    /// Pixel format of the frame files.
    pub pixel_format: PixelFormat,
    /// Frame width, sensor pixels.
    pub width: usize,
    /// Frame height, sensor pixels.
    pub height: usize,
    /// The sensor that exposed them.
    pub model: SensorModel,
    /// [`SensorModel::stokes_gain`]: processed Stokes (dark frame subtracted) divided by it are
    /// the rendered Stokes.
    pub stokes_gain: f32,
}

/// The file name of a [`SensorRecord`] beside the frames.
pub const SENSOR_FILE: &str = "sensor.json";

impl SensorRecord {
    /// The record of frames of `width x height` in `pixel_format` exposed by `model`.
    pub fn new(model: SensorModel, pixel_format: PixelFormat, width: usize, height: usize) -> Self {
        Self { pixel_format, width, height, stokes_gain: model.stokes_gain(), model }
    }

    /// Read `path`.
    pub fn read(path: &Path) -> Result<Self> {
        Ok(read_json(path, "a sensor record")?)
    }

    /// Write `path` atomically.
    pub fn write(&self, path: &Path) -> Result<()> {
        Ok(write_json(path, self)?)
    }
}

/// A Poisson sample of mean `lambda`: exact (Knuth) below 30, normal approximation above.
fn poisson(rng: &mut Rng, lambda: f32) -> f32 {
    if lambda >= 30.0 {
        return (lambda + lambda.sqrt() * rng.normal()).max(0.0);
    }
    let limit = (-lambda).exp();
    let (mut k, mut p) = (0.0, 1.0);
    loop {
        p *= rng.next_f32();
        if p <= limit {
            return k;
        }
        k += 1.0;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn poisson_has_its_mean_and_variance() {
        let mut rng = Rng::for_pixel(4, 0, 0);
        for lambda in [0.5f32, 7.0, 80.0] {
            let n = 50_000;
            let xs: Vec<f64> = (0..n).map(|_| poisson(&mut rng, lambda) as f64).collect();
            let mean = xs.iter().sum::<f64>() / n as f64;
            let var = xs.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / n as f64;
            assert!((mean - lambda as f64).abs() < 0.05 * lambda as f64 + 0.02, "{lambda}: mean {mean}");
            assert!((var - lambda as f64).abs() < 0.08 * lambda as f64 + 0.05, "{lambda}: var {var}");
        }
    }

    #[test]
    fn sensor_records_read_back_what_they_wrote() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join(SENSOR_FILE);
        let model =
            SensorModel { exposure: 0.37, gain_db: 2.5, extinction_ratio: Some(150.0), ..SensorModel::default() };
        let record = SensorRecord::new(model, PixelFormat::BAYER_RG_POLARIZED_12P, 384, 320);
        record.write(&path).unwrap();
        assert_eq!(SensorRecord::read(&path).unwrap(), record);
        assert!((record.stokes_gain - 0.37 * 10f32.powf(2.5 / 20.0)).abs() < 1e-6);
        std::fs::write(&path, r#"{"pixel_format": "RGB8"}"#).unwrap();
        let err = SensorRecord::read(&path).unwrap_err().to_string();
        assert!(err.contains(SENSOR_FILE) && err.contains("RGB8"), "{err}");
    }

    #[test]
    fn extinction_ratio_scales_the_linear_part() {
        let model = SensorModel { extinction_ratio: Some(99.0), ..SensorModel::default() };
        assert!((model.polarizer_efficiency() - 0.98).abs() < 1e-6);
        assert_eq!(SensorModel::default().polarizer_efficiency(), 1.0);
    }
}
