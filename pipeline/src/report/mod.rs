//! One page (`report.html`) per reconstruction, batch, built dataset and release,
//! self-contained: nothing fetched, no server. A reconstruction's: the mesh in an interactive
//! 3D view (our own small WebGL code, `viewer.js`) with the views' cameras as frustums, coloured
//! by its distance to the truth where there is one, the training's losses and normal error
//! plotted (SVG), the figures as tables (options, evaluation, times, residuals), and the
//! pictures the run wrote (comparison, residuals, normal error maps); a batch's: a sortable row
//! per task linking to its page; a dataset's ([`write_dataset_report`]): its datasheet, its
//! truth in 3D and a grid of its views. Meshes above [`PAGE_TRIANGLES`] triangles are decimated
//! for the page, which says so; the full mesh stays beside it.

mod dataset;

pub use dataset::{write_dataset_report, DatasetObject};

use crate::Result;
use base64::engine::general_purpose::STANDARD as BASE64;
use base64::Engine;
use rmvp_dataset::io::atomic::write_bytes_atomically;
use rmvp_dataset::io::input::{read_bytes, read_text};
use rmvp_dataset::{Mesh, Scene};
use rmvp_recon::reconstruct::{COMPARISON, LOG, MESH, MESH_PARTS, RESIDUALS, RESIDUALS_PICTURE, TIMES};
use rmvp_recon::unseen::UnseenParts;
use serde_json::Value;
use std::collections::HashMap;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// The page's file name in the folder it describes.
pub const PAGE: &str = "report.html";
/// The evaluation a run's folder may hold (`rmvp eval --json`, the demo, the quality bench).
pub const EVALUATION: &str = "evaluation.json";
/// The normal error maps a run's folder may hold (`rmvp eval -o DIR/normal_errors`, a batch's
/// task, the quality bench).
pub const ERROR_MAPS: &str = "normal_errors";
/// Triangles of the mesh the page draws at most.
pub const PAGE_TRIANGLES: usize = 200_000;

/// The largest picture embedded in a page; larger ones (a 1224x1024 capture's contact sheets)
/// are shown from their files beside it, so that the page stays small.
const EMBEDDED_BYTES: usize = 2 << 20;

/// Most points of a loss curve (the log is averaged over buckets beyond).
const CURVE_POINTS: usize = 600;
/// Curves of at most this many points show each as a dot.
const MARKED_POINTS: usize = 64;

