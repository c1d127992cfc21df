//! The page of a built dataset (`rmvp dataset build`) and of a release (`rmvp dataset
//! publish`): its datasheet, then per object the true surface in 3D with the views' cameras and a
//! grid of the views (S0, AoP by DoP, true normals), and a release's checksums.

use super::{escape, mesh_section, page_end, page_start, PAGE};
use crate::Result;
use base64::engine::general_purpose::STANDARD as BASE64;
use base64::Engine;
use rayon::prelude::*;
use rmvp_dataset::io::atomic::write_bytes_atomically;
use rmvp_dataset::io::png::encode_png_u8;
use rmvp_dataset::visualize::{contact_sheet, downsample, view_pictures};
use rmvp_dataset::{Image, Scene, Split, View};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// A view's pictures in the grid are at most this wide.
const TILE_WIDTH: usize = 240;

/// One object of a dataset's page.
pub struct DatasetObject<'a> {
    /// Its name (its folder in a release).
    pub name: &'a str,
    /// Its views, cameras and true surface.
    pub scene: &'a Scene,
}

/// Write `dir/report.html` for a dataset: `datasheet` (Markdown, the release's `README.md` or
/// a build's summary) rendered, then each of `objects`, then `checksums` (the release's
/// `SHA256SUMS` lines) where given; returns its path.
pub fn write_dataset_report(
    dir: &Path,
    title: &str,
    datasheet: &str,
    objects: &[DatasetObject],
    checksums: Option<&str>,
) -> Result<PathBuf> {
    let mut html = page_start(title);
    // The page's heading is the title: a datasheet's own is left out.
    let datasheet = datasheet.strip_prefix(&format!("# {title}\n")).unwrap_or(datasheet);
    let parser = pulldown_cmark::Parser::new_ext(datasheet, pulldown_cmark::Options::ENABLE_TABLES);
    // The datasheet comes from rmvp's own records; raw HTML in it (a name from a file) is shown
    // as text, never as markup.
    let parser = parser.map(|event| match event {
        pulldown_cmark::Event::Html(text) | pulldown_cmark::Event::InlineHtml(text) => {
            pulldown_cmark::Event::Text(text)
        }
        other => other,
    });
    html += "<div class=\"datasheet\">";
    pulldown_cmark::html::push_html(&mut html, parser);
    html += "</div>";
    for (k, object) in objects.iter().enumerate() {
        let _ = write!(html, "<h2>{}</h2>", escape(object.name));
        match &object.scene.mesh {
            Some(mesh) => html += &mesh_section(&format!("object-{k}"), mesh, Some(object.scene), None)?,
            None => html += "<p>No true surface in this dataset (built without a scan).</p>",
        }
        html += &view_grid(object.scene)?;
    }
    if let Some(sums) = checksums {
        let files = sums.lines().count();
        let _ = write!(
            html,
            "<h2>Checksums</h2><details><summary>SHA-256 of the release's {files} data files (<code>SHA256SUMS</code>, \
             which also lists this page)</summary><pre>{}</pre></details>",
            escape(sums)
        );
    }
    html += &page_end();
    let page = dir.join(PAGE);
    write_bytes_atomically(&page, html.as_bytes())?;
    Ok(page)
}

/// Every view of `scene` as one picture (S0, AoP by DoP, true normals, those it has) with its
/// name and split, training views first.
fn view_grid(scene: &Scene) -> Result<String> {
    let tiles: Vec<Option<Vec<u8>>> = scene
        .views
        .par_iter()
        .map(|view| view_strip(view).map(|s| encode_png_u8(&s)).transpose())
        .collect::<Result<_, _>>()?;
    let mut html = String::from(
        "<p class=\"note\">Each view: S0, AoP as hue by DoP as brightness, the true normals (those the dataset \
         has).</p><div class=\"grid views\">",
    );
    for (view, tile) in scene.views.iter().zip(tiles) {
        let Some(png) = tile else { continue };
        let split = match view.split {
            Split::Train => "training",
            Split::Eval => "held out",
        };
        let caption = format!("view {} ({split})", view.name);
        let _ = write!(
            html,
            "<figure><img alt=\"{0}\" src=\"data:image/png;base64,{1}\"><figcaption>{0}</figcaption></figure>",
            escape(&caption),
            BASE64.encode(png)
        );
    }
    Ok(html + "</div>")
}

/// A view's pictures side by side, each shrunk to [`TILE_WIDTH`]; None for a view with none.
fn view_strip(view: &View) -> Option<Image<u8>> {
    let shrunk: Vec<Image<u8>> =
        view_pictures(view).into_iter().flatten().map(|p| downsample(&p, p.width().div_ceil(TILE_WIDTH))).collect();
    (!shrunk.is_empty()).then(|| contact_sheet(&shrunk, shrunk.len()))
}
