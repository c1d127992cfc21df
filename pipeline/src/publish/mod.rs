//! Releases of built datasets (`rmvp dataset publish`): one folder per object (both layouts
//! and the build record), contact sheets, tables of the views and objects, a dataset card
//! (`README.md`: the Hub's front matter above a generated datasheet), the metadata that venues
//! and repositories read (Croissant, DataCite, Zenodo), a page to look at (`report.html`) and
//! `SHA256SUMS`; optionally a tar or zip archive of the whole. A release is written beside its
//! final place (`RELEASE.partial`) and moved there whole, so that a folder named like a release
//! is always complete. Who publishes it and under what licence ([`metadata`]) must be given.
//!
//! ```text
//! RELEASE/README.md                  dataset card: front matter (licence, configs per split),
//!                                    then the datasheet: objects, camera, calibration, poses,
//!                                    scan alignment, split, formats and frames, licence, loading
//! RELEASE/croissant.json             MLCommons Croissant 1.0 (files, record sets, citations)
//! RELEASE/datacite.json .zenodo.json DataCite's and Zenodo's metadata (creators, licence, ...)
//! RELEASE/index/views-train.json     one record per view of the split: camera, files
//! RELEASE/index/views-eval.json
//! RELEASE/index/objects.json         one record per object: views, mesh, scan
//! RELEASE/report.html                the datasheet, each object's truth in 3D and its views
//!                                    (crate::report), the checksums
//! RELEASE/SHA256SUMS                 `sha256sum -c` format, every other file
//! RELEASE/<object>/build.json        the build record (rmvp_pipeline::build::BuildRecord),
//!                                    its input files named without their paths
//! RELEASE/<object>/nersp/ rmvp/      the two layouts
//! RELEASE/<object>/contact/s0.png aop_dop.png normals.png
//! ```

pub mod card;
pub mod croissant;
pub mod datacite;
pub mod index;
pub mod metadata;

use crate::build::{BuildRecord, ENV_CONVENTION};
use crate::report::{write_dataset_report, DatasetObject, PAGE};
use crate::{Error, Result};
use index::{write_index, IndexedObject};
use metadata::{license_url, ReleaseInfo, ReleaseMetadata};
use rmvp_dataset::io::json::write_json;
use rmvp_dataset::io::{png, write_bytes_atomically};
use rmvp_dataset::layout::{read_scene, rmvp::read_manifest, Layout};
use rmvp_dataset::progress::progress_bar;
use rmvp_dataset::session::{files_under, sha256_file};
use rmvp_dataset::visualize::{contact_sheet, downsample, view_pictures};
use rmvp_dataset::{Image, Scene};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// The checksum file of a release.
pub const CHECKSUMS: &str = "SHA256SUMS";
/// The datasheet of a release.
pub const DATASHEET: &str = "README.md";
/// Contact sheets of an object.
pub const CONTACT_FOLDER: &str = "contact";
/// Contact-sheet tiles are at most this wide.
const TILE_WIDTH: usize = 256;

/// An archive of a whole release.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
#[serde(rename_all = "lowercase")]
pub enum Archive {
    /// `RELEASE.tar` (uncompressed: the float arrays barely compress).
    Tar,
    /// `RELEASE.zip` (stored).
    Zip,
}

/// What to publish; [`PublishOptions::default`] holds `rmvp dataset publish`'s defaults.
#[derive(Clone, Debug, PartialEq)]
pub struct PublishOptions {
    /// Built datasets (`rmvp dataset build`), one object each.
    pub datasets: Vec<PathBuf>,
    /// The release folder (must not exist).
    pub output: PathBuf,
    /// Creators, licence, title, version, ... (the licence and the creators must be given).
    pub info: ReleaseInfo,
    /// An archive of the release beside it.
    pub archive: Option<Archive>,
    /// Show progress bars.
    pub progress: bool,
}

impl Default for PublishOptions {
    fn default() -> Self {
        Self {
            datasets: Vec::new(),
            output: PathBuf::from("release"),
            info: ReleaseInfo::default(),
            archive: None,
            progress: true,
        }
    }
}