/// Write `dir/report.html` for the reconstruction in `dir` (`rmvp recon`'s output), with the
/// cameras of `scene` where given; returns its path.
pub fn write_recon_report(dir: &Path, scene: Option<&Scene>) -> Result<PathBuf> {
    let title = dir.canonicalize().ok().and_then(|d| d.file_name().map(|n| n.to_string_lossy().into_owned()));
    let mut html = page_start(&title.unwrap_or_else(|| "reconstruction".into()));

    html += "<h2>Surface</h2>";
    let mesh_path = dir.join(MESH);
    let evaluation = read_json(&dir.join(EVALUATION))?;
    if mesh_path.is_file() {
        let mesh = Mesh::read(&mesh_path)?;
        let truth = scene.and_then(|s| s.mesh.as_ref()).map(|truth| {
            let threshold = evaluation.as_ref().and_then(|e| e.get("threshold")).and_then(Value::as_f64);
            (truth, 2.0 * threshold.or_else(|| rmvp_align::surface::default_threshold(truth)).unwrap_or(0.01))
        });
        html += &mesh_section("surface", &mesh, scene, truth)?;
        let parts_path = dir.join(MESH_PARTS);
        if parts_path.exists() {
            let parts: UnseenParts = rmvp_dataset::io::json::read_json(&parts_path, "the mesh's parts")?;
            if let Some(line) = parts.summary() {
                let _ = write!(html, "<p>{}</p>", escape(&line));
            }
        }
    } else {
        html += "<p>No mesh yet: the run has not finished.</p>";
    }

    html += "<h2>Figures</h2>";
    let options =
        rmvp_recon::checkpoint::recorded_options(&dir.join(rmvp_recon::reconstruct::CHECKPOINT)).ok().flatten();
    if let Some(options) = options {
        let value = serde_json::to_value(&options).expect("options serialise");
        html += &options_table("Options", &value);
    }
    if let Some(e) = &evaluation {
        html += &evaluation_tables(e);
    }
    if let Some(times) = read_json(&dir.join(TIMES))? {
        let cell = |k: &str| times.get(k).map(figure).unwrap_or_default();
        let _ = write!(
            html,
            "<table><caption>Times</caption><tr><th>training, seconds</th><td>{}</td></tr>\
             <tr><th>mesh and outputs, seconds</th><td>{}</td></tr><tr><th>threads</th><td>{}</td></tr></table>",
            cell("training_seconds"),
            cell("results_seconds"),
            cell("threads")
        );
    }
    if let Some(residuals) = read_json(&dir.join(RESIDUALS))? {
        html += &residual_table(&residuals);
    }

    html += "<h2>Training</h2>";
    let log_path = dir.join(LOG);
    if log_path.is_file() {
        let evaluated = evaluation.as_ref().and_then(|e| e.get("normal_mae_deg")).and_then(Value::as_f64);
        html += &training_plots(&read_text(&log_path)?, &log_path, evaluated)?;
    }

    html += "<h2>Views</h2>";
    for (file, caption) in [
        (COMPARISON, "Per training view: input S0, rendered S0, input AoP, rendered AoP (hue, by DoP), normals."),
        (RESIDUALS_PICTURE, "Per training view: where the model's S0, S1, S2 and AoP differ from the input's."),
    ] {
        html += &picture(dir, file, caption)?;
    }
    let errors = dir.join(ERROR_MAPS);
    if errors.is_dir() {
        let mut maps: Vec<String> = rmvp_dataset::io::input::files_under(&errors)?
            .into_iter()
            .filter(|name| name.ends_with("_normal_error.png") && !name.contains('/'))
            .collect();
        maps.sort();
        html += "<div class=\"grid\">";
        for map in maps {
            let view = map.trim_end_matches("_normal_error.png");
            let caption = format!("view {view}: normal error, black 0 to white 30 degrees");
            html += &picture(dir, &format!("{ERROR_MAPS}/{map}"), &caption)?;
        }
        html += "</div>";
    }
    html += &page_end();
    let page = dir.join(PAGE);
    write_bytes_atomically(&page, html.as_bytes())?;
    Ok(page)
}

/// One finished task of a batch, as its page lists it.
pub struct TaskRow {
    /// The task's id, its folder under `tasks/`.
    pub id: String,
    /// Dataset, variant and seed.
    pub dataset: String,
    /// The variant's name.
    pub variant: String,
    /// The seed.
    pub seed: u64,
    /// Chamfer, F-score and normal error in degrees, where evaluated.
    pub figures: Option<(f64, f64, Option<f64>)>,
    /// Training and outputs, minutes.
    pub minutes: f64,
}

/// Write `dir/report.html` for a batch: one row per finished task (sortable by any column,
/// each linking to the task's own page), after the batch's chart `chart` (a PNG beside it).
pub fn write_batch_report(dir: &Path, tasks: &[TaskRow], chart: &Path) -> Result<PathBuf> {
    let mut html = page_start(&format!("Batch: {} tasks finished", tasks.len()));
    let chart_name = chart.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
    html += &picture(dir, &chart_name, "Normal error by dataset and variant, mean and spread over seeds.")?;
    html += "<table id=\"tasks\"><caption>Tasks (click a column to sort)</caption><tr><th>task</th><th>dataset</th>\
             <th>variant</th><th>seed</th><th>Chamfer</th><th>F-score</th><th>normal error, degrees</th><th>minutes</th></tr>";
    for t in tasks {
        let (chamfer, fscore, normal) = match t.figures {
            Some((c, f, n)) => (format!("{c:.4}"), format!("{f:.3}"), n.map_or(String::new(), |n| format!("{n:.2}"))),
            None => Default::default(),
        };
        let _ = write!(
            html,
            "<tr><td><a href=\"tasks/{0}/{PAGE}\">{0}</a></td><td>{1}</td><td>{2}</td><td>{3}</td><td>{chamfer}</td><td>{fscore}</td><td>{normal}</td><td>{4:.1}</td></tr>",
            escape(&t.id),
            escape(&t.dataset),
            escape(&t.variant),
            t.seed,
            t.minutes
        );
    }
    let _ = write!(html, "</table><script>{}</script></body></html>", include_str!("sort.js"));
    let page = dir.join(PAGE);
    write_bytes_atomically(&page, html.as_bytes())?;
    Ok(page)
}

