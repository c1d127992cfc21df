//! What the simulated camera's firmware does with its registers: where it keeps each setting
//! the frames depend on (rmvp's own description, or a real camera's served through
//! [`super::served`]), what they hold when it starts, and what it updates while it runs.

use super::gige::Registers;
use super::served::{Register, ServedDescription};
use super::{register, LeftState, Readout, ADC_BITS, LINK_THROUGHPUT_LIMIT};
use crate::{Error, Result};

/// How a setting is stored in its register.
#[derive(Clone, Copy, Debug)]
enum Encoding {
    Unsigned,
    Signed,
    Float32,
}

/// A setting's register: where, how, and the scale from the stored number to the setting's unit.
#[derive(Clone, Copy, Debug)]
struct Field {
    address: u32,
    encoding: Encoding,
    little_endian: bool,
    scale: f64,
}

impl Field {
    /// A big-endian register of rmvp's own description.
    const fn own(address: u32, encoding: Encoding) -> Self {
        Self { address, encoding, little_endian: false, scale: 1.0 }
    }

    fn served(register: Register, encoding: Encoding, scale: f64) -> Self {
        Self { address: register.address, encoding, little_endian: register.little_endian, scale }
    }

    fn word(&self, camera: &Registers) -> u32 {
        let bytes = camera.read(self.address).to_be_bytes();
        if self.little_endian {
            u32::from_le_bytes(bytes)
        } else {
            u32::from_be_bytes(bytes)
        }
    }

    fn read(&self, camera: &Registers) -> f64 {
        let word = self.word(camera);
        let stored = match self.encoding {
            Encoding::Unsigned => f64::from(word),
            Encoding::Signed => f64::from(word as i32),
            Encoding::Float32 => f64::from(f32::from_bits(word)),
        };
        stored * self.scale
    }

    fn write(&self, camera: &Registers, value: f64) {
        let stored = value / self.scale;
        let word = match self.encoding {
            Encoding::Unsigned => stored.round().max(0.0) as u32,
            Encoding::Signed => stored.round() as i32 as u32,
            Encoding::Float32 => (stored as f32).to_bits(),
        };
        let bytes = if self.little_endian { word.to_le_bytes() } else { word.to_be_bytes() };
        camera.write(self.address, u32::from_be_bytes(bytes));
    }
}

/// The settings the frames depend on.
#[derive(Clone, Copy, Debug)]
struct Settings {
    exposure_us: Field,
    gain_db: Field,
    gamma: Field,
    reverse_x: Field,
    reverse_y: Field,
    adc_depth: Field,
    offset_x: Field,
    offset_y: Field,
    temperature_c: Field,
}

/// What a served FLIR description's firmware keeps up to date.
#[derive(Clone, Copy, Debug)]
struct FlirTiming {
    stop: Field,
    rate_enabled: Field,
    frame_time_us: Field,
    frame_time_min_us: Field,
    resulting_frame_time_us: Field,
    current_throughput: Option<Field>,
    payload_size: Field,
}

/// The fastest the simulated sensor reads out, frames a second.
const MAX_FRAME_RATE: f64 = 75.0;
/// FLIR's fixed-point scale of the sensor temperature (`DeviceTemperature_Posn`).
const TEMPERATURE_FRACTION_BITS: u32 = 8;
/// FLIR's fixed-point scale of the black level (`BlackLevel_Posn`).
const BLACK_LEVEL_FRACTION_BITS: u32 = 16;
/// FLIR's gain register: 2^14 counts per factor of two (6.0206 dB).
const GAIN_DB_PER_COUNT: f64 = 6.020_599_913 / 16_384.0;

/// The firmware of one simulated camera.
pub(super) struct Firmware {
    settings: Settings,
    timing: Option<FlirTiming>,
}

impl Firmware {
    /// rmvp's own description (`capture/genicam/`).
    pub(super) fn own() -> Self {
        use Encoding::*;
        Self {
            settings: Settings {
                exposure_us: Field::own(register::EXPOSURE_TIME_US, Unsigned),
                gain_db: Field::own(register::GAIN_DB, Float32),
                gamma: Field::own(register::GAMMA_ENABLE, Unsigned),
                reverse_x: Field::own(register::REVERSE_X, Unsigned),
                reverse_y: Field::own(register::REVERSE_Y, Unsigned),
                adc_depth: Field::own(register::ADC_BIT_DEPTH, Unsigned),
                offset_x: Field::own(register::OFFSET_X, Unsigned),
                offset_y: Field::own(register::OFFSET_Y, Unsigned),
                temperature_c: Field::own(register::TEMPERATURE_C, Float32),
            },
            timing: None,
        }
    }

