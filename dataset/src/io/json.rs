//! JSON records (manifests, reports, alignments): read with errors that name the file and say
//! what it should have been, written pretty and atomically.

use crate::io::write_bytes_atomically;
use crate::{Error, Result};
use serde::de::DeserializeOwned;
use serde::Serialize;
use std::path::Path;

/// Read `path` as a `T`; an unreadable or malformed file is an error naming it and `what` it
/// should be ("a session manifest").
pub fn read_json<T: DeserializeOwned>(path: &Path, what: &str) -> Result<T> {
    let text = crate::io::input::read_text(path)?;
    serde_json::from_str(&text).map_err(|e| Error::format(path, format!("not {what}: {e}")))
}

/// Write `value` to `path` as pretty JSON, atomically.
pub fn write_json<T: Serialize>(path: &Path, value: &T) -> Result<()> {
    let text = serde_json::to_string_pretty(value).expect("records serialise");
    write_bytes_atomically(path, text.as_bytes())
}
