//! Who publishes a release and under what terms: the creators, licence, title, version and
//! related works that the release's Croissant, DataCite and Zenodo metadata and its dataset
//! card carry. They come from `rmvp dataset publish`'s options or a `release.toml`:
//!
//! ```toml
//! title = "RMVP3D: polarized multi-view images of reflective objects"
//! version = "1.0.0"
//! license = "CC-BY-4.0"            # an SPDX identifier
//! description = "Objects of metal and glazed ceramic, ..."
//! publisher = "Example University"  # default: the first creator's affiliation
//! url = "https://example.org/rmvp3d"
//! keywords = ["polarization", "reflective objects"]
//!
//! [[creators]]
//! name = "Doe, Jane"                # "Family, Given", as DataCite writes names
//! affiliation = "Example University"
//! orcid = "0000-0002-1825-0097"
//!
//! [[related]]
//! identifier = "https://github.com/PRIS-CV/NeRSP"
//! scheme = "URL"                    # DOI, URL, arXiv, ...
//! relation = "References"           # a DataCite relation type
//! ```

use crate::{Error, Result};
use serde::{Deserialize, Serialize};
use std::path::Path;

/// A release's metadata as given: each field may be missing until [`ReleaseInfo::resolve`].
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ReleaseInfo {
    /// Title.
    pub title: Option<String>,
    /// Version of the data (not of rmvp).
    pub version: Option<String>,
    /// SPDX licence identifier of the data.
    pub license: Option<String>,
    /// A paragraph on what the data is.
    pub description: Option<String>,
    /// Who publishes it.
    pub publisher: Option<String>,
    /// Where it lives.
    pub url: Option<String>,
    /// Keywords.
    #[serde(default)]
    pub keywords: Vec<String>,
    /// The people who made it, in order.
    #[serde(default)]
    pub creators: Vec<Creator>,
    /// Works it belongs to (a paper, code, an earlier version).
    #[serde(default)]
    pub related: Vec<RelatedWork>,
}

/// One creator.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Creator {
    /// `Family, Given` (or an organisation's name, without a comma).
    pub name: String,
    /// Affiliation.
    pub affiliation: Option<String>,
    /// ORCID iD, `0000-0000-0000-0000`.
    pub orcid: Option<String>,
}

/// A related work, as DataCite relates identifiers.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RelatedWork {
    /// The identifier (a DOI without `https://doi.org/`, a URL, an arXiv id).
    pub identifier: String,
    /// Its scheme: `DOI`, `URL`, `arXiv`, ...
    pub scheme: String,
    /// DataCite relation type: `IsSupplementTo`, `References`, `IsDerivedFrom`, ...
    pub relation: String,
}

/// A release's metadata, complete.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ReleaseMetadata {
    /// Title.
    pub title: String,
    /// Version of the data.
    pub version: String,
    /// SPDX licence identifier.
    pub license: String,
    /// What the data is.
    pub description: String,
    /// Who publishes it.
    pub publisher: String,
    /// Where it lives, if said.
    pub url: Option<String>,
    /// Keywords (rmvp's own first).
    pub keywords: Vec<String>,
    /// Creators, at least one.
    pub creators: Vec<Creator>,
    /// Related works.
    pub related: Vec<RelatedWork>,
    /// Publication date, `YYYY-MM-DD` (UTC).
    pub date: String,
}

/// The title when none is given.
pub const DEFAULT_TITLE: &str = "Polarized multi-view dataset of reflective objects";
/// The version when none is given.
pub const DEFAULT_VERSION: &str = "1.0.0";
/// Keywords every release carries.
const KEYWORDS: [&str; 4] = ["polarization", "multi-view", "3D reconstruction", "reflective objects"];

/// The official NeRSP paper's citation (its repository's BibTeX, with the names in BibTeX's
/// `Family, Given` order and the booktitle spelled out).
pub const NERSP_CITATION: &str = "@inproceedings{nersp2024yufei,\n  title = {NeRSP: Neural 3D Reconstruction for \
Reflective Objects with Sparse Polarized Images},\n  author = {Han, Yufei and Guo, Heng and Fukai, Koki and Santo, \
Hiroaki and Shi, Boxin and Okura, Fumio and Ma, Zhanyu and Jia, Yunpeng},\n  booktitle = {Proceedings of the IEEE/CVF \
Conference on Computer Vision and Pattern Recognition (CVPR)},\n  year = {2024}\n}";

