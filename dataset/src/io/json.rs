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

/// The fields where two records differ, each as `name: was -> now` (nested fields by their
/// path, `reference.mesh_res`; a field one side lacks is `null` there), in `was`'s order.
pub fn differences<T: Serialize>(was: &T, now: &T) -> Vec<(String, String)> {
    fn walk(path: &str, was: &serde_json::Value, now: &serde_json::Value, out: &mut Vec<(String, String)>) {
        use serde_json::Value;
        match (was, now) {
            (Value::Object(a), Value::Object(b)) => {
                for key in a.keys().chain(b.keys().filter(|k| !a.contains_key(*k))) {
                    let name = if path.is_empty() { key.clone() } else { format!("{path}.{key}") };
                    walk(&name, a.get(key).unwrap_or(&Value::Null), b.get(key).unwrap_or(&Value::Null), out);
                }
            }
            (a, b) if a != b => out.push((path.to_string(), format!("{path}: {a} -> {b}"))),
            _ => {}
        }
    }
    let json = |v: &T| serde_json::to_value(v).expect("records serialise");
    let mut out = Vec::new();
    walk("", &json(was), &json(now), &mut out);
    out
}

/// Write `value` to `path` as pretty JSON, atomically.
pub fn write_json<T: Serialize>(path: &Path, value: &T) -> Result<()> {
    let text = serde_json::to_string_pretty(value).expect("records serialise");
    write_bytes_atomically(path, text.as_bytes())
}