/// What a release holds.
#[derive(Clone, Debug, PartialEq)]
pub struct Release {
    /// Object folders, in order.
    pub objects: Vec<String>,
    /// Files listed in `SHA256SUMS`.
    pub files: usize,
    /// Their bytes.
    pub bytes: u64,
    /// The archive written, if any.
    pub archive: Option<PathBuf>,
}

/// Publish `options.datasets` into `options.output`.
pub fn publish(options: &PublishOptions) -> Result<Release> {
    let out = &options.output;
    if out.exists() {
        return Err(Error::Folder { path: out.clone(), why: "exists already; a release is written once".into() });
    }
    if options.datasets.is_empty() {
        return Err(Error::Folder { path: out.clone(), why: "no dataset to publish".into() });
    }
    let metadata = options.info.clone().resolve()?;
    let partial = sibling(out, "partial");
    if partial.exists() {
        std::fs::remove_dir_all(&partial).map_err(|e| rmvp_dataset::Error::io(&partial, e))?;
    }
    let mut objects: Vec<(String, BuildRecord, Scene)> = Vec::new();
    for dataset in &options.datasets {
        let record = BuildRecord::read(dataset)?;
        if !record.complete {
            return Err(Error::Folder {
                path: dataset.clone(),
                why: "an unfinished build; complete it before publishing".into(),
            });
        }
        let mut name = folder_name(&record.object);
        if objects.iter().any(|(n, _, _)| *n == name) {
            name = format!("{name}_{}", objects.len() + 1);
        }
        let scene = read_scene(&dataset.join(Layout::Rmvp.name()))?;
        let dir = partial.join(&name);
        for layout in [Layout::Nersp, Layout::Rmvp] {
            copy_tree(&dataset.join(layout.name()), &dir.join(layout.name()))?;
        }
        // The record without the building machine's paths.
        record.for_release().write(&dir)?;
        write_contact_sheets(&scene, &dir.join(CONTACT_FOLDER))?;
        objects.push((name, record, scene));
    }
    // The tables, then every data file's checksum, which the metadata lists.
    let mut manifests = Vec::new();
    for (name, _, _) in &objects {
        manifests.push(read_manifest(&partial.join(name).join(Layout::Rmvp.name()))?);
    }
    let indexed: Vec<IndexedObject> = objects
        .iter()
        .zip(&manifests)
        .map(|((name, record, _), manifest)| IndexedObject {
            name,
            manifest,
            scan: record.scan.as_ref().and_then(|s| s.file.file_name()).map(|f| f.to_string_lossy().into_owned()),
        })
        .collect();
    let counts = write_index(&partial, &indexed)?;
    let data_files = files_under(&partial)?;
    let bar = progress_bar(options.progress, data_files.len() as u64, "checksums");
    let mut listed = Vec::new();
    let mut bytes = 0;
    for file in &data_files {
        let (hash, size) = sha256_file(&partial.join(file))?;
        bytes += size;
        listed.push((file.clone(), hash));
        bar.inc(1);
    }
    bar.finish();
    let owners = index::file_owners(&indexed, &data_files);
    write_json(&partial.join(croissant::CROISSANT), &croissant::croissant(&metadata, &listed, &owners))?;
    let mut formats: Vec<&str> = listed.iter().map(|(f, _)| croissant::encoding_format(f)).collect();
    formats.sort();
    formats.dedup();
    write_json(&partial.join(datacite::DATACITE), &datacite::datacite(&metadata, &formats, bytes))?;
    write_json(&partial.join(datacite::ZENODO), &datacite::zenodo(&metadata))?;
    let datasheet = datasheet(&metadata, &objects);
    let card = card::front_matter(&metadata, counts.iter().sum()) + &datasheet;
    write_bytes_atomically(&partial.join(DATASHEET), card.as_bytes())?;
    let mut sums = String::new();
    for name in [croissant::CROISSANT, datacite::DATACITE, datacite::ZENODO, DATASHEET] {
        let (hash, size) = sha256_file(&partial.join(name))?;
        bytes += size;
        listed.push((name.to_string(), hash));
    }
    listed.sort();
    for (file, hash) in &listed {
        let _ = writeln!(sums, "{hash}  {file}");
    }
    let shown: Vec<DatasetObject> = objects.iter().map(|(name, _, scene)| DatasetObject { name, scene }).collect();
    bytes += write_page_and_checksums(&partial, &metadata.title, &datasheet, &shown, &sums)?;
    std::fs::rename(&partial, out).map_err(|e| rmvp_dataset::Error::io(out, e))?;
    let archive = options.archive.map(|kind| write_archive(out, kind)).transpose()?;
    Ok(Release { objects: objects.into_iter().map(|(n, _, _)| n).collect(), files: listed.len() + 1, bytes, archive })
}

