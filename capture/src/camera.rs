//! GenICam cameras through aravis: discovery, opening by serial or address, features by their
//! GenICam names, pixel-format negotiation and streaming with a buffer pool. The same code
//! drives the FLIR Blackfly S over USB3 Vision and the simulated camera over GigE Vision.

use crate::gigevision::bootstrap;
use crate::mosaic::SensorLayout;
use crate::raw::PixelFormat;
use crate::{Error, Result};
use aravis::glib::prelude::Cast;
use aravis::prelude::*;
pub use rmvp_dataset::session::{CameraIdentity, CameraOptions, TriggerSource};
use serde::{Deserialize, Serialize};
use std::net::{Ipv4Addr, SocketAddrV4};
use std::sync::{Mutex, OnceLock};
use std::time::Duration;

pub mod holders;
pub mod polarizers;

/// Who controls an open camera.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Control {
    /// This process.
    Ours,
    /// Another application, at the address and port the camera reports (`None`: it does not
    /// say; GigE Vision before 2.0).
    Elsewhere(Option<SocketAddrV4>),
}

/// What to tell the user when another application holds a GigE Vision camera's control
/// channel, at `holder` as the camera reports it.
pub fn controlled_elsewhere(holder: Option<SocketAddrV4>) -> String {
    let by = match holder {
        Some(address) => format!("another application at {address}"),
        None => "another application (the camera does not say which)".into(),
    };
    format!(
        "is controlled by {by}: close it (SpinView, another rmvp, any GigE Vision viewer), or wait for \
         it to let go; a camera takes commands from one application at a time, and one that stopped \
         without letting go is free again after its heartbeat timeout (a few seconds)"
    )
}

/// What to tell the user when a USB3 Vision camera (USB serial `serial`) is claimed by another
/// application: the processes holding its device node, where this user may see them.
fn usb_claimed_elsewhere(serial: &str) -> String {
    let node = holders::usb_device_node(serial);
    let holders = node.as_deref().map(holders::holders_of).unwrap_or_default();
    let by = match (&node, holders.is_empty()) {
        (Some(node), false) => format!(
            "{} (holding {})",
            holders.iter().map(ToString::to_string).collect::<Vec<_>>().join(", "),
            node.display()
        ),
        _ => "another application (not one this user can see)".into(),
    };
    format!(
        "is controlled by {by}: close it (SpinView, another rmvp, any USB3 Vision viewer); the kernel \
         gives a USB camera to one application at a time"
    )
}

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

impl DeviceInfo {
    /// Whether `selector` names this camera: its address, its aravis id, or the serial that
    /// ends the id. Over USB3 Vision aravis ends the id with the USB serial in hexadecimal
    /// while the label and `DeviceSerialNumber` give it in decimal, so a decimal serial also
    /// matches its hexadecimal form (with or without leading zeros, any case).
    pub fn selected_by(&self, selector: &str) -> bool {
        let serial = self.id.rsplit('-').next().unwrap_or_default();
        let hex_of_label = selector
            .parse::<u64>()
            .ok()
            .filter(|_| self.protocol == "USB3Vision")
            .is_some_and(|n| u64::from_str_radix(serial, 16).is_ok_and(|usb| usb == n));
        self.address == selector || self.id == selector || serial == selector || hex_of_label
    }
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
    /// `selector`, to control it. A camera that another application controls is refused,
    /// naming that application ([`controlled_elsewhere`]).
    pub fn open(selector: Option<&str>) -> Result<Self> {
        let (camera, control) = Self::open_to_inspect(selector)?;
        match control {
            Control::Ours => Ok(camera),
            Control::Elsewhere(holder) => Err(Error::camera(&camera.name, controlled_elsewhere(holder))),
        }
    }

