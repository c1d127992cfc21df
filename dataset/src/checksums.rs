//! `sha256sum`-style listings (`<sha256>  <file>` a line) checked against the files under a
//! folder, as a release's `SHA256SUMS` is: every listed file present with its checksum, no file
//! left unlisted. A listed name is a path inside the folder, nothing else; each fault names its
//! file.

use crate::io::input;
use crate::session::{files_under, sha256_file};
use crate::{Error, Result};
use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;

/// What checking a listing found.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ListingCheck {
    /// The SHA-256 of each listed file that could be read, as read.
    pub hashes: BTreeMap<String, String>,
    /// Files whose checksums matched.
    pub matched: usize,
    /// Every fault, each naming its file (relative to the folder).
    pub faults: Vec<String>,
}

/// Check the listing `root/listing` against the files under `root`. `Err` only when the
/// listing itself cannot be read; everything else is a fault of the result.
pub fn check_listing(root: &Path, listing: &str) -> Result<ListingCheck> {
    let text = input::read_text(&root.join(listing))?;
    let mut check = ListingCheck::default();
    let mut names = BTreeSet::new();
    for (number, line) in text.lines().enumerate() {
        let line_no = number + 1;
        let Some((hash, file)) =
            line.split_once("  ").filter(|(h, _)| h.len() == 64 && h.bytes().all(|b| b.is_ascii_hexdigit()))
        else {
            check.faults.push(format!("{listing} line {line_no}: not `<sha256>  <file>`"));
            continue;
        };
        // A listed name is a path inside the folder, nothing else: it is never opened otherwise.
        let path = match input::inside(root, file) {
            Ok(path) => path,
            Err(why) => {
                check.faults.push(format!("{listing} line {line_no}: {why}"));
                continue;
            }
        };
        names.insert(file.to_string());
        match sha256_file(&path) {
            Ok((actual, _)) => {
                if actual == hash {
                    check.matched += 1;
                } else {
                    check.faults.push(format!("{file}: checksum differs from {listing} (changed or damaged)"));
                }
                check.hashes.insert(file.to_string(), actual);
            }
            Err(Error::Io { source, .. }) if source.kind() == std::io::ErrorKind::NotFound => {
                check.faults.push(format!("{file}: listed in {listing} but missing"))
            }
            Err(e) => check.faults.push(format!("{file}: {}", without_path(&e, &path))),
        }
    }
    for file in files_under(root)? {
        if file != listing && !names.contains(&file) {
            check.faults.push(format!("{file}: not listed in {listing}"));
        }
    }
    Ok(check)
}

/// What an error says of a file, without the file's path (faults name it relative to the
/// folder).
pub fn without_path(e: &Error, path: &Path) -> String {
    let text = e.to_string();
    text.strip_prefix(&format!("{}: ", path.display())).map_or(text.clone(), str::to_string)
}
