//! How the object and camera get to each view before it is captured: the operator (press
//! Enter), a timer, a hardware trigger on `Line0`, or the simulated rig's motorised turntable.

use crate::camera::CameraDevice;
use crate::camera::TriggerSource;
use crate::{Error, Result};
use rmvp_dataset::session::PositioningMode;
use std::io::BufRead;
use std::time::{Duration, Instant};

/// How views are positioned and started.
#[derive(Clone, Debug, PartialEq)]
pub enum Positioning {
    /// The operator moves the camera and presses Enter.
    Interactive,
    /// The operator moves the camera during a fixed pause.
    Timed(Duration),
    /// Each view starts with a pulse on the camera's `Line0` input.
    HardwareTrigger,
    /// The rig's turntable (`TurntablePosition`) turns to each view.
    Turntable,
}

/// What the operator sees of the view just captured.
#[derive(Clone, Debug, Default)]
pub struct LastView {
    /// Views complete so far.
    pub done: usize,
    /// Fraction of pixels with a saturated angle.
    pub saturated_fraction: f64,
    /// Mean DoP over bright pixels.
    pub mean_dop: f64,
}

impl Positioning {
    /// The pause of timed mode unless told otherwise.
    pub const TIMED_INTERVAL: Duration = Duration::from_secs(3);

    /// The positioning of `mode`; `interval` is the pause of timed mode.
    pub fn new(mode: PositioningMode, interval: Duration) -> Self {
        match mode {
            PositioningMode::Interactive => Positioning::Interactive,
            PositioningMode::Timed => Positioning::Timed(interval),
            PositioningMode::Trigger => Positioning::HardwareTrigger,
            PositioningMode::Turntable => Positioning::Turntable,
        }
    }

    /// How the camera's frames start under this positioning: the `Line0` input for a hardware
    /// trigger, free running otherwise.
    pub fn trigger(&self) -> TriggerSource {
        match self {
            Positioning::HardwareTrigger => TriggerSource::Line0,
            _ => TriggerSource::FreeRun,
        }
    }

    /// The mode stored in the manifest.
    pub fn mode(&self) -> PositioningMode {
        match self {
            Positioning::Interactive => PositioningMode::Interactive,
            Positioning::Timed(_) => PositioningMode::Timed,
            Positioning::HardwareTrigger => PositioningMode::Trigger,
            Positioning::Turntable => PositioningMode::Turntable,
        }
    }

    /// The turntable where the camera has one, else the operator.
    pub fn default_for(camera: &CameraDevice) -> Self {
        if camera.is_available("TurntablePosition") {
            Positioning::Turntable
        } else {
            Positioning::Interactive
        }
    }

    /// Bring the rig to view `index` of `total`.
    pub fn prepare(&self, camera: &CameraDevice, index: usize, total: usize, last: &LastView) -> Result<()> {
        match self {
            Positioning::Interactive => prompt(&format!(
                "{}view {}/{total}: place the camera and press Enter",
                status_line(last, index),
                index + 1
            )),
            Positioning::Timed(pause) => {
                if index > 0 {
                    eprintln!(
                        "{}moving to view {}/{total} for {:.1} s",
                        status_line(last, index),
                        index + 1,
                        pause.as_secs_f64()
                    );
                    std::thread::sleep(*pause);
                }
                Ok(())
            }
            Positioning::HardwareTrigger => {
                eprintln!("{}view {}/{total}: waiting for a trigger on Line0", status_line(last, index), index + 1);
                Ok(())
            }
            Positioning::Turntable => turn_to(camera, index),
        }
    }

    /// Cover (or uncover) the lens for dark frames.
    pub fn cap_lens(&self, camera: &CameraDevice, covered: bool) -> Result<()> {
        if camera.is_available("LensCap") {
            return camera.write("LensCap", if covered { "true" } else { "false" }).map(|_| ());
        }
        prompt(if covered {
            "dark frames: cover the lens and press Enter"
        } else {
            "dark frames done: uncover the lens and press Enter"
        })
    }
}

fn status_line(last: &LastView, index: usize) -> String {
    if index == 0 || last.done == 0 {
        return String::new();
    }
    format!(
        "{} views done; last: {:.2} % saturated, mean DoP {:.3}. ",
        last.done,
        100.0 * last.saturated_fraction,
        last.mean_dop
    )
}

fn prompt(message: &str) -> Result<()> {
    eprintln!("{message}");
    let mut line = String::new();
    match std::io::stdin().lock().read_line(&mut line) {
        Ok(0) => Err(Error::OperatorGone),
        Ok(_) => Ok(()),
        Err(e) => Err(Error::Unsupported(format!("reading the operator's Enter: {e}"))),
    }
}

/// Turn the turntable to `index` and wait until frames show it.
fn turn_to(camera: &CameraDevice, index: usize) -> Result<()> {
    let positions = camera.integer("TurntablePositions")? as usize;
    if index >= positions {
        return Err(Error::camera(
            camera.name(),
            format!("the turntable has {positions} positions, view {index} asked"),
        ));
    }
    camera.set_integer("TurntablePosition", index as i64)?;
    let start = Instant::now();
    while camera.integer("TurntablePositionReached")? as usize != index {
        if start.elapsed() > Duration::from_secs(120) {
            return Err(Error::camera(camera.name(), format!("the turntable did not reach position {index} in 120 s")));
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    Ok(())
}