/// The release's page (`report.html`), showing the data files' checksums `sums`, and
/// `SHA256SUMS`: `sums` and the page's; returns the page's bytes.
fn write_page_and_checksums(
    release: &Path,
    title: &str,
    datasheet: &str,
    objects: &[DatasetObject],
    sums: &str,
) -> Result<u64> {
    let page = write_dataset_report(release, title, datasheet, objects, Some(sums))?;
    let (hash, size) = sha256_file(&page)?;
    write_bytes_atomically(&release.join(CHECKSUMS), format!("{sums}{hash}  {PAGE}\n").as_bytes())?;
    Ok(size)
}

/// Write a published release's page again (`rmvp report RELEASE`), from its datasheet, its
/// objects and its checksums, and its line in `SHA256SUMS`; returns the page's path. The data
/// files are not read beyond what the page shows, nor checked (`rmvp dataset verify` does).
pub fn write_release_report(release: &Path) -> Result<PathBuf> {
    let card = rmvp_dataset::io::input::read_text(&release.join(DATASHEET))?;
    let datasheet = without_front_matter(&card);
    let title = datasheet.lines().find_map(|l| l.strip_prefix("# ")).unwrap_or("release").to_string();
    let listed = rmvp_dataset::io::input::read_text(&release.join(CHECKSUMS))?;
    let sums: String =
        listed.lines().filter(|l| !l.ends_with(&format!("  {PAGE}"))).map(|l| format!("{l}\n")).collect();
    let build_record = format!("/{}", crate::build::BUILD_FILE);
    let names: Vec<&str> = sums.lines().filter_map(|l| l.split_once("  ")?.1.strip_suffix(&build_record)).collect();
    let mut scenes = Vec::new();
    for name in &names {
        rmvp_dataset::io::input::file_name(name)
            .map_err(|why| rmvp_dataset::Error::format(release.join(CHECKSUMS), format!("object {why}")))?;
        scenes.push(read_scene(&release.join(name).join(Layout::Rmvp.name()))?);
    }
    let objects: Vec<DatasetObject> =
        names.iter().zip(&scenes).map(|(name, scene)| DatasetObject { name, scene }).collect();
    write_page_and_checksums(release, &title, datasheet, &objects, &sums)?;
    Ok(release.join(PAGE))
}

/// A dataset card's text after its YAML front matter (all of it when it has none).
pub fn without_front_matter(card: &str) -> &str {
    card.strip_prefix("---\n")
        .and_then(|rest| rest.split_once("\n---\n"))
        .map_or(card, |(_, body)| body.trim_start_matches('\n'))
}

/// `path` with `.suffix` added to its file name.
fn sibling(path: &Path, suffix: &str) -> PathBuf {
    let mut name = path.file_name().unwrap_or_default().to_os_string();
    name.push(format!(".{suffix}"));
    path.with_file_name(name)
}

/// A folder name from an object name: letters, digits, `-` and `_`.
fn folder_name(object: &str) -> String {
    let name: String =
        object.chars().map(|c| if c.is_ascii_alphanumeric() || c == '-' || c == '_' { c } else { '_' }).collect();
    if name.is_empty() {
        "object".into()
    } else {
        name
    }
}