impl ReleaseInfo {
    /// Read a `release.toml`.
    pub fn read(path: &Path) -> Result<Self> {
        let text = rmvp_dataset::io::input::read_text(path)?;
        toml::from_str(&text).map_err(|e| rmvp_dataset::Error::format(path, e.message().to_string()).into())
    }

    /// `self` with every field `over` gives replacing its own (creators and related works as
    /// lists).
    pub fn overridden_by(self, over: ReleaseInfo) -> Self {
        Self {
            title: over.title.or(self.title),
            version: over.version.or(self.version),
            license: over.license.or(self.license),
            description: over.description.or(self.description),
            publisher: over.publisher.or(self.publisher),
            url: over.url.or(self.url),
            keywords: list(over.keywords, self.keywords),
            creators: list(over.creators, self.creators),
            related: list(over.related, self.related),
        }
    }

    /// The complete metadata, published today; refused, saying what to give, when the licence
    /// or the creators are missing or malformed.
    pub fn resolve(self) -> Result<ReleaseMetadata> {
        let missing = |what: &str, how: &str| Error::ReleaseInfo { why: format!("{what} missing: {how}") };
        let license = self.license.filter(|l| !l.trim().is_empty()).ok_or_else(|| {
            missing(
                "the licence of the data is",
                "give --license SPDX-ID (e.g. CC-BY-4.0) or `license = \"CC-BY-4.0\"` in the --info file",
            )
        })?;
        if !license.chars().all(|c| c.is_ascii_alphanumeric() || "-.+".contains(c)) {
            return Err(Error::ReleaseInfo {
                why: format!("licence {license:?} is not an SPDX identifier (e.g. CC-BY-4.0, CC0-1.0, MIT)"),
            });
        }
        if self.creators.is_empty() {
            return Err(missing(
                "the creators are",
                "give --creator \"Family, Given[; affiliation[; ORCID]]\" for each, or [[creators]] in the --info file",
            ));
        }
        for creator in &self.creators {
            if creator.name.trim().is_empty() {
                return Err(Error::ReleaseInfo { why: "a creator without a name".into() });
            }
            if let Some(orcid) = &creator.orcid {
                if !is_orcid(orcid) {
                    return Err(Error::ReleaseInfo {
                        why: format!(
                            "creator {}: ORCID {orcid:?} is not of the form 0000-0002-1825-0097",
                            creator.name
                        ),
                    });
                }
            }
        }
        let publisher = match self.publisher.or_else(|| self.creators[0].affiliation.clone()) {
            Some(publisher) => publisher,
            None => {
                return Err(missing("the publisher is", "give --publisher, or an affiliation to the first creator"))
            }
        };
        let mut keywords: Vec<String> = KEYWORDS.iter().map(|k| k.to_string()).collect();
        keywords.extend(self.keywords.into_iter().filter(|k| !KEYWORDS.contains(&k.as_str())));
        Ok(ReleaseMetadata {
            title: self.title.unwrap_or_else(|| DEFAULT_TITLE.into()),
            version: self.version.unwrap_or_else(|| DEFAULT_VERSION.into()),
            license,
            description: self.description.unwrap_or_else(|| {
                "Polarized multi-view images of reflective objects (Stokes vectors, angle and degree of \
                 polarization, masks), calibrated cameras and, where scanned, ground-truth meshes, normals and \
                 depth, in the official NeRSP loader's layout and rmvp's."
                    .into()
            }),
            publisher,
            url: self.url,
            keywords,
            creators: self.creators,
            related: self.related,
            date: rmvp_dataset::session::utc_now()[..10].to_string(),
        })
    }
}

/// `over` unless it is empty, else `base`.
fn list<T>(over: Vec<T>, base: Vec<T>) -> Vec<T> {
    if over.is_empty() {
        base
    } else {
        over
    }
}

impl std::str::FromStr for Creator {
    type Err = String;

