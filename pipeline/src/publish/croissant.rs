//! A release's MLCommons Croissant 1.0 metadata (`croissant.json`, JSON-LD), as the NeurIPS
//! Datasets and Benchmarks track asks for: the release's data files with their SHA-256 and
//! encoding formats, the record sets of its tables (views with their cameras and files, split
//! by `split`; objects with their meshes and scans), the licence, the version and the
//! citations (the dataset's and NeRSP's). `tests/cli.rs` validates the demo's with MLCommons'
//! own `mlcroissant` and checks its records against rmvp's reading of the same release.

use super::index::{views_table, Column, OBJECTS_TABLE, OBJECT_COLUMNS, SPLITS, VIEW_COLUMNS};
use super::metadata::{license_url, ReleaseMetadata, NERSP_CITATION};
use serde_json::{json, Value};

/// The metadata file of a release.
pub const CROISSANT: &str = "croissant.json";

/// The record set of views and of objects.
const VIEWS: &str = "views";
const OBJECTS: &str = "objects";
/// The file set of the views' tables (one per split).
const VIEW_TABLES: &str = "view-tables";

/// The MIME type of a release's file, by its extension.
pub fn encoding_format(file: &str) -> &'static str {
    match file.rsplit_once('.').map(|(_, ext)| ext.to_ascii_lowercase()).as_deref() {
        Some("exr") => "image/x-exr",
        Some("png") => "image/png",
        Some("jpg" | "jpeg") => "image/jpeg",
        Some("npy") => "application/x-npy",
        // NumPy's archives are zip files of .npy.
        Some("npz") => "application/zip",
        Some("json") => "application/json",
        Some("jsonl") => "application/jsonl",
        Some("ply") => "application/x-ply",
        Some("obj") => "model/obj",
        Some("csv") => "text/csv",
        Some("md") => "text/markdown",
        Some("html") => "text/html",
        Some("txt") => "text/plain",
        _ => "application/octet-stream",
    }
}

/// The dataset's own citation, BibTeX.
pub fn dataset_citation(metadata: &ReleaseMetadata) -> String {
    let authors: Vec<&str> = metadata.creators.iter().map(|c| c.name.as_str()).collect();
    let key: String = metadata
        .creators
        .first()
        .map(|c| c.family_and_given().map_or(c.name.as_str(), |(family, _)| family))
        .unwrap_or("dataset")
        .chars()
        .filter(char::is_ascii_alphanumeric)
        .collect::<String>()
        .to_lowercase();
    let mut entry = format!(
        "@misc{{{key}{year},\n  title = {{{title}}},\n  author = {{{authors}}},\n  year = {{{year}}},\n  \
         version = {{{version}}},\n  publisher = {{{publisher}}}",
        year = &metadata.date[..4],
        title = metadata.title,
        authors = authors.join(" and "),
        version = metadata.version,
        publisher = metadata.publisher,
    );
    if let Some(url) = &metadata.url {
        entry += &format!(",\n  url = {{{url}}}");
    }
    entry + "\n}"
}

/// A creator as schema.org describes a person or an organisation.
fn creator(c: &super::metadata::Creator) -> Value {
    let mut person = match c.family_and_given() {
        Some((family, given)) => json!({
            "@type": "sc:Person", "name": format!("{given} {family}"), "familyName": family, "givenName": given,
        }),
        None => json!({"@type": "sc:Organization", "name": c.name}),
    };
    if let Some(affiliation) = &c.affiliation {
        person["affiliation"] = json!({"@type": "sc:Organization", "name": affiliation});
    }
    if let Some(orcid) = &c.orcid {
        person["sameAs"] = json!(format!("https://orcid.org/{orcid}"));
    }
    person
}

/// The fields of record set `set`, each a column of `columns` read from `source`.
fn fields(set: &str, columns: &[Column], source: &Value) -> Vec<Value> {
    columns
        .iter()
        .map(|column| {
            let data_type =
                if column.name == "split" { json!(["sc:Text", "wd:Q3985153"]) } else { json!(column.data_type) };
            let mut source = source.clone();
            source["extract"] = json!({"jsonPath": format!("$[*].{}", column.name)});
            json!({
                "@type": "cr:Field",
                "@id": format!("{set}/{}", column.name),
                "name": column.name,
                "description": column.description,
                "dataType": data_type,
                "source": source,
            })
        })
        .collect()
}

