//! Whether a camera's sensor has polarizers: a fact rmvp checks before it captures Stokes.
//!
//! A colour Blackfly S without polarizers streams `BayerRG*` frames whose 2x2 cells are
//! colours, not polarizer angles; read as a polarization mosaic they give Stokes, AoP and DoP
//! of light no polarizer saw. FLIR's descriptions define the `Polarized*` entries on every
//! model (implemented or not), so only the formats a camera offers now count, then its model.

use crate::raw::PixelFormat;

/// FLIR's cameras with Sony's on-sensor polarizers, by part number without the `-C` suffix
/// (how `DeviceModelName` carries it: `Blackfly S BFS-U3-51S5PC`), with their sensor. Source:
/// Teledyne FLIR, "Imaging reflective surfaces: Sony's first polarized sensor"
/// (teledynevisionsolutions.com, learning center), its list of supported camera models.
pub const FLIR_POLARIZED_MODELS: [(&str, &str); 5] = [
    ("BFS-U3-51S5P", "Sony IMX250MZR, polarized mono"),
    ("BFS-U3-51S5PC", "Sony IMX250MYR, polarized colour"),
    ("BFS-PGE-51S5P", "Sony IMX250MZR, polarized mono"),
    ("BFS-PGE-51S5PC", "Sony IMX250MYR, polarized colour"),
    ("BFS-PGE-123S6P", "Sony IMX253MZR, polarized mono"),
];

/// Why rmvp takes a camera's sensor for a polarized one.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum PolarizerEvidence {
    /// It offers a format that names polarizers (`BayerRGPolarized*`, `Polarized*`).
    Format(String),
    /// Its model is one of [`FLIR_POLARIZED_MODELS`].
    Model(&'static str),
    /// The user said so (`--polarized-sensor`).
    Declared,
}

impl std::fmt::Display for PolarizerEvidence {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            PolarizerEvidence::Format(name) => write!(f, "it offers {name}"),
            PolarizerEvidence::Model(part) => write!(f, "{part} is one of FLIR's polarized models"),
            PolarizerEvidence::Declared => write!(f, "declared with --polarized-sensor"),
        }
    }
}

/// The FLIR polarized model `model` (a `DeviceModelName`) is, if any: one of its words, with
/// `_` read as `-` and a trailing `-C` dropped, is a part number of [`FLIR_POLARIZED_MODELS`].
pub fn polarized_model(model: &str) -> Option<&'static str> {
    model.split_whitespace().find_map(|word| {
        let word = word.to_ascii_uppercase().replace('_', "-");
        let part = word.strip_suffix("-C").unwrap_or(&word);
        FLIR_POLARIZED_MODELS.iter().map(|(p, _)| *p).find(|p| *p == part)
    })
}

/// Why the camera `model`, offering `offered`, has polarizers; `declared`: the user says it
/// has. The error says why not and what to do.
pub fn polarizer_evidence(model: &str, offered: &[String], declared: bool) -> Result<PolarizerEvidence, String> {
    let naming = offered.iter().find(|name| name.parse::<PixelFormat>().is_ok_and(|f| f.family.names_polarizers()));
    if let Some(name) = naming {
        return Ok(PolarizerEvidence::Format(name.clone()));
    }
    if let Some(part) = polarized_model(model) {
        return Ok(PolarizerEvidence::Model(part));
    }
    if declared {
        return Ok(PolarizerEvidence::Declared);
    }
    Err(format!(
        "has no polarizers that rmvp can see: it offers no polarized pixel format (it offers {}) and {model:?} \
         is not one of FLIR's polarized models ({}); its 2x2 cells are colour filters, and Stokes, AoP and DoP \
         from them would be of light no polarizer saw. Open the polarization camera (--camera SERIAL or \
         ADDRESS; `rmvp cameras` lists them), or pass --polarized-sensor if this camera's sensor does have \
         on-chip polarizers",
        if offered.is_empty() { "none".to_string() } else { offered.join(", ") },
        FLIR_POLARIZED_MODELS.iter().map(|(p, _)| format!("{p}-C")).collect::<Vec<_>>().join(", ")
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn names(list: &[&str]) -> Vec<String> {
        list.iter().map(|s| s.to_string()).collect()
    }

    #[test]
    fn models_are_read_as_flir_writes_them() {
        assert_eq!(polarized_model("Blackfly S BFS-U3-51S5PC"), Some("BFS-U3-51S5PC"));
        assert_eq!(polarized_model("Blackfly S BFS-U3-51S5P"), Some("BFS-U3-51S5P"));
        assert_eq!(polarized_model("Simulated BFS-U3-51S5PC-C"), Some("BFS-U3-51S5PC"));
        assert_eq!(polarized_model("bfs_pge_123s6p"), Some("BFS-PGE-123S6P"));
        // The same sensor family without polarizers, and a colour GigE Blackfly S.
        for model in ["Blackfly S BFS-U3-51S5C", "Blackfly S BFS-U3-51S5M", "BFS_PGE_23S6", "Blackfly S BFS-PGE-50S4C"]
        {
            assert_eq!(polarized_model(model), None, "{model}");
        }
    }

    #[test]
    fn a_plain_bayer_camera_is_refused_unless_declared() {
        let plain = names(&["BayerRG8", "BayerRG12p"]);
        let err = polarizer_evidence("Blackfly S BFS-PGE-50S4C", &plain, false).unwrap_err();
        assert!(
            err.contains("BayerRG8, BayerRG12p") && err.contains("BFS-PGE-50S4C") && err.contains("--polarized-sensor")
        );
        assert_eq!(polarizer_evidence("Blackfly S BFS-PGE-50S4C", &plain, true), Ok(PolarizerEvidence::Declared));
        // The polarized models offer the same bytes under Bayer names.
        assert_eq!(
            polarizer_evidence("Blackfly S BFS-U3-51S5PC", &plain, false),
            Ok(PolarizerEvidence::Model("BFS-U3-51S5PC"))
        );
        let polarized = names(&["BayerRG8", "BayerRGPolarized12p"]);
        assert_eq!(
            polarizer_evidence("anything", &polarized, false),
            Ok(PolarizerEvidence::Format("BayerRGPolarized12p".into()))
        );
    }
}