/// A page's head (its style) and title.
fn page_start(title: &str) -> String {
    format!(
        "<!doctype html><html lang=\"en\"><head><meta charset=\"utf-8\"><title>{0}</title><style>{1}</style></head>\
         <body><h1>{0}</h1>",
        escape(title),
        include_str!("style.css")
    )
}

/// A page's end: its 3D views' script and the element its self-test writes into.
fn page_end() -> String {
    format!("<pre id=\"selftest\" hidden></pre><script>{}</script></body></html>", include_str!("viewer.js"))
}

/// `text` with HTML's special characters escaped.
fn escape(text: &str) -> String {
    text.replace('&', "&amp;").replace('<', "&lt;").replace('>', "&gt;").replace('"', "&quot;")
}

/// A JSON file's value, None where it does not exist.
fn read_json(path: &Path) -> Result<Option<Value>> {
    if !path.exists() {
        return Ok(None);
    }
    let text = read_text(path)?;
    let value = serde_json::from_str(&text).map_err(|e| rmvp_dataset::Error::format(path, format!("not JSON: {e}")))?;
    Ok(Some(value))
}

/// A number as a table shows it.
fn figure(v: &Value) -> String {
    match v {
        Value::Number(n) => match n.as_f64() {
            Some(x) if n.is_f64() => format!("{x:.4}"),
            _ => n.to_string(),
        },
        Value::String(s) => escape(s),
        Value::Null => "".into(),
        other => escape(&other.to_string()),
    }
}

/// A table of the options' scalar fields, the preset's for those not set.
fn options_table(title: &str, value: &Value) -> String {
    let mut html = format!("<table><caption>{}</caption>", escape(title));
    if let Value::Object(map) = value {
        for (k, v) in map.iter().filter(|(_, v)| !v.is_object() && !v.is_array()) {
            let shown = if v.is_null() { "<span class=\"note\">the preset's</span>".into() } else { figure(v) };
            let _ = write!(html, "<tr><th>{}</th><td>{shown}</td></tr>", escape(k));
        }
    }
    html + "</table>"
}

/// The surface figures and the normal error per view of an evaluation.
fn evaluation_tables(e: &Value) -> String {
    let mut html = String::from("<table><caption>Against the truth</caption>");
    for (key, label) in [
        ("chamfer", "Chamfer"),
        ("accuracy", "accuracy (reconstruction to truth)"),
        ("completeness", "completeness (truth to reconstruction)"),
        ("fscore", "F-score"),
        ("threshold", "F-score threshold"),
        ("normal_mae_deg", "normal error, degrees (mean over views)"),
    ] {
        if let Some(v) = e.get(key) {
            let _ = write!(html, "<tr><th>{label}</th><td>{}</td></tr>", figure(v));
        }
    }
    html += "</table>";
    if let Some(Value::Array(views)) = e.get("normal_views") {
        html += "<table><caption>Normal error per view</caption><tr><th>view</th><th>split</th><th>degrees</th><th>pixels</th></tr>";
        for v in views {
            let cell = |k: &str| v.get(k).map(figure).unwrap_or_default();
            let _ = write!(
                html,
                "<tr><td>{}</td><td>{}</td><td>{}</td><td>{}</td></tr>",
                cell("view"),
                cell("split"),
                cell("mae_deg"),
                cell("pixels")
            );
        }
        html += "</table>";
    }
    html
}

