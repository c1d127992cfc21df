//! A release's tables: one record per view and split (`index/views-train.json`,
//! `index/views-eval.json`) and one per object (`index/objects.json`), the records that its
//! Croissant metadata and its dataset card describe. Each table is a JSON array of objects, one
//! key per column, `null` where a view or object has nothing: JSON keeps a view named `000` a
//! name (a CSV reader would take it for the number 0) and every number exact. Paths are
//! relative to the release.

use crate::Result;
use rmvp_dataset::io::write_bytes_atomically;
use rmvp_dataset::layout::rmvp::{SceneManifest, SceneViewRecord};
use rmvp_dataset::Split;
use serde_json::{json, Value};
use std::path::Path;

/// The tables' folder in a release.
pub const INDEX_FOLDER: &str = "index";
/// The objects' table.
pub const OBJECTS_TABLE: &str = "index/objects.json";
/// The splits, in order, as their tables name them.
pub const SPLITS: [Split; 2] = [Split::Train, Split::Eval];

/// The views' table of `split`.
pub fn views_table(split: Split) -> String {
    format!("{INDEX_FOLDER}/views-{split}.json")
}

/// A column of a table: name, what it holds, and its Croissant data type.
#[derive(Clone, Copy, Debug)]
pub struct Column {
    /// Header.
    pub name: &'static str,
    /// What it holds.
    pub description: &'static str,
    /// `sc:Text`, `sc:Integer`, `sc:Float` or `sc:URL`.
    pub data_type: &'static str,
}

const fn column(name: &'static str, description: &'static str, data_type: &'static str) -> Column {
    Column { name, description, data_type }
}

/// The views' columns.
pub const VIEW_COLUMNS: [Column; 28] = [
    column("object", "The object's folder in the release.", "sc:Text"),
    column("view", "The view's name.", "sc:Text"),
    column("split", "train (an input of reconstruction) or eval (held out).", "sc:Text"),
    column("width", "Image width, pixels.", "sc:Integer"),
    column("height", "Image height, pixels.", "sc:Integer"),
    column("fx", "K[0][0], pixels.", "sc:Float"),
    column("fy", "K[1][1], pixels.", "sc:Float"),
    column("cx", "K[0][2], pixels (pixel (i, j) is centred at (i + 0.5, j + 0.5)).", "sc:Float"),
    column("cy", "K[1][2], pixels.", "sc:Float"),
    column("skew", "K[0][1].", "sc:Float"),
    column("r11", "World-to-camera rotation R (OpenCV: x_cam = R x_world + t), row 1, column 1.", "sc:Float"),
    column("r12", "R, row 1, column 2.", "sc:Float"),
    column("r13", "R, row 1, column 3.", "sc:Float"),
    column("r21", "R, row 2, column 1.", "sc:Float"),
    column("r22", "R, row 2, column 2.", "sc:Float"),
    column("r23", "R, row 2, column 3.", "sc:Float"),
    column("r31", "R, row 3, column 1.", "sc:Float"),
    column("r32", "R, row 3, column 2.", "sc:Float"),
    column("r33", "R, row 3, column 3.", "sc:Float"),
    column("t1", "World-to-camera translation t, x.", "sc:Float"),
    column("t2", "t, y.", "sc:Float"),
    column("t3", "t, z.", "sc:Float"),
    column("stokes", "Stokes S0, S1, S2 (EXR, linear, image frame).", "sc:URL"),
    column("mask", "Object mask (8-bit PNG, 255 object).", "sc:URL"),
    column("aop", "Angle of polarization (EXR, radians, from image +x towards +y).", "sc:URL"),
    column("dop", "Degree of polarization (EXR).", "sc:URL"),
    column("normal", "Ground-truth world-frame normals (EXR), empty without a scan.", "sc:URL"),
    column("depth", "Ground-truth z-depth (EXR), empty without a scan.", "sc:URL"),
];

/// The objects' columns.
pub const OBJECT_COLUMNS: [Column; 7] = [
    column("object", "The object's folder in the release.", "sc:Text"),
    column("views", "Number of views.", "sc:Integer"),
    column("train_views", "Number of training views.", "sc:Integer"),
    column("mesh", "The aligned laser scan, the ground-truth mesh (PLY, world frame), empty without one.", "sc:URL"),
    column("scan", "The scan's file as the lab gave it (its name), empty without one.", "sc:Text"),
    column("env_map", "The environment map (EXR), empty without one.", "sc:URL"),
    column("build_record", "How the object was built (JSON).", "sc:URL"),
];