    /// `Family, Given[; affiliation[; ORCID]]`.
    fn from_str(text: &str) -> std::result::Result<Self, String> {
        let mut parts = text.split(';').map(str::trim);
        let name = parts.next().filter(|n| !n.is_empty()).ok_or("a creator needs a name: \"Family, Given\"")?;
        let affiliation = parts.next().filter(|a| !a.is_empty()).map(String::from);
        let orcid = parts.next().filter(|o| !o.is_empty()).map(String::from);
        if parts.next().is_some() {
            return Err(format!("{text:?}: expected \"Family, Given[; affiliation[; ORCID]]\""));
        }
        Ok(Self { name: name.into(), affiliation, orcid })
    }
}

impl Creator {
    /// Family and given names of a person's `Family, Given`; `None` for an organisation.
    pub fn family_and_given(&self) -> Option<(&str, &str)> {
        self.name.split_once(',').map(|(family, given)| (family.trim(), given.trim()))
    }
}

/// Whether `id` is an ORCID iD (four groups of four digits, the last character a digit or
/// `X`, its ISO 7064 11-2 check digit right).
fn is_orcid(id: &str) -> bool {
    let digits: Vec<char> = id.chars().filter(|&c| c != '-').collect();
    let grouped = id.len() == 19 && id.char_indices().all(|(i, c)| if i % 5 == 4 { c == '-' } else { c != '-' });
    if !grouped || digits.len() != 16 || !digits[..15].iter().all(char::is_ascii_digit) {
        return false;
    }
    let total = digits[..15].iter().fold(0u32, |total, d| (total + d.to_digit(10).unwrap_or(0)) * 2);
    let check = (12 - total % 11) % 11;
    digits[15] == if check == 10 { 'X' } else { char::from_digit(check, 10).unwrap_or('?') }
}

/// The licence's page at SPDX.
pub fn license_url(license: &str) -> String {
    format!("https://spdx.org/licenses/{license}.html")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn orcid_check_digits_are_checked() {
        // ORCID's own examples.
        assert!(is_orcid("0000-0002-1825-0097") && is_orcid("0000-0001-5109-3700") && is_orcid("0000-0002-1694-233X"));
        assert!(!is_orcid("0000-0002-1825-0098") && !is_orcid("0000000218250097") && !is_orcid("0000-0002-1825-009"));
    }

    #[test]
    fn a_release_without_licence_or_creators_is_refused_saying_what_to_give() {
        let err = ReleaseInfo::default().resolve().unwrap_err().to_string();
        assert!(err.contains("licence") && err.contains("--license"), "{err}");
        let licensed = ReleaseInfo { license: Some("CC-BY-4.0".into()), ..ReleaseInfo::default() };
        let err = licensed.clone().resolve().unwrap_err().to_string();
        assert!(err.contains("creators") && err.contains("--creator"), "{err}");
        let creator: Creator = "Doe, Jane; Example University; 0000-0002-1825-0097".parse().unwrap();
        assert_eq!(creator.family_and_given(), Some(("Doe", "Jane")));
        let metadata = ReleaseInfo { creators: vec![creator], ..licensed }.resolve().unwrap();
        assert_eq!((metadata.publisher.as_str(), metadata.version.as_str()), ("Example University", DEFAULT_VERSION));
        assert!("; nobody".parse::<Creator>().is_err());
    }

    #[test]
    fn a_release_toml_is_read_and_options_override_it() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("release.toml");
        std::fs::write(
            &path,
            "title = \"T\"\nlicense = \"CC0-1.0\"\n[[creators]]\nname = \"Doe, Jane\"\n[[related]]\nidentifier = \
             \"https://github.com/PRIS-CV/NeRSP\"\nscheme = \"URL\"\nrelation = \"References\"\n",
        )
        .unwrap();
        let info = ReleaseInfo::read(&path).unwrap();
        assert_eq!((info.title.as_deref(), info.creators.len(), info.related.len()), (Some("T"), 1, 1));
        let over = ReleaseInfo { license: Some("CC-BY-4.0".into()), ..ReleaseInfo::default() };
        let merged = info.overridden_by(over);
        assert_eq!((merged.license.as_deref(), merged.title.as_deref()), (Some("CC-BY-4.0"), Some("T")));
        std::fs::write(&path, "licence = \"CC0-1.0\"\n").unwrap();
        let err = ReleaseInfo::read(&path).unwrap_err().to_string();
        assert!(err.contains("release.toml") && err.contains("licence"), "{err}");
    }
}