/// The residuals of each training view.
fn residual_table(residuals: &Value) -> String {
    let mut html = String::from(
        "<table><caption>The model against its input, per training view</caption><tr><th>view</th><th>pixels</th>\
         <th>S0 relative error</th><th>S1</th><th>S2</th><th>S0 bias</th><th>AoP median error, degrees</th></tr>",
    );
    if let Value::Array(views) = residuals {
        for v in views {
            let cell = |k: &str| v.get(k).map(figure).unwrap_or_default();
            let mae = |i: usize| v.get("relative_mae").and_then(|m| m.get(i)).map(figure).unwrap_or_default();
            let _ = write!(
                html,
                "<tr><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td></tr>",
                cell("view"),
                cell("pixels"),
                mae(0),
                mae(1),
                mae(2),
                cell("relative_bias_s0"),
                cell("aop_median_deg")
            );
        }
    }
    html + "</table>"
}

/// A picture file of `dir` at `name` (a relative path) in the page with its caption: embedded up
/// to [`EMBEDDED_BYTES`], larger ones shown from beside the page (nothing where it is absent).
fn picture(dir: &Path, name: &str, caption: &str) -> Result<String> {
    let path = dir.join(name);
    if !path.exists() {
        return Ok(String::new());
    }
    let bytes = read_bytes(&path)?;
    if !bytes.starts_with(b"\x89PNG\r\n\x1a\n") {
        return Err(rmvp_dataset::Error::format(&path, "not a PNG file").into());
    }
    let source = if bytes.len() <= EMBEDDED_BYTES {
        format!("data:image/png;base64,{}", BASE64.encode(&bytes))
    } else {
        escape(name)
    };
    Ok(format!("<figure><img alt=\"{0}\" src=\"{source}\"><figcaption>{0}</figcaption></figure>", escape(caption)))
}

/// The training's course from its log (`log.jsonl`, one step a line): the loss terms against
/// the iteration (log scale) and, where the run measured it, the normal error against the
/// truth (degrees, with the evaluated mesh's figure `evaluated_deg` beside it), as SVG.
fn training_plots(log: &str, path: &Path, evaluated_deg: Option<f64>) -> Result<String> {
    let mut series: Vec<(String, Vec<f64>)> = Vec::new();
    let mut index: HashMap<String, usize> = HashMap::new();
    let mut normal_error: Vec<(f64, f64)> = Vec::new();
    let mut steps = 0;
    for (n, line) in log.lines().enumerate() {
        let step: Value = serde_json::from_str(line)
            .map_err(|e| rmvp_dataset::Error::format(path, format!("line {}: not a step's report: {e}", n + 1)))?;
        let mut terms: Vec<(String, f64)> =
            vec![("loss".into(), step.get("loss").and_then(Value::as_f64).unwrap_or(f64::NAN))];
        if let Some(Value::Object(losses)) = step.get("losses") {
            terms.extend(losses.iter().map(|(k, v)| (k.clone(), v.as_f64().unwrap_or(f64::NAN))));
        }
        for (name, value) in terms {
            let at = *index.entry(name.clone()).or_insert_with(|| {
                series.push((name, vec![f64::NAN; steps]));
                series.len() - 1
            });
            series[at].1.push(value);
        }
        steps += 1;
        series.iter_mut().for_each(|(_, values)| values.resize(steps, f64::NAN));
        if let Some(e) = step.get("normal_error_deg").and_then(Value::as_f64).filter(|e| e.is_finite()) {
            normal_error.push((steps as f64, e));
        }
    }
    if steps == 0 {
        return Ok("<p>The log is empty.</p>".into());
    }
    let bucket = steps.div_ceil(CURVE_POINTS);
    let curves: Vec<(String, Vec<(f64, f64)>)> = series
        .iter()
        .map(|(name, values)| {
            let points = values
                .chunks(bucket)
                .enumerate()
                .filter_map(|(i, chunk)| {
                    let good: Vec<f64> = chunk.iter().copied().filter(|v| v.is_finite() && *v > 0.0).collect();
                    (!good.is_empty()).then(|| ((i * bucket) as f64, good.iter().sum::<f64>() / good.len() as f64))
                })
                .collect();
            (name.clone(), points)
        })
        .collect();
    let mut html = svg_plot(&curves, steps, Scale::Log, "losses against iteration", &[]);
    if !normal_error.is_empty() {
        let mut marks = Vec::new();
        if let Some(e) = evaluated_deg {
            marks.push(("the extracted mesh, evaluated".to_string(), e));
        }
        html += &svg_plot(
            &[("normal error, degrees".into(), normal_error)],
            steps,
            Scale::Linear,
            "normal error against iteration",
            &marks,
        );
        let _ = write!(
            html,
            "<p class=\"note\">The normal error against the truth during training: the field sphere traced at {} \
             sampled pixels of the views with ground-truth normals every {} iterations.</p>",
            rmvp_recon::tracking::TRACK_PIXELS,
            rmvp_recon::tracking::TRACK_EVERY
        );
    }
    Ok(html)
}