fn copy_file(from: &Path, to: &Path) -> Result<()> {
    if let Some(parent) = to.parent() {
        std::fs::create_dir_all(parent).map_err(|e| rmvp_dataset::Error::io(parent, e))?;
    }
    std::fs::copy(from, to).map_err(|e| rmvp_dataset::Error::io(from, e))?;
    Ok(())
}

fn copy_tree(from: &Path, to: &Path) -> Result<()> {
    for file in files_under(from)? {
        copy_file(&from.join(&file), &to.join(&file))?;
    }
    Ok(())
}

/// S0 previews, AoP x DoP and ground-truth normals of every view (training views first).
fn write_contact_sheets(scene: &Scene, dir: &Path) -> Result<()> {
    let mut sheets: [Vec<Image<u8>>; 3] = Default::default();
    for view in &scene.views {
        for (sheet, picture) in sheets.iter_mut().zip(view_pictures(view)) {
            sheet.extend(picture.map(|p| downsample(&p, p.width().div_ceil(TILE_WIDTH))));
        }
    }
    std::fs::create_dir_all(dir).map_err(|e| rmvp_dataset::Error::io(dir, e))?;
    for (tiles, name) in sheets.iter().zip(["s0.png", "aop_dop.png", "normals.png"]) {
        if !tiles.is_empty() {
            png::write_png_u8(&dir.join(name), &contact_sheet(tiles, 6))?;
        }
    }
    Ok(())
}

/// The archive of `release` beside it (`RELEASE.tar` or `.zip`), written atomically.
fn write_archive(release: &Path, kind: Archive) -> Result<PathBuf> {
    let ext = match kind {
        Archive::Tar => "tar",
        Archive::Zip => "zip",
    };
    let path = sibling(release, ext);
    let root = release.file_name().unwrap_or_default().to_string_lossy().into_owned();
    let files = files_under(release)?;
    rmvp_dataset::io::write_atomically(&path, |writer| {
        match kind {
            Archive::Tar => {
                let mut tar = tar::Builder::new(writer);
                for file in &files {
                    tar.append_path_with_name(release.join(file), format!("{root}/{file}"))?;
                }
                tar.finish()?;
            }
            Archive::Zip => {
                let mut zip = zip::ZipWriter::new_stream(writer);
                let options = zip::write::SimpleFileOptions::default()
                    .compression_method(zip::CompressionMethod::Stored)
                    .large_file(true);
                for file in &files {
                    zip.start_file(format!("{root}/{file}"), options).map_err(std::io::Error::other)?;
                    std::io::copy(&mut std::fs::File::open(release.join(file))?, &mut zip)?;
                }
                zip.finish().map_err(std::io::Error::other)?;
            }
        }
        Ok(())
    })?;
    Ok(path)
}

/// The datasheet of a release.
fn datasheet(metadata: &ReleaseMetadata, objects: &[(String, BuildRecord, Scene)]) -> String {
    let mut s = String::new();
    let _ = writeln!(s, "# {}\n", metadata.title);
    let creators: Vec<&str> = metadata.creators.iter().map(|c| c.name.as_str()).collect();
    let _ = writeln!(
        s,
        "Version {} by {}, published {} by {} with rmvp {} (`rmvp dataset publish`). License of the data: \
         **{}** (<{}>). Check the files with `sha256sum -c {CHECKSUMS}` or `rmvp dataset verify .`.\n\n{}\n",
        metadata.version,
        creators.join("; "),
        metadata.date,
        metadata.publisher,
        env!("CARGO_PKG_VERSION"),
        metadata.license,
        license_url(&metadata.license),
        metadata.description,
    );
    let _ = writeln!(s, "## Objects\n");
    let _ = writeln!(s, "| object | views | training views | image size | ground truth | environment map |");
    let _ = writeln!(s, "| --- | --- | --- | --- | --- | --- |");
    for (name, record, scene) in objects {
        let _ = writeln!(
            s,
            "| `{name}` | {} | {} ({}) | {}x{} | {} | {} |",
            record.views.len(),
            record.train.len(),
            record.train.join(", "),
            record.size[0],
            record.size[1],
            if scene.mesh.is_some() { "laser scan, normals, depth" } else { "none" },
            if scene.env_map.is_some() { "yes" } else { "no" },
        );
    }
    for (name, record, _) in objects {
        let _ = write!(s, "\n## `{name}`\n\n{}", record.datasheet_section());
    }
    let _ = write!(
        s,
        "\n## Citation\n\nThe data:\n\n```bibtex\n{}\n```\n\nThe method it was made for:\n\n```bibtex\n{}\n```\n",
        croissant::dataset_citation(metadata),
        metadata::NERSP_CITATION
    );
    let _ = write!(
        s,
        "{}",
        FORMATS.replace("{ENV}", ENV_CONVENTION).replace("{CHECKSUMS}", CHECKSUMS).replace("{CONTACT}", CONTACT_FOLDER)
    );
    s
}

