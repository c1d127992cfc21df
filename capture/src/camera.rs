//! GenICam cameras through aravis: discovery, opening by serial or address, features by their
//! GenICam names, pixel-format negotiation and streaming with a buffer pool. The same code
//! drives the FLIR Blackfly S over USB3 Vision and the simulated camera over GigE Vision.

use crate::raw::PixelFormat;
use crate::{Error, Result};
use aravis::glib::prelude::Cast;
use aravis::prelude::*;
pub use rmvp_dataset::session::{CameraIdentity, CameraOptions, TriggerSource};
use serde::{Deserialize, Serialize};
use std::sync::{Mutex, OnceLock};
use std::time::Duration;

/// A camera aravis can see.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct DeviceInfo {
    /// aravis's device id (vendor-model-serial).
    pub id: String,
    /// Vendor name.
    pub vendor: String,
    /// Model name.
    pub model: String,
    /// Transport: `USB3Vision` or `GigEVision`.
    pub protocol: String,
    /// Network address (GigE Vision) or bus path (USB3 Vision).
    pub address: String,
}

/// aravis's global device list (the library allows one owner per process).
fn aravis_token() -> &'static Mutex<aravis::Aravis> {
    static TOKEN: OnceLock<Mutex<aravis::Aravis>> = OnceLock::new();
    TOKEN.get_or_init(|| Mutex::new(aravis::Aravis::initialize().expect("only rmvp initialises aravis")))
}

/// Every GenICam camera aravis finds (USB3 Vision and GigE Vision, including simulated ones).
pub fn list_devices() -> Vec<DeviceInfo> {
    let text = |s: &std::ffi::CStr| s.to_string_lossy().into_owned();
    aravis_token()
        .lock()
        .expect("aravis token")
        .get_device_list()
        .into_iter()
        .map(|d| DeviceInfo {
            id: text(&d.id),
            vendor: text(&d.vendor),
            model: text(&d.model),
            protocol: text(&d.protocol),
            address: text(&d.address),
        })
        .collect()
}

/// Pixel formats in order of preference: the full 12-bit depth packed, then 16-bit, 10-bit
/// packed, 8-bit; polarization-named formats first, then the same bytes under Bayer names, then
/// the mono polarization sensor.
pub fn preferred_pixel_formats() -> Vec<String> {
    let mut names = Vec::new();
    for family in ["BayerRGPolarized", "BayerRG", "Polarized"] {
        for depth in ["12p", "16", "12", "10p", "8"] {
            names.push(format!("{family}{depth}"));
        }
    }
    names
}

/// The pixel format to stream, from the names a camera offers: `requested` if given (it must be
/// offered and one we decode), else the first of [`preferred_pixel_formats`] that is offered.
pub fn choose_pixel_format(offered: &[String], requested: Option<&str>) -> Result<PixelFormat> {
    if let Some(name) = requested {
        if !offered.iter().any(|o| o == name) {
            return Err(Error::Unsupported(format!(
                "the camera does not offer pixel format {name}; it offers {}",
                offered.join(", ")
            )));
        }
        return PixelFormat::from_name(name);
    }
    preferred_pixel_formats()
        .iter()
        .find(|name| offered.contains(name))
        .map(|name| PixelFormat::from_name(name))
        .unwrap_or_else(|| {
            Err(Error::Unsupported(format!(
                "none of the camera's pixel formats ({}) is a polarization mosaic rmvp reads \
                 (BayerRGPolarized*, BayerRG*, Polarized*)",
                offered.join(", ")
            )))
        })
}

/// One pop from the stream.
#[derive(Debug)]
pub enum Grab {
    /// A complete frame, as the camera sent it.
    Frame(Vec<u8>),
    /// A frame the stream lost or could not complete (status from aravis).
    Dropped(String),
    /// No frame within the time-out, but the camera still answers.
    Timeout,
}

/// An open camera.
pub struct CameraDevice {
    camera: aravis::Camera,
    device: aravis::Device,
    name: String,
    stream: Option<aravis::Stream>,
    format: PixelFormat,
    width: usize,
    height: usize,
}