/// The vertical axis of a plot.
#[derive(Clone, Copy, PartialEq)]
enum Scale {
    /// Decades, for losses.
    Log,
    /// From 0, for angles.
    Linear,
}

/// Curves (name, points of iteration and value) over `steps` iterations as an SVG plot, with
/// horizontal dashed lines at `marks` (name, value).
fn svg_plot(
    curves: &[(String, Vec<(f64, f64)>)],
    steps: usize,
    scale: Scale,
    label: &str,
    marks: &[(String, f64)],
) -> String {
    let (w, h, left, bottom) = (760.0, 300.0, 60.0, 30.0);
    let values = curves.iter().flat_map(|(_, p)| p.iter().map(|q| q.1)).chain(marks.iter().map(|m| m.1));
    let (lo, hi, ticks): (f64, f64, Vec<(f64, String)>) = match scale {
        Scale::Log => {
            let logs: Vec<f64> = values.filter(|v| *v > 0.0).map(f64::log10).collect();
            let (lo, hi) = logs.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &v| (a.min(v), b.max(v)));
            let (lo, hi) = if lo.is_finite() { (lo.floor(), hi.ceil().max(lo.floor() + 1.0)) } else { (0.0, 1.0) };
            (lo, hi, (lo as i32..=hi as i32).map(|d| (d as f64, format!("1e{d}"))).collect())
        }
        Scale::Linear => {
            let top = values.fold(0f64, f64::max).max(1e-9);
            let step = [1.0, 2.0, 5.0, 10.0, 20.0, 50.0, 100.0].into_iter().find(|s| top / s <= 6.0).unwrap_or(200.0);
            let hi = (top / step).ceil() * step;
            (0.0, hi, (0..=(hi / step) as usize).map(|k| (k as f64 * step, format!("{}", k as f64 * step))).collect())
        }
    };
    let to_axis = |v: f64| if scale == Scale::Log { v.max(1e-300).log10() } else { v };
    let x = |i: f64| left + (w - left - 10.0) * i / steps.max(1) as f64;
    let y = |v: f64| 10.0 + (h - bottom - 10.0) * (hi - to_axis(v)) / (hi - lo);
    let y_tick = |t: f64| 10.0 + (h - bottom - 10.0) * (hi - t) / (hi - lo);
    let colours = ["#e8e8e8", "#4e9af1", "#f1a24e", "#5fd07a", "#e05d5d", "#b57be8", "#d8d05a"];
    let mut svg = format!("<svg class=\"plot\" viewBox=\"0 0 {w} {h}\" role=\"img\" aria-label=\"{}\">", escape(label));
    for (t, text) in &ticks {
        let yy = y_tick(*t);
        let _ = write!(svg, "<line x1=\"{left}\" x2=\"{}\" y1=\"{yy:.1}\" y2=\"{yy:.1}\" class=\"gridline\"/><text x=\"{}\" y=\"{:.1}\" class=\"tick\">{text}</text>", w - 10.0, 6.0, yy + 4.0);
    }
    let _ =
        write!(svg, "<text x=\"{}\" y=\"{}\" class=\"tick\">iteration (0 to {steps})</text>", w / 2.0 - 60.0, h - 8.0);
    let mut legend = 0;
    for (k, (name, points)) in curves.iter().enumerate() {
        let colour = colours[k % colours.len()];
        let path: String = points.iter().map(|&(i, v)| format!("{:.1},{:.1} ", x(i), y(v))).collect();
        let _ = write!(svg, "<polyline fill=\"none\" stroke=\"{colour}\" stroke-width=\"1.5\" points=\"{path}\"/>");
        if points.len() <= MARKED_POINTS {
            for &(i, v) in points {
                let _ = write!(svg, "<circle cx=\"{:.1}\" cy=\"{:.1}\" r=\"3\" fill=\"{colour}\"/>", x(i), y(v));
            }
        }
        let _ = write!(
            svg,
            "<text x=\"{}\" y=\"{}\" style=\"fill:{colour}\" class=\"legend\">{}</text>",
            w - 190.0,
            24.0 + 16.0 * legend as f64,
            escape(name)
        );
        legend += 1;
    }
    for (name, value) in marks {
        let yy = y(*value);
        let _ = write!(
            svg,
            "<line x1=\"{left}\" x2=\"{}\" y1=\"{yy:.1}\" y2=\"{yy:.1}\" class=\"mark\"/>\
             <text x=\"{}\" y=\"{}\" class=\"legend mark-label\">{}: {value:.2}</text>",
            w - 10.0,
            w - 190.0,
            24.0 + 16.0 * legend as f64,
            escape(name)
        );
        legend += 1;
    }
    svg + "</svg>"
}