    /// A served FLIR Blackfly S description: its value registers, with FLIR's fixed-point
    /// scales.
    pub(super) fn flir(served: &ServedDescription) -> Result<Self> {
        use Encoding::*;
        let field = |name: &str, encoding: Encoding, scale: f64| {
            served.register(name).map(|r| Field::served(r, encoding, scale)).ok_or_else(|| {
                Error::Unsupported(format!("the served description has no register {name}, which the simulator drives"))
            })
        };
        let settings = Settings {
            exposure_us: field("ExposureTime_Val", Unsigned, 1.0)?,
            gain_db: field("Gain_Val", Signed, GAIN_DB_PER_COUNT)?,
            gamma: field("GammaEnable_Val", Unsigned, 1.0)?,
            reverse_x: field("ReverseX_Val", Unsigned, 1.0)?,
            reverse_y: field("ReverseY_Val", Unsigned, 1.0)?,
            adc_depth: field("AdcBitDepth_Val", Unsigned, 1.0)?,
            offset_x: field("OffsetX_Val", Unsigned, 1.0)?,
            offset_y: field("OffsetY_Val", Unsigned, 1.0)?,
            temperature_c: field("DeviceTemperature_Val", Signed, 1.0 / f64::from(1u32 << TEMPERATURE_FRACTION_BITS))?,
        };
        let timing = FlirTiming {
            stop: field("AcquisitionStop_Val", Unsigned, 1.0)?,
            rate_enabled: field("FrameRateEn_Val", Unsigned, 1.0)?,
            frame_time_us: field("FrameTime_Val", Unsigned, 1.0)?,
            frame_time_min_us: field("FrameTime_Min", Unsigned, 1.0)?,
            resulting_frame_time_us: field("ResultingFrameTime_Val", Unsigned, 1.0)?,
            current_throughput: field("DeviceLinkCurrentThroughput_Val", Unsigned, 1.0).ok(),
            payload_size: field("PayloadSize_Val", Unsigned, 1.0)?,
        };
        Ok(Self { settings, timing: Some(timing) })
    }

    /// Exposure time, microseconds.
    pub(super) fn exposure_us(&self, camera: &Registers) -> u32 {
        self.settings.exposure_us.read(camera).round().max(0.0) as u32
    }

    /// Analog gain, dB.
    pub(super) fn gain_db(&self, camera: &Registers) -> f32 {
        self.settings.gain_db.read(camera) as f32
    }

    /// The readout settings the frames go through.
    pub(super) fn readout(&self, camera: &Registers) -> Readout {
        let s = &self.settings;
        let on = |f: &Field| f.read(camera) != 0.0;
        Readout {
            adc_bits: ADC_BITS.get(s.adc_depth.read(camera) as usize).copied().unwrap_or(12),
            gamma: on(&s.gamma),
            reverse_x: on(&s.reverse_x),
            reverse_y: on(&s.reverse_y),
            offset_x: s.offset_x.read(camera) as u32,
            offset_y: s.offset_y.read(camera) as u32,
        }
    }

    /// The sensor's temperature, degrees C.
    pub(super) fn set_temperature(&self, camera: &Registers, celsius: f64) {
        self.settings.temperature_c.write(camera, celsius);
    }

    /// The state the camera starts in: what another program left (`left`), the readout
    /// settings of a camera fresh from its default user set otherwise.
    pub(super) fn start_as(&self, camera: &Registers, left: &LeftState) {
        let s = &self.settings;
        s.exposure_us.write(camera, super::REFERENCE_EXPOSURE_US);
        s.gain_db.write(camera, 0.0);
        s.gamma.write(camera, f64::from(u8::from(left.gamma)));
        s.reverse_x.write(camera, f64::from(u8::from(left.reverse_x)));
        s.reverse_y.write(camera, f64::from(u8::from(left.reverse_y)));
        s.offset_x.write(camera, f64::from(left.offset_x));
        s.offset_y.write(camera, 0.0);
        s.adc_depth.write(camera, if left.adc_8_bits { 0.0 } else { 2.0 });
        s.temperature_c.write(camera, 36.0);
    }