/// Frame buffers queued to the stream.
const STREAM_BUFFERS: usize = 8;

impl CameraDevice {
    /// Open the first camera (`None`), or the one whose serial number, address or aravis id is
    /// `selector`.
    pub fn open(selector: Option<&str>) -> Result<Self> {
        let name = selector.unwrap_or("first camera").to_string();
        let id = selector.map(|s| {
            list_devices()
                .into_iter()
                .find(|d| d.address == s || d.id == s || d.id.ends_with(&format!("-{s}")))
                .map_or_else(|| s.to_string(), |d| d.id)
        });
        let camera = aravis::Camera::new(id.as_deref()).map_err(|e| {
            Error::camera(&name, format!("cannot open ({e}); cameras found: {}", describe(&list_devices())))
        })?;
        let device = camera.device().ok_or_else(|| Error::camera(&name, "no GenICam device behind the camera"))?;
        let mut camera = Self {
            camera,
            device,
            name,
            stream: None,
            format: PixelFormat::BAYER_RG_POLARIZED_12P,
            width: 0,
            height: 0,
        };
        let identity = camera.identity();
        camera.name = format!("{} {} ({})", identity.vendor, identity.model, identity.serial);
        camera.read_geometry()?;
        Ok(camera)
    }

    /// The camera's name in messages: vendor, model and serial.
    pub fn name(&self) -> &str {
        &self.name
    }

    /// Vendor, model, serial and firmware.
    pub fn identity(&self) -> CameraIdentity {
        let read = |f: &str| self.feature(f).unwrap_or_default();
        let firmware = self.feature("DeviceFirmwareVersion").or_else(|_| self.feature("DeviceVersion"));
        CameraIdentity {
            vendor: read("DeviceVendorName"),
            model: read("DeviceModelName"),
            serial: read("DeviceSerialNumber"),
            firmware: firmware.unwrap_or_default(),
            protocol: if self.camera.is_uv_device() { "USB3Vision" } else { "GigEVision" }.into(),
        }
    }

    /// Whether the camera has a feature of this GenICam name.
    pub fn has_feature(&self, name: &str) -> bool {
        self.device.feature(name).is_some()
    }

    fn node(&self, name: &str) -> Result<aravis::GcFeatureNode> {
        self.device
            .feature(name)
            .and_then(|n| n.downcast::<aravis::GcFeatureNode>().ok())
            .ok_or_else(|| Error::camera(&self.name, format!("has no feature {name}")))
    }

    /// A feature's value as text (enumerations by entry name, floats and integers in decimal).
    pub fn feature(&self, name: &str) -> Result<String> {
        self.node(name)?
            .value_as_string()
            .map(|s| s.to_string())
            .map_err(|e| Error::camera(&self.name, format!("cannot read {name}: {e}")))
    }

    /// Set a feature from text, as [`CameraDevice::feature`] writes it.
    pub fn set_feature(&self, name: &str, value: &str) -> Result<()> {
        self.node(name)?
            .set_value_from_string(value)
            .map_err(|e| Error::camera(&self.name, format!("cannot set {name} = {value}: {e}")))
    }

    /// A float feature (e.g. `ExposureTime`, `Gain`, `DeviceTemperature`).
    pub fn float(&self, name: &str) -> Result<f64> {
        self.device.float_feature_value(name).map_err(|e| Error::camera(&self.name, format!("cannot read {name}: {e}")))
    }

    /// Set a float feature.
    pub fn set_float(&self, name: &str, value: f64) -> Result<()> {
        self.device
            .set_float_feature_value(name, value)
            .map_err(|e| Error::camera(&self.name, format!("cannot set {name} = {value}: {e}")))
    }

    /// An integer feature.
    pub fn integer(&self, name: &str) -> Result<i64> {
        self.device
            .integer_feature_value(name)
            .map_err(|e| Error::camera(&self.name, format!("cannot read {name}: {e}")))
    }

    /// Set an integer feature.
    pub fn set_integer(&self, name: &str, value: i64) -> Result<()> {
        self.device
            .set_integer_feature_value(name, value)
            .map_err(|e| Error::camera(&self.name, format!("cannot set {name} = {value}: {e}")))
    }