/// The 3D view: the mesh (decimated to [`PAGE_TRIANGLES`] if larger), the cameras of `scene`
/// as frustums and, with `truth` (the true surface and the distance shown in full red), each
/// vertex's distance to it, in the page as base64 arrays. `id` names the view in the page.
fn mesh_section(id: &str, mesh: &Mesh, scene: Option<&Scene>, truth: Option<(&Mesh, f64)>) -> Result<String> {
    let (positions, faces) = decimated(mesh, PAGE_TRIANGLES);
    let (lo, hi) = mesh.bounds().unwrap_or(([-1.0; 3], [1.0; 3]));
    let centre = [0, 1, 2].map(|k| 0.5 * (lo[k] + hi[k]));
    let radius = 0.5 * (0..3).map(|k| hi[k] - lo[k]).fold(0f32, f32::max).max(1e-6);
    let mut frustums: Vec<f32> = Vec::new();
    let mut reach = 0f32;
    for view in scene.map(|s| s.views.as_slice()).unwrap_or_default() {
        let c = view.camera.center();
        let corners = [(0.0, 0.0), (1.0, 0.0), (1.0, 1.0), (0.0, 1.0)].map(|(u, v)| {
            let ray = view.camera.ray(u * view.camera.width as f64, v * view.camera.height as f64);
            let p = ray.origin
                + ray.direction
                    * (0.4 * radius as f64 / ray.direction.dot(&(view.camera.r.transpose() * nalgebra::Vector3::z())));
            [p.x as f32, p.y as f32, p.z as f32]
        });
        let apex = [c.x as f32, c.y as f32, c.z as f32];
        reach = reach.max((0..3).map(|k| (apex[k] - centre[k]).powi(2)).sum::<f32>().sqrt());
        for k in 0..4 {
            frustums.extend(apex.iter().chain(&corners[k]));
            frustums.extend(corners[k].iter().chain(&corners[(k + 1) % 4]));
        }
    }
    let base64_of = |values: &mut dyn Iterator<Item = [u8; 4]>| BASE64.encode(values.flatten().collect::<Vec<u8>>());
    let mut data = serde_json::json!({
        "positions": base64_of(&mut positions.iter().flatten().map(|v| v.to_le_bytes())),
        "indices": base64_of(&mut faces.iter().flatten().map(|v| v.to_le_bytes())),
        "centre": centre,
        "radius": radius,
        "frustums": frustums,
        "frustumReach": reach,
    });
    let mut legend = String::new();
    if let Some((truth, full_scale)) = truth {
        let distances = rmvp_align::surface::distances_to_surface(truth, &positions)?;
        data["errors"] = base64_of(&mut distances.iter().map(|&d| (d as f32).to_le_bytes())).into();
        data["errorScale"] = full_scale.into();
        let _ = write!(
            legend,
            "<span class=\"legend-bar\"><span>0</span><span class=\"ramp\"></span><span>{full_scale:.4}</span></span> \
             <span class=\"note\">colour by error: each vertex's distance to the true surface, in the world's units</span>"
        );
    }
    let note = if faces.len() < mesh.faces.len() {
        format!(
            "{} of the mesh's {} triangles drawn here (vertices merged on a grid); the full mesh is beside this page.",
            faces.len(),
            mesh.faces.len()
        )
    } else {
        format!("{} triangles, {} vertices.", mesh.faces.len(), mesh.positions.len())
    };
    let error_option = if truth.is_some() { "<option value=\"error\">error</option>" } else { "" };
    Ok(format!(
        "<div class=\"viewer\" id=\"{id}\"><canvas class=\"mesh-view\" width=\"760\" height=\"520\"></canvas>\
         <p class=\"mesh-error\"></p><label>colour <select class=\"colour\"><option value=\"shaded\">shaded</option>\
         <option value=\"normal\">by normal</option>{error_option}</select></label> {legend}\
         <p class=\"note\">Drag to turn, wheel to zoom; the views' cameras in orange. {note}</p>\
         <script type=\"application/json\" class=\"mesh-data\">{data}</script></div>"
    ))
}