/// One object of a release, as the tables need it.
pub struct IndexedObject<'a> {
    /// Folder name.
    pub name: &'a str,
    /// Its rmvp layout's manifest.
    pub manifest: &'a SceneManifest,
    /// The scan's file name, if scanned.
    pub scan: Option<String>,
}

/// The cells of a view's row, in [`VIEW_COLUMNS`] order.
fn view_row(object: &str, record: &SceneViewRecord) -> Vec<Value> {
    let (k, r, t) = (&record.camera.k, &record.camera.r, &record.camera.t);
    let file = |f: &Option<String>| json!(f.as_ref().map(|f| format!("{object}/rmvp/{f}")));
    let mut row = vec![
        json!(object),
        json!(record.name),
        json!(record.split.to_string()),
        json!(record.camera.width),
        json!(record.camera.height),
    ];
    row.extend([k[0][0], k[1][1], k[0][2], k[1][2], k[0][1]].map(|v| json!(v)));
    row.extend(r.iter().flatten().chain(t).map(|v| json!(v)));
    let files = &record.files;
    row.extend([&files.stokes, &files.mask, &files.aop, &files.dop, &files.normal, &files.depth].map(file));
    row
}

/// The cells of an object's row, in [`OBJECT_COLUMNS`] order.
fn object_row(object: &IndexedObject) -> Vec<Value> {
    let file = |f: &Option<String>| json!(f.as_ref().map(|f| format!("{}/rmvp/{f}", object.name)));
    let views = &object.manifest.views;
    vec![
        json!(object.name),
        json!(views.len()),
        json!(views.iter().filter(|v| v.split == Split::Train).count()),
        file(&object.manifest.mesh),
        json!(object.scan),
        file(&object.manifest.env_map),
        json!(format!("{}/{}", object.name, crate::build::BUILD_FILE)),
    ]
}

/// A table's text: an array of `rows` as objects keyed by `columns`, one row a line.
fn table(columns: &[Column], rows: &[Vec<Value>]) -> String {
    let lines: Vec<String> = rows
        .iter()
        .map(|row| {
            let record: serde_json::Map<String, Value> =
                columns.iter().zip(row).map(|(c, v)| (c.name.to_string(), v.clone())).collect();
            serde_json::to_string(&record).expect("plain data")
        })
        .collect();
    format!("[\n{}\n]\n", lines.join(",\n"))
}

/// Write the tables of `objects` into `release`; returns the views of each split, in
/// [`SPLITS`] order.
pub fn write_index(release: &Path, objects: &[IndexedObject]) -> Result<[usize; 2]> {
    std::fs::create_dir_all(release.join(INDEX_FOLDER))
        .map_err(|e| rmvp_dataset::Error::io(release.join(INDEX_FOLDER), e))?;
    let mut counts = [0; 2];
    for (count, split) in counts.iter_mut().zip(SPLITS) {
        let rows: Vec<Vec<Value>> = objects
            .iter()
            .flat_map(|o| o.manifest.views.iter().filter(|v| v.split == split).map(|v| view_row(o.name, v)))
            .collect();
        *count = rows.len();
        write_bytes_atomically(&release.join(views_table(split)), table(&VIEW_COLUMNS, &rows).as_bytes())?;
    }
    let rows: Vec<Vec<Value>> = objects.iter().map(object_row).collect();
    write_bytes_atomically(&release.join(OBJECTS_TABLE), table(&OBJECT_COLUMNS, &rows).as_bytes())?;
    Ok(counts)
}

/// What each of the objects' files belongs to: `object spot, view 003 (train)` for a view's
/// files in `rmvp/` (the NeRSP layout holds the same views, numbered), `object spot` for the
/// object's other files, keyed by their paths in the release.
pub fn file_owners(objects: &[IndexedObject], files: &[String]) -> std::collections::BTreeMap<String, String> {
    let mut owners = std::collections::BTreeMap::new();
    for object in objects {
        let prefix = format!("{}/", object.name);
        for file in files.iter().filter(|f| f.starts_with(&prefix)) {
            owners.insert(file.clone(), format!("object {}", object.name));
        }
        for view in &object.manifest.views {
            let f = &view.files;
            let mut named: Vec<&String> =
                [&f.stokes, &f.mask, &f.aop, &f.dop, &f.normal, &f.depth, &f.preview].into_iter().flatten().collect();
            named.extend(f.polarizers.iter().flatten());
            for file in named {
                let owner = format!("object {}, view {} ({})", object.name, view.name, view.split);
                owners.insert(format!("{}/rmvp/{file}", object.name), owner);
            }
        }
    }
    owners
}