/// The Croissant JSON-LD of a release: `metadata`, and `files`, every data file with its
/// SHA-256 (paths relative to the release, `/`-separated), described by `owners` (the object,
/// view and split a file belongs to) where it says.
pub fn croissant(
    metadata: &ReleaseMetadata,
    files: &[(String, String)],
    owners: &std::collections::BTreeMap<String, String>,
) -> Value {
    let mut distribution: Vec<Value> = files
        .iter()
        .map(|(file, sha256)| {
            let mut object = json!({
                "@type": "cr:FileObject",
                "@id": file,
                "name": file,
                "contentUrl": file,
                "encodingFormat": encoding_format(file),
                "sha256": sha256,
            });
            if let Some(owner) = owners.get(file) {
                object["description"] = json!(owner);
            }
            object
        })
        .collect();
    distribution.push(json!({
        "@type": "cr:FileSet",
        "@id": VIEW_TABLES,
        "name": VIEW_TABLES,
        "description": format!(
            "The views' tables, one per split: {}.",
            SPLITS.map(views_table).join(", ")
        ),
        "encodingFormat": "application/json",
        "includes": format!("{}/views-*.json", super::index::INDEX_FOLDER),
    }));
    let views = json!({
        "@type": "cr:RecordSet",
        "@id": VIEWS,
        "name": VIEWS,
        "description": "One record per view: its object, split, camera (OpenCV: x_cam = R x_world + t) and files.",
        "key": [{"@id": format!("{VIEWS}/object")}, {"@id": format!("{VIEWS}/view")}],
        "field": fields(VIEWS, &VIEW_COLUMNS, &json!({"fileSet": {"@id": VIEW_TABLES}})),
    });
    let objects = json!({
        "@type": "cr:RecordSet",
        "@id": OBJECTS,
        "name": OBJECTS,
        "description": "One record per object: its views, ground-truth mesh (the aligned laser scan) and scan.",
        "key": {"@id": format!("{OBJECTS}/object")},
        "field": fields(OBJECTS, &OBJECT_COLUMNS, &json!({"fileObject": {"@id": OBJECTS_TABLE}})),
    });
    let mut dataset = json!({
        "@context": context(),
        "@type": "sc:Dataset",
        "conformsTo": "http://mlcommons.org/croissant/1.0",
        "name": metadata.title,
        "description": metadata.description,
        "license": license_url(&metadata.license),
        "version": metadata.version,
        "datePublished": metadata.date,
        "keywords": metadata.keywords,
        "creator": metadata.creators.iter().map(creator).collect::<Vec<_>>(),
        "publisher": {"@type": "sc:Organization", "name": metadata.publisher},
        "citeAs": dataset_citation(metadata),
        "citation": [NERSP_CITATION],
        "isAccessibleForFree": true,
        "distribution": distribution,
        "recordSet": [views, objects],
    });
    if let Some(url) = &metadata.url {
        dataset["url"] = json!(url);
    }
    dataset
}

/// Croissant 1.0's JSON-LD context, as its specification and `mlcroissant` give it.
fn context() -> Value {
    json!({
        "@language": "en",
        "@vocab": "https://schema.org/",
        "citeAs": "cr:citeAs",
        "column": "cr:column",
        "conformsTo": "dct:conformsTo",
        "cr": "http://mlcommons.org/croissant/",
        "rai": "http://mlcommons.org/croissant/RAI/",
        "data": {"@id": "cr:data", "@type": "@json"},
        "dataType": {"@id": "cr:dataType", "@type": "@vocab"},
        "dct": "http://purl.org/dc/terms/",
        "equivalentProperty": "cr:equivalentProperty",
        "examples": {"@id": "cr:examples", "@type": "@json"},
        "extract": "cr:extract",
        "field": "cr:field",
        "fileProperty": "cr:fileProperty",
        "fileObject": "cr:fileObject",
        "fileSet": "cr:fileSet",
        "format": "cr:format",
        "includes": "cr:includes",
        "isLiveDataset": "cr:isLiveDataset",
        "jsonPath": "cr:jsonPath",
        "key": "cr:key",
        "md5": "cr:md5",
        "parentField": "cr:parentField",
        "path": "cr:path",
        "recordSet": "cr:recordSet",
        "references": "cr:references",
        "regex": "cr:regex",
        "repeated": "cr:repeated",
        "replace": "cr:replace",
        "samplingRate": "cr:samplingRate",
        "sc": "https://schema.org/",
        "separator": "cr:separator",
        "source": "cr:source",
        "subField": "cr:subField",
        "transform": "cr:transform",
        "wd": "https://www.wikidata.org/wiki/",
    })
}

/// The files and SHA-256 a release's `croissant.json` lists: `(contentUrl, sha256)` of each
/// file object, in order; an error says what is malformed.
pub fn listed_files(croissant: &Value) -> std::result::Result<Vec<(String, String)>, String> {
    let distribution = croissant["distribution"].as_array().ok_or("no distribution list")?;
    distribution
        .iter()
        .filter(|entry| entry["@type"] == "cr:FileObject")
        .map(|entry| match (entry["contentUrl"].as_str(), entry["sha256"].as_str()) {
            (Some(file), Some(sha256)) => Ok((file.to_string(), sha256.to_string())),
            _ => Err(format!("a file object without contentUrl or sha256: {entry}")),
        })
        .collect()
}