/// `mesh` with at most `triangles` triangles: its vertices merged on ever coarser grids over its
/// bounds (vertex clustering) until the triangles that remain fit. Returns positions and faces.
fn decimated(mesh: &Mesh, triangles: usize) -> (Vec<[f32; 3]>, Vec<[u32; 3]>) {
    if mesh.faces.len() <= triangles {
        return (mesh.positions.clone(), mesh.faces.clone());
    }
    let (lo, hi) = mesh.bounds().unwrap_or(([0.0; 3], [1.0; 3]));
    let size = (0..3).map(|k| hi[k] - lo[k]).fold(0f32, f32::max).max(1e-9);
    let mut cells = 512usize;
    loop {
        let mut cluster: HashMap<[u32; 3], u32> = HashMap::new();
        let mut sums: Vec<([f64; 3], u32)> = Vec::new();
        let remap: Vec<u32> = mesh
            .positions
            .iter()
            .map(|p| {
                let key = [0, 1, 2].map(|k| (((p[k] - lo[k]) / size * cells as f32) as u32).min(cells as u32 - 1));
                let id = *cluster.entry(key).or_insert_with(|| {
                    sums.push(([0.0; 3], 0));
                    sums.len() as u32 - 1
                });
                let s = &mut sums[id as usize];
                (0..3).for_each(|k| s.0[k] += p[k] as f64);
                s.1 += 1;
                id
            })
            .collect();
        let faces: Vec<[u32; 3]> = mesh
            .faces
            .iter()
            .map(|f| f.map(|v| remap[v as usize]))
            .filter(|f| f[0] != f[1] && f[1] != f[2] && f[0] != f[2])
            .collect();
        if faces.len() <= triangles || cells <= 16 {
            let positions = sums.iter().map(|(s, n)| s.map(|v| (v / *n as f64) as f32)).collect();
            return (positions, faces);
        }
        cells = cells * 3 / 4;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_large_mesh_is_decimated_to_the_page_and_keeps_its_shape() {
        let mesh = rmvp_render::shapes::icosphere(7);
        assert!(mesh.faces.len() > 300_000);
        let (positions, faces) = decimated(&mesh, 50_000);
        assert!(faces.len() <= 50_000 && faces.len() > 20_000, "{} triangles", faces.len());
        let worst = positions
            .iter()
            .map(|p| ((p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt() - 1.0).abs())
            .fold(0f32, f32::max);
        assert!(worst < 0.01, "a vertex {worst} off the sphere");
        assert!(faces.iter().flatten().all(|&v| (v as usize) < positions.len()));
    }

    #[test]
    fn names_from_files_are_escaped() {
        assert_eq!(escape("<img src=x onerror=\"a&b\">"), "&lt;img src=x onerror=&quot;a&amp;b&quot;&gt;");
    }
}
