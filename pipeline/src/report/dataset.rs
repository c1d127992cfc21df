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
    html += &datasheet_html(datasheet);
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

/// A datasheet's Markdown as HTML. Its text comes from records that quote files (a camera's
/// name, a scan's file name), so what it cannot mean is disarmed: raw HTML is shown as text, a
/// link leads only to a web page (http or https), and no image is fetched.
fn datasheet_html(markdown: &str) -> String {
    use pulldown_cmark::{Event, Tag};
    let web = |url: &str| url.starts_with("https://") || url.starts_with("http://");
    let events =
        pulldown_cmark::Parser::new_ext(markdown, pulldown_cmark::Options::ENABLE_TABLES).map(|event| match event {
            Event::Html(text) | Event::InlineHtml(text) => Event::Text(text),
            Event::Start(Tag::Link { link_type, dest_url, title, id }) if !web(&dest_url) => {
                Event::Start(Tag::Link { link_type, dest_url: "".into(), title, id })
            }
            Event::Start(Tag::Image { link_type, title, id, .. }) => {
                Event::Start(Tag::Image { link_type, dest_url: "".into(), title, id })
            }
            other => other,
        });
    let mut html = String::from("<div class=\"datasheet\">");
    pulldown_cmark::html::push_html(&mut html, events);
    html + "</div>"
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_datasheet_renders_its_tables_and_nothing_a_quoted_file_could_slip_in() {
        let html = datasheet_html(
            "| a | b |\n| --- | --- |\n| 1 | 2 |\n\n- Camera: <script>alert(1)</script> \
             [x](javascript:alert(1)) ![y](https://example.org/y.png) [licence](https://spdx.org/licenses/CC-BY-4.0.html)\n",
        );
        assert!(html.contains("<table>") && html.contains("<td>1</td>"), "{html}");
        assert!(!html.contains("<script") && html.contains("&lt;script&gt;"), "{html}");
        assert!(!html.contains("javascript:") && !html.contains("example.org"), "{html}");
        assert!(html.contains("href=\"https://spdx.org/licenses/CC-BY-4.0.html\""), "{html}");
    }
}