    /// Run a command feature (e.g. `AcquisitionStart`).
    pub fn execute(&self, name: &str) -> Result<()> {
        self.device.execute_command(name).map_err(|e| Error::camera(&self.name, format!("{name} failed: {e}")))
    }

    /// The names of the pixel formats the camera offers now.
    pub fn offered_pixel_formats(&self) -> Result<Vec<String>> {
        self.camera
            .dup_available_pixel_formats_as_strings()
            .map(|v| v.into_iter().map(|s| s.to_string()).collect())
            .map_err(|e| Error::camera(&self.name, format!("cannot list pixel formats: {e}")))
    }

    fn read_geometry(&mut self) -> Result<()> {
        self.width = self.integer("Width")? as usize;
        self.height = self.integer("Height")? as usize;
        if let Ok(name) = self.feature("PixelFormat") {
            if let Ok(format) = PixelFormat::from_name(&name) {
                self.format = format;
            }
        }
        Ok(())
    }

    /// Apply `settings`: pixel format (negotiated), auto exposure and gain off, exposure time,
    /// gain, frame rate and trigger. Returns the pixel format chosen.
    pub fn configure(&mut self, settings: &CameraOptions) -> Result<PixelFormat> {
        let format = choose_pixel_format(&self.offered_pixel_formats()?, settings.pixel_format.as_deref())?;
        // The buffer pool is sized for the payload: a new format needs a new pool.
        self.stream = None;
        self.set_feature("PixelFormat", &format.name())?;
        for auto in ["ExposureAuto", "GainAuto"] {
            if self.has_feature(auto) {
                self.set_feature(auto, "Off")?;
            }
        }
        self.set_exposure(settings.exposure_us)?;
        self.set_float("Gain", settings.gain_db)?;
        if self.has_feature("AcquisitionFrameRateEnable") {
            self.set_feature(
                "AcquisitionFrameRateEnable",
                if settings.frame_rate.is_some() { "true" } else { "false" },
            )?;
        }
        if let Some(rate) = settings.frame_rate {
            self.set_float("AcquisitionFrameRate", rate)?;
        }
        self.set_feature("AcquisitionMode", "Continuous")?;
        if self.has_feature("TriggerSelector") {
            self.set_feature("TriggerSelector", "FrameStart")?;
        }
        // FLIR cameras only accept a trigger source while the trigger is off.
        self.set_feature("TriggerMode", "Off")?;
        if settings.trigger == TriggerSource::Line0 {
            self.set_feature("TriggerSource", "Line0")?;
            self.set_feature("TriggerMode", "On")?;
        }
        self.read_geometry()?;
        if self.format != format {
            return Err(Error::camera(
                &self.name,
                format!("asked for {} but streams {}", format.name(), self.format.name()),
            ));
        }
        Ok(format)
    }

    /// Set `ExposureTime` (microseconds), e.g. between HDR brackets.
    pub fn set_exposure(&self, exposure_us: f64) -> Result<()> {
        self.set_float("ExposureTime", exposure_us)
    }

    /// Pixel format, width and height of the frames.
    pub fn frame_format(&self) -> (PixelFormat, usize, usize) {
        (self.format, self.width, self.height)
    }

    /// Create the stream (if needed), queue the buffer pool and start acquiring.
    pub fn start(&mut self) -> Result<()> {
        if self.stream.is_none() {
            if self.camera.is_gv_device() {
                // The largest packet the path carries (jumbo frames, 64 KiB on loopback): fewer
                // packets per frame. A camera that cannot tell keeps its default.
                let _ = self.camera.gv_auto_packet_size();
            }
            let stream = self
                .camera
                .create_stream()
                .map_err(|e| Error::camera(&self.name, format!("cannot open a stream: {e}")))?;
            let payload = self.camera.payload().map_err(|e| Error::camera(&self.name, format!("PayloadSize: {e}")))?;
            for _ in 0..STREAM_BUFFERS {
                stream.push_buffer(aravis::Buffer::new_allocate(payload as usize));
            }
            self.stream = Some(stream);
        }
        self.execute("AcquisitionStart")
    }