    /// What the firmware keeps current while it runs: a stop command, the payload of a frame,
    /// the shortest frame time the exposure allows, the frame time it runs at (and streams at)
    /// and the link's load.
    pub(super) fn tick(&self, camera: &Registers, payload_bytes: u64) {
        let Some(t) = &self.timing else { return };
        t.payload_size.write(camera, payload_bytes as f64);
        if t.stop.read(camera) != 0.0 {
            t.stop.write(camera, 0.0);
            camera.write(register::ACQUISITION, 0);
        }
        let exposure = self.settings.exposure_us.read(camera);
        let shortest = exposure.max(1e6 / MAX_FRAME_RATE).ceil();
        t.frame_time_min_us.write(camera, shortest);
        let frame_time =
            if t.rate_enabled.read(camera) != 0.0 { t.frame_time_us.read(camera).max(shortest) } else { shortest };
        t.resulting_frame_time_us.write(camera, frame_time);
        camera.write(register::FRAME_PERIOD_US, frame_time as u32);
        if let Some(throughput) = &t.current_throughput {
            throughput.write(camera, payload_bytes as f64 * 1e6 / frame_time);
        }
    }
}

/// A served description's registers as a BFS-U3-51S5PC-C's firmware fills them: every flag of
/// what is implemented and available set (the description's own `initial`), then limits,
/// values and the fixed-point scales its converters read. `format_code` is the pixel format it
/// starts streaming; `serial` its serial number.
pub(super) fn flir_defaults(
    served: &ServedDescription,
    format_code: u32,
    serial: &str,
    left: &LeftState,
) -> Vec<(u32, Vec<u8>)> {
    let mut writes = served.initial.clone();
    let (w, h) = (super::SENSOR_WIDTH as u64, super::SENSOR_HEIGHT as u64);
    let black_level = super::black_level_fraction();
    let values: [(&str, u64); 32] = [
        ("Width_Val", w),
        ("Width_Min", 16),
        ("Width_Max", w),
        ("Width_Inc", 4),
        ("Height_Val", h),
        ("Height_Min", 4),
        ("Height_Max", h),
        ("Height_Inc", 2),
        ("OffsetX_Max", 0),
        ("OffsetX_Inc", 4),
        ("OffsetY_Max", 0),
        ("OffsetY_Inc", 2),
        ("SensorWidth_Val", w),
        ("SensorHeight_Val", h),
        ("PixelFormat_Val", u64::from(format_code)),
        ("ExposureTime_Min", 10),
        ("ExposureTime_Max", 30_000_000),
        ("Gain_Max", (47.99 / GAIN_DB_PER_COUNT) as u64),
        ("FrameRateNumerator_Val", 1_000_000),
        ("ResultingFrameRateNumerator_Val", 1_000_000),
        ("FrameTime_Val", 40_000),
        ("FrameTime_Max", 1_000_000),
        ("DeviceTemperature_Posn", u64::from(TEMPERATURE_FRACTION_BITS)),
        ("BlackLevel_Posn", u64::from(BLACK_LEVEL_FRACTION_BITS)),
        ("BlackLevel_Val", (black_level * f64::from(1u32 << BLACK_LEVEL_FRACTION_BITS)) as u64),
        ("BlackLevel_Max", (0.1 * f64::from(1u32 << BLACK_LEVEL_FRACTION_BITS)) as u64),
        ("ExposureAuto_Val", 2),
        ("GainAuto_Val", 2),
        ("DeviceLinkThroughputLimit_Val", u64::from(LINK_THROUGHPUT_LIMIT)),
        ("DeviceLinkThroughputLimit_Min", 50_000_000),
        ("DeviceLinkThroughputLimit_Max", 500_000_000),
        ("DeviceLinkSpeedBps_Val", 625_000_000),
    ];
    for (name, value) in values {
        if let Some(register) = served.register(name) {
            writes.push((register.address, register.bytes(value)));
        }
    }
    let strings = [
        ("DeviceVendorName", "FLIR".to_string()),
        ("DeviceModelName", format!("Simulated {}", served.model)),
        ("DeviceSerialNumber", serial.to_string()),
        ("DeviceFirmwareVersion", concat!("rmvp-sim ", env!("CARGO_PKG_VERSION")).to_string()),
    ];
    for (name, text) in strings {
        if let Some(register) = served.register(name) {
            let mut bytes = text.into_bytes();
            bytes.resize(register.length as usize, 0);
            writes.push((register.address, bytes));
        }
    }
    if left.readout_locked {
        for lock in ["ReverseX_Lck", "ReverseY_Lck"] {
            if let Some((register, bit)) = served.flag(lock) {
                writes.push((register.address, register.bytes(1 << bit)));
            }
        }
    }
    writes
}
