//! JSON records (manifests, reports, alignments): read with errors that name the file and say
//! what it should have been, written pretty and atomically.
//!
//! What reading a record may cost is bounded by its size: a record has at most
//! [`MAX_JSON_BYTES`]; its typed fields take a few times their text at most, unknown fields are
//! skipped without being kept, and a free-form field (provenance, recorded settings: a JSON tree,
//! which takes up to 16 times its text) is read through [`free_form`], at most
//! [`MAX_FREE_FORM_BYTES`] each. Types read from files therefore use neither
//! `#[serde(flatten)]` nor `#[serde(untagged)]` (which keep the whole value, unknown fields
//! included, as a tree before they choose) except behind [`free_form`].

use crate::io::write_bytes_atomically;
use crate::{Error, Result};
use serde::de::{DeserializeOwned, Error as _};
use serde::{Deserialize, Deserializer, Serialize};
use serde_json::value::RawValue;
use std::path::Path;

/// The largest JSON record read, in bytes (a manifest of a hundred thousand files takes a
/// tenth of it).
pub const MAX_JSON_BYTES: u64 = 64 << 20;
/// The most bytes of JSON text one free-form field may have.
pub const MAX_FREE_FORM_BYTES: usize = 1 << 20;

/// Read the UTF-8 text of a JSON record of at most [`MAX_JSON_BYTES`].
pub fn read_json_text(path: &Path) -> Result<String> {
    crate::io::input::read_text_limited(path, MAX_JSON_BYTES)
}

/// Read `path` as a `T`; an unreadable or malformed file is an error naming it and `what` it
/// should be ("a session manifest").
pub fn read_json<T: DeserializeOwned>(path: &Path, what: &str) -> Result<T> {
    let text = read_json_text(path)?;
    serde_json::from_str(&text).map_err(|e| Error::format(path, format!("not {what}: {e}")))
}

/// Deserialise a free-form field (`#[serde(deserialize_with = "free_form")]`) of at most
/// [`MAX_FREE_FORM_BYTES`] of JSON text, measured before it is parsed into a tree. Only for
/// records read from JSON text.
pub fn free_form<'de, D: Deserializer<'de>, T: DeserializeOwned>(deserializer: D) -> std::result::Result<T, D::Error> {
    parse_free_form(<&RawValue>::deserialize(deserializer)?).map_err(D::Error::custom)
}

/// Parse the text of a free-form field of at most [`MAX_FREE_FORM_BYTES`].
pub fn parse_free_form<T: DeserializeOwned>(raw: &RawValue) -> std::result::Result<T, String> {
    let size = raw.get().len();
    if size > MAX_FREE_FORM_BYTES {
        return Err(format!("a free-form field of {size} bytes, more than the {MAX_FREE_FORM_BYTES} one may have"));
    }
    serde_json::from_str(raw.get()).map_err(|e| e.to_string())
}

/// A JSON object's fields in their order, each value's text unparsed (borrowed from the
/// record's text); a field given twice is refused.
pub struct RawFields<'a>(pub Vec<(String, &'a RawValue)>);

impl<'de: 'a, 'a> Deserialize<'de> for RawFields<'a> {
    fn deserialize<D: Deserializer<'de>>(deserializer: D) -> std::result::Result<Self, D::Error> {
        struct FieldsVisitor<'a>(std::marker::PhantomData<&'a ()>);
        impl<'de: 'a, 'a> serde::de::Visitor<'de> for FieldsVisitor<'a> {
            type Value = RawFields<'a>;

            fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
                f.write_str("a JSON object")
            }

            fn visit_map<A: serde::de::MapAccess<'de>>(
                self,
                mut map: A,
            ) -> std::result::Result<RawFields<'a>, A::Error> {
                let mut fields: Vec<(String, &'a RawValue)> = Vec::new();
                while let Some((key, value)) = map.next_entry::<String, &'a RawValue>()? {
                    if fields.iter().any(|(k, _)| *k == key) {
                        return Err(A::Error::custom(format!("field {key:?} given twice")));
                    }
                    fields.push((key, value));
                }
                Ok(RawFields(fields))
            }
        }
        deserializer.deserialize_map(FieldsVisitor(std::marker::PhantomData))
    }
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