    /// Open a camera as [`CameraDevice::open`] does, also when another application controls it
    /// (then its features can be read, not written), and say who controls it.
    pub fn open_to_inspect(selector: Option<&str>) -> Result<(Self, Control)> {
        let name = selector.unwrap_or("first camera").to_string();
        // An address names one camera; a serial may not (two simulated cameras, two suites), so
        // an address goes to aravis as it is.
        let id = selector.map(|s| match s.parse::<Ipv4Addr>() {
            Ok(_) => s.to_string(),
            Err(_) => list_devices().into_iter().find(|d| d.selected_by(s)).map_or_else(|| s.to_string(), |d| d.id),
        });
        let camera = aravis::Camera::new(id.as_deref()).map_err(|e| {
            let message = e.to_string();
            if message.contains("LIBUSB_ERROR_BUSY") {
                let serial = id.as_deref().and_then(|id| id.rsplit('-').next()).unwrap_or_default();
                return Error::camera(&name, usb_claimed_elsewhere(serial));
            }
            Error::camera(&name, format!("cannot open ({message}); cameras found: {}", describe(&list_devices())))
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
        let control = camera.control();
        camera.read_geometry()?;
        Ok((camera, control))
    }

    /// Give up the camera's control channel (GigE Vision) at once, so that another application
    /// can take the camera while this one only reads it (`rmvp cameras`); over USB3 Vision the
    /// camera stays claimed until it is closed.
    pub fn let_go(&self) {
        if let Some(gv) = self.device.downcast_ref::<aravis::GvDevice>() {
            if gv.is_controller() {
                let _ = gv.leave_control();
            }
        }
    }

    /// Who controls the camera. Over USB3 Vision this process, once it is open (a camera
    /// another application holds does not open).
    fn control(&self) -> Control {
        let Some(gv) = self.device.downcast_ref::<aravis::GvDevice>() else { return Control::Ours };
        if gv.is_controller() {
            return Control::Ours;
        }
        let read = |address: u32| self.device.read_register(u64::from(address)).ok().map(|(_, v)| v);
        let ip = read(bootstrap::PRIMARY_APPLICATION_IP).filter(|&ip| ip != 0);
        let port = read(bootstrap::PRIMARY_APPLICATION_PORT).unwrap_or(0) as u16;
        Control::Elsewhere(ip.map(|ip| SocketAddrV4::new(Ipv4Addr::from(ip), port)))
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

    /// Whether a feature works on this camera now: defined, implemented and available. FLIR
    /// defines every node on every model and says through `pIsImplemented` and `pIsAvailable`
    /// whether it works, so a node's existence says nothing.
    pub fn is_available(&self, name: &str) -> bool {
        self.node(name).is_ok_and(|n| n.is_implemented().unwrap_or(false) && n.is_available().unwrap_or(false))
    }

    /// Whether a feature can be written now: available and not locked (`pIsLocked`: many FLIR
    /// features are locked while `TLParamsLocked` is set, during acquisition).
    pub fn is_writable(&self, name: &str) -> bool {
        self.is_available(name) && self.node(name).is_ok_and(|n| !n.is_locked().unwrap_or(true))
    }

    /// Set a feature from text and read it back. aravis checks neither locks nor ranges, so
    /// this refuses a feature that is not available or is locked, and an error names a value
    /// the camera did not keep (floats may be rounded to the camera's step: within 0.5 %).
    pub fn write(&self, name: &str, value: &str) -> Result<String> {
        if !self.is_available(name) {
            return Err(Error::camera(&self.name, format!("cannot set {name} = {value}: not available on it now")));
        }
        if !self.is_writable(name) {
            return Err(Error::camera(&self.name, format!("cannot set {name} = {value}: it is locked")));
        }
        self.set_feature(name, value)?;
        let kept = self.feature(name)?;
        if !same_value(value, &kept) {
            return Err(Error::camera(&self.name, format!("set {name} = {value}, but it reads back {kept}")));
        }
        Ok(kept)
    }

    /// [`CameraDevice::write`] for a float feature; returns the value the camera kept.
    pub fn write_float(&self, name: &str, value: f64) -> Result<f64> {
        let kept = self.write(name, &value.to_string())?;
        kept.parse().map_err(|_| Error::camera(&self.name, format!("{name} reads back {kept:?}, not a number")))
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

    /// Put the camera in a known state and apply `settings`, reading back every value written:
    /// a camera without polarizers is refused ([`polarizers::polarizer_evidence`]); pixel
    /// format (negotiated) and an ADC depth to match, gamma off, readout unmirrored and
    /// offsets that keep the mosaic's phase ([`CameraDevice::keep_the_mosaic`]), auto exposure
    /// and gain off, exposure, gain, then the frame rate (its maximum depends on the exposure)
    /// and the trigger. Returns the pixel format chosen.
    pub fn configure(&mut self, settings: &CameraOptions) -> Result<PixelFormat> {
        let offered = self.offered_pixel_formats()?;
        polarizers::polarizer_evidence(&self.identity().model, &offered, settings.polarized_sensor)
            .map_err(|message| Error::camera(&self.name, message))?;
        let format = choose_pixel_format(&offered, settings.pixel_format.as_deref())?;
        // The buffer pool is sized for the payload: a new format needs a new pool.
        self.stream = None;
        self.write("PixelFormat", &format.name())?;
        if self.is_writable("AdcBitDepth") {
            // The IMX250's ADC gives at most 12 bits; 16-bit formats carry 12.
            self.write("AdcBitDepth", &format!("Bit{}", format.bits.min(12)))?;
        }
        self.keep_the_mosaic(format)?;
        for auto in ["ExposureAuto", "GainAuto"] {
            if self.is_available(auto) {
                self.write(auto, "Off")?;
            }
        }
        // A frame rate left enabled by another program would bound the exposure.
        if self.is_available("AcquisitionFrameRateEnable") {
            self.write("AcquisitionFrameRateEnable", "false")?;
        }
        self.set_exposure(settings.exposure_us)?;
        self.write_float("Gain", settings.gain_db)?;
        if let Some(rate) = settings.frame_rate {
            if self.is_available("AcquisitionFrameRateEnable") {
                self.write("AcquisitionFrameRateEnable", "true")?;
            }
            if let Ok((_, max)) = self.camera.float_bounds("AcquisitionFrameRate") {
                if rate > max {
                    return Err(Error::camera(
                        &self.name,
                        format!(
                            "cannot run at {rate} frames/s: at an exposure of {} us it runs at most {max:.3}",
                            settings.exposure_us
                        ),
                    ));
                }
            }
            self.write_float("AcquisitionFrameRate", rate)?;
        }
        self.write("AcquisitionMode", "Continuous")?;
        if self.is_available("TriggerSelector") {
            self.write("TriggerSelector", "FrameStart")?;
        }
        // FLIR cameras only accept a trigger source while the trigger is off.
        self.write("TriggerMode", "Off")?;
        if settings.trigger == TriggerSource::Line0 {
            self.write("TriggerSource", "Line0")?;
            self.write("TriggerMode", "On")?;
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

    /// Keep the sensor's mosaic where rmvp reads it: gamma off (the samples stay linear),
    /// readout not mirrored (`ReverseX`/`ReverseY` move which polarizer sits at the first
    /// pixel), and `OffsetX`/`OffsetY` whole mosaic tiles (2 pixels for the mono sensor, 4 for
    /// the colour one). A camera that cannot be put so is refused, naming the feature.
    pub fn keep_the_mosaic(&self, format: PixelFormat) -> Result<()> {
        let refuse = |feature: &str, why: String| {
            Error::camera(&self.name, format!("{feature}: {why}; rmvp cannot read its polarizer mosaic so"))
        };
        for (feature, linear) in [("GammaEnable", "false"), ("ReverseX", "false"), ("ReverseY", "false")] {
            if !self.is_available(feature) || same_value(linear, &self.feature(feature)?) {
                continue;
            }
            self.write(feature, linear).map_err(|e| {
                refuse(
                    feature,
                    format!("left {}, and it cannot be set {linear} ({e})", self.feature(feature).unwrap_or_default()),
                )
            })?;
        }
        let tile = if format.family.layout() == SensorLayout::MonoPolarized { 2 } else { 4 };
        for feature in ["OffsetX", "OffsetY"] {
            if !self.is_available(feature) {
                continue;
            }
            let offset = self.integer(feature)?;
            if offset % tile == 0 {
                continue;
            }
            self.write(feature, &(offset - offset % tile).to_string()).map_err(|e| {
                refuse(feature, format!("{offset} is not a multiple of the {tile}-pixel mosaic tile ({e})"))
            })?;
        }
        Ok(())
    }

    /// Set `ExposureTime` (microseconds), e.g. between HDR brackets, and read it back.
    pub fn set_exposure(&self, exposure_us: f64) -> Result<()> {
        self.write_float("ExposureTime", exposure_us).map(|_| ())
    }

    /// Pixel format, width and height of the frames.
    pub fn frame_format(&self) -> (PixelFormat, usize, usize) {
        (self.format, self.width, self.height)
    }

    /// Create the stream (if needed), queue the buffer pool and start acquiring.
    pub fn start(&mut self) -> Result<()> {
        if self.stream.is_none() {
            if self.camera.is_uv_device() {
                // aravis streams USB3 synchronously by default; asynchronous bulk transfers
                // keep up with the sensor's full rate.
                self.camera.uv_set_usb_mode(aravis::UvUsbMode::Async);
            }
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
            let frame = self.format.frame_bytes(self.width, self.height);
            if (payload as usize) < frame {
                return Err(Error::camera(
                    &self.name,
                    format!(
                        "PayloadSize is {payload} bytes, less than a {}x{} {} frame ({frame})",
                        self.width,
                        self.height,
                        self.format.name()
                    ),
                ));
            }
            for _ in 0..STREAM_BUFFERS {
                stream.push_buffer(aravis::Buffer::new_allocate(payload as usize));
            }
            self.stream = Some(stream);
        }
        // The host locks the transport-layer parameters while it streams (SFNC): FLIR cameras
        // then lock the features that would change the payload.
        if self.is_available("TLParamsLocked") {
            self.set_integer("TLParamsLocked", 1)?;
        }
        self.execute("AcquisitionStart")
    }

    /// Stop acquiring and return frames still queued to the pool.
    pub fn stop(&mut self) -> Result<()> {
        let result = self.execute("AcquisitionStop");
        if self.is_available("TLParamsLocked") {
            self.set_integer("TLParamsLocked", 0)?;
        }
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
            let (data, received) = buffer.data();
            let expected = self.format.frame_bytes(self.width, self.height);
            // SAFETY: aravis owns `received` readable bytes at `data` until we push the buffer
            // back below. A short frame is returned short (the caller counts it as dropped).
            Grab::Frame(unsafe { std::slice::from_raw_parts(data, received.min(expected)) }.to_vec())
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

/// Whether a value read back is the value written: the same text, the same boolean, or numbers
/// within 0.5 % (a camera rounds floats to its own step, e.g. exposure to its line time).
fn same_value(written: &str, read: &str) -> bool {
    let boolean = |v: &str| match v.to_ascii_lowercase().as_str() {
        "true" | "1" => Some(true),
        "false" | "0" => Some(false),
        _ => None,
    };
    if written == read || boolean(written).is_some_and(|w| boolean(read) == Some(w)) {
        return true;
    }
    match (written.parse::<f64>(), read.parse::<f64>()) {
        (Ok(w), Ok(r)) => (w - r).abs() <= 0.005 * w.abs().max(r.abs()) || (w - r).abs() < 1e-9,
        _ => false,
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
    fn read_back_values_compare_as_the_camera_writes_them() {
        assert!(same_value("Off", "Off") && !same_value("Off", "Continuous"));
        assert!(same_value("false", "0") && same_value("true", "1") && !same_value("true", "false"));
        assert!(same_value("20000", "20003.2"), "rounded to the line time");
        assert!(!same_value("20000", "19000") && !same_value("30", "25"), "clamped");
    }

    #[test]
    fn a_usb3_camera_opens_by_the_decimal_serial_on_its_label() {
        let usb = |id: &str| DeviceInfo {
            id: id.into(),
            vendor: "FLIR".into(),
            model: "Blackfly S BFS-U3-51S5PC".into(),
            protocol: "USB3Vision".into(),
            address: "1-2".into(),
        };
        // Label 19130117 = 0x0123E705.
        let flir = usb("FLIR-Blackfly S BFS-U3-51S5PC-0123E705");
        for selector in ["19130117", "0123E705", "1-2", "FLIR-Blackfly S BFS-U3-51S5PC-0123E705"] {
            assert!(flir.selected_by(selector), "{selector}");
        }
        assert!(!flir.selected_by("19130118") && !flir.selected_by("0123E706"));
        assert!(usb("FLIR-BFS-0123e705").selected_by("19130117"), "lower-case hex");
        let gige =
            DeviceInfo { protocol: "GigEVision".into(), address: "127.0.0.1".into(), ..usb("rmvp-Sim-19130117") };
        assert!(gige.selected_by("19130117") && !DeviceInfo { id: "rmvp-Sim-123".into(), ..gige }.selected_by("291"));
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
