//! A release's DataCite metadata (`datacite.json`, the attributes of DataCite's REST API, schema
//! 4) and the same as Zenodo reads a deposit's (`.zenodo.json`), from its
//! [`ReleaseMetadata`]: what a repository needs to mint the release's DOI.

use super::metadata::{license_url, ReleaseMetadata};
use serde_json::{json, Value};

/// DataCite's metadata file of a release.
pub const DATACITE: &str = "datacite.json";
/// Zenodo's metadata file of a release.
pub const ZENODO: &str = ".zenodo.json";

/// The release's DataCite attributes; `formats` are its files' MIME types, `bytes` its size.
pub fn datacite(metadata: &ReleaseMetadata, formats: &[&str], bytes: u64) -> Value {
    let creators: Vec<Value> = metadata
        .creators
        .iter()
        .map(|c| {
            let mut creator = match c.family_and_given() {
                Some((family, given)) => {
                    json!({"name": c.name, "nameType": "Personal", "familyName": family, "givenName": given})
                }
                None => json!({"name": c.name, "nameType": "Organizational"}),
            };
            creator["affiliation"] = json!(c.affiliation.iter().map(|a| json!({"name": a})).collect::<Vec<_>>());
            creator["nameIdentifiers"] = json!(c
                .orcid
                .iter()
                .map(|o| json!({
                    "nameIdentifier": format!("https://orcid.org/{o}"),
                    "nameIdentifierScheme": "ORCID",
                    "schemeUri": "https://orcid.org",
                }))
                .collect::<Vec<_>>());
            creator
        })
        .collect();
    json!({
        "types": {"resourceTypeGeneral": "Dataset", "resourceType": "Polarized multi-view images"},
        "creators": creators,
        "titles": [{"title": metadata.title}],
        "publisher": {"name": metadata.publisher},
        "publicationYear": metadata.date[..4].to_string(),
        "dates": [{"date": metadata.date, "dateType": "Issued"}],
        "version": metadata.version,
        "language": "en",
        "subjects": metadata.keywords.iter().map(|k| json!({"subject": k})).collect::<Vec<_>>(),
        "rightsList": [{
            "rights": metadata.license,
            "rightsUri": license_url(&metadata.license),
            "rightsIdentifier": metadata.license.to_lowercase(),
            "rightsIdentifierScheme": "SPDX",
            "schemeUri": "https://spdx.org/licenses/",
        }],
        "descriptions": [{"description": metadata.description, "descriptionType": "Abstract"}],
        "relatedIdentifiers": metadata.related.iter().map(|r| json!({
            "relatedIdentifier": r.identifier,
            "relatedIdentifierType": r.scheme,
            "relationType": r.relation,
        })).collect::<Vec<_>>(),
        "formats": formats,
        "sizes": [format!("{bytes} bytes")],
        "url": metadata.url,
        "schemaVersion": "http://datacite.org/schema/kernel-4",
    })
}

/// Zenodo's relation names are DataCite's with a lower-case first letter.
fn zenodo_relation(relation: &str) -> String {
    let mut chars = relation.chars();
    chars.next().map(|c| c.to_lowercase().chain(chars).collect()).unwrap_or_default()
}

/// The release's Zenodo deposit metadata.
pub fn zenodo(metadata: &ReleaseMetadata) -> Value {
    let creators: Vec<Value> = metadata
        .creators
        .iter()
        .map(|c| {
            let mut creator = json!({"name": c.name});
            if let Some(affiliation) = &c.affiliation {
                creator["affiliation"] = json!(affiliation);
            }
            if let Some(orcid) = &c.orcid {
                creator["orcid"] = json!(orcid);
            }
            creator
        })
        .collect();
    json!({
        "upload_type": "dataset",
        "title": metadata.title,
        "creators": creators,
        "description": metadata.description,
        "license": metadata.license.to_lowercase(),
        "version": metadata.version,
        "publication_date": metadata.date,
        "keywords": metadata.keywords,
        "access_right": "open",
        "related_identifiers": metadata.related.iter().map(|r| json!({
            "identifier": r.identifier,
            "relation": zenodo_relation(&r.relation),
            "scheme": r.scheme.to_lowercase(),
        })).collect::<Vec<_>>(),
    })
}