/// The datasheet's fixed part: files, frames, loading.
const FORMATS: &str = r#"
## Files and frames

Each object folder holds the same data twice:

- `nersp/`, the layout of the official NeRSP loader (`models/dataio/ours_data.py`), read unchanged:
  `cameras.npz` (`world_mat_i` = K [R | t] as 4x4, `scale_mat_i` = unit sphere to world, training
  views i = 0..N-1, 0-based), `image/0000.png` (8-bit preview of S0),
  `input_azimuth_maps/0000.png` (16-bit RGBA: R = G = B = AoP / pi * 65535, alpha = mask),
  `s0/ s1/ s2/0000.npy` (float32 H x W x 3; the loader multiplies them by 0.5), and in `gt/`
  every view, training and held out: `cameras.json` (K, R, t, size, split), `mask/`, `normal/`
  (world-frame unit normals, EXR channels N.X N.Y N.Z), `depth/` (z-depth, EXR channel Z),
  `mesh.ply` (the aligned scan, world frame), `env.exr`.
- `rmvp/`, rmvp's layout: `scene.json` (versioned manifest) and `views/<name>/` per view
  (`stokes.exr`, `mask.png`, `aop.exr`, `dop.exr`, `normal.exr`, `depth.exr`).

Conventions: cameras follow OpenCV (x right, y down, z forward, `x_cam = R x_world + t`, pixel
(i, j) centred at (i + 0.5, j + 0.5)); lens distortion is removed from every image. Stokes vectors
are linear radiance in the image frame: AoP = 0.5 atan2(S2, S1) from image +x towards image +y
(down), `I(theta) = 0.5 (S0 + S1 cos 2 theta + S2 sin 2 theta)`. The ground-truth silhouette of a
view is where its depth is positive. Environment map: {ENV}.

`{CONTACT}/` holds pictures of every view: S0, AoP (hue) x DoP (brightness), ground-truth normals.
`build.json` records how each object was built (inputs, stages, residuals).

Tables (JSON arrays, one object per record, `null` where there is nothing):
`index/views-train.json` and `index/views-eval.json` hold one record per view of the split
(object, view, split, image size, K as fx fy cx cy skew, R row by row as r11 ... r33, t as t1 t2
t3, and the view's files in `rmvp/`), `index/objects.json` one per object (views, ground-truth
mesh, scan). The
metadata: `croissant.json` (MLCommons Croissant 1.0: every data file with its SHA-256, record
sets of the tables, the licence and citations), `datacite.json` and `.zenodo.json` (creators,
licence and version, as DataCite and Zenodo read them); the front matter of this file is the
Hugging Face Hub's.

## Loading

- Python: `rmvp.read_release(RELEASE, split="train")`, the split's views of every object, the
  files checked against `{CHECKSUMS}` first.
- Croissant: `mlcroissant.Dataset("croissant.json").records("views")`.
- NeRSP: point its `data_dir` at an object's `nersp/` folder (`data_type = ours_real`).
- rmvp: `rmvp recon OBJECT/nersp -o out` (either layout), `rmvp eval OBJECT/nersp --pred out/mesh.ply --gt OBJECT/nersp/gt/mesh.ply`.
- Exports: `rmvp dataset export OBJECT/rmvp --format nerfstudio|colmap|rmvp3d -o DIR`.
"#;