    /// Stop acquiring and return frames still queued to the pool.
    pub fn stop(&mut self) -> Result<()> {
        let result = self.execute("AcquisitionStop");
        if let Some(stream) = &self.stream {
            while let Some(buffer) = stream.timeout_pop_buffer(100_000) {
                stream.push_buffer(buffer);
            }
        }
        result
    }

    /// The next frame, waiting at most `timeout`. A camera that no longer answers (unplugged,
    /// powered off, its process killed) is an error naming it.
    pub fn grab(&mut self, timeout: Duration) -> Result<Grab> {
        let stream = self.stream.as_ref().ok_or_else(|| Error::camera(&self.name, "grab before start"))?;
        let Some(buffer) = stream.timeout_pop_buffer(timeout.as_micros() as u64) else {
            return match self.feature("DeviceSerialNumber") {
                Ok(_) => Ok(Grab::Timeout),
                Err(e) => Err(Error::camera(
                    &self.name,
                    format!("stopped answering during acquisition (unplugged or powered off?): {e}"),
                )),
            };
        };
        let status = buffer.status();
        let grab = if status == aravis::BufferStatus::Success {
            let (data, size) = buffer.data();
            let expected = self.format.frame_bytes(self.width, self.height);
            let n = if size == 0 { expected } else { size.min(expected) };
            // SAFETY: aravis owns `n <= allocated` readable bytes at `data` until we push the
            // buffer back below.
            Grab::Frame(unsafe { std::slice::from_raw_parts(data, n) }.to_vec())
        } else {
            Grab::Dropped(format!("{status:?}"))
        };
        stream.push_buffer(buffer);
        Ok(grab)
    }
}

impl Drop for CameraDevice {
    fn drop(&mut self) {
        if self.stream.is_some() {
            let _ = self.execute("AcquisitionStop");
        }
    }
}

/// A one-line list of cameras for messages.
pub fn describe(devices: &[DeviceInfo]) -> String {
    if devices.is_empty() {
        return "none found. A USB3 Vision camera needs a USB 3 port, a udev rule that lets this user \
                open it and about 1000 MB of usbfs memory (/sys/module/usbcore/parameters/\
                usbfs_memory_mb; the camera setup script does both, see the acquisition guide); a \
                GigE Vision camera must be on this machine's subnet. Without a camera, \
                `rmvp capture --simulated` runs the same session on a simulated one."
            .into();
    }
    devices.iter().map(|d| format!("{} [{} at {}]", d.id, d.protocol, d.address)).collect::<Vec<_>>().join(", ")
}

#[cfg(test)]
mod tests {
    use super::*;

    fn names(list: &[&str]) -> Vec<String> {
        list.iter().map(|s| s.to_string()).collect()
    }

    #[test]
    fn negotiation_prefers_polarized_twelve_bit_packed() {
        let flir = names(&["BayerRG8", "BayerRG16", "BayerRGPolarized8", "BayerRGPolarized12p", "BayerRGPolarized16"]);
        assert_eq!(choose_pixel_format(&flir, None).unwrap().name(), "BayerRGPolarized12p");
        let bayer_only = names(&["Mono8", "BayerRG8", "BayerRG16", "RGB8"]);
        assert_eq!(choose_pixel_format(&bayer_only, None).unwrap().name(), "BayerRG16");
        let mono = names(&["Mono8", "Polarized8", "Polarized12p"]);
        assert_eq!(choose_pixel_format(&mono, None).unwrap().name(), "Polarized12p");
        assert_eq!(choose_pixel_format(&flir, Some("BayerRGPolarized8")).unwrap().name(), "BayerRGPolarized8");
        let err = choose_pixel_format(&flir, Some("Polarized8")).unwrap_err().to_string();
        assert!(err.contains("does not offer"), "{err}");
        let err = choose_pixel_format(&names(&["Mono8", "RGB8"]), None).unwrap_err().to_string();
        assert!(err.contains("Mono8, RGB8"), "{err}");
    }
}
