//! Batch plans: `batch.toml` (datasets x variants x seeds, evaluation settings) read, checked
//! and expanded into numbered tasks, before anything runs or is submitted.
//!
//! ```toml
//! datasets = ["scenes/*_nersp", "/data/rmvp3d/cow/rmvp"]   # relative to this file; globs
//! seeds = [0, 1, 2]
//!
//! [[variant]]
//! name = "full"
//! options = { iters = 1000 }   # `rmvp recon`'s options, by their flags' names
//!
//! [[variant]]
//! name = "no-geometric"
//! options = { no_geometric = true }
//!
//! [evaluation]             # optional: against each dataset's ground-truth mesh and normals
//! max_samples = 200000
//! ```

use crate::{Error, Result};
use rmvp_align::SurfaceOptions;
use rmvp_dataset::layout::Layout;
use rmvp_recon::options::ReconOptions;
use serde::{Deserialize, Serialize};
use std::ops::Range;
use std::path::{Path, PathBuf};
use toml::Spanned;

/// The most tasks a plan may expand to.
pub const MAX_TASKS: usize = 100_000;
/// The largest plan file read, in bytes: a plan names globs, variants and seeds, a few
/// kilobytes; a TOML document takes tens of times its text while parsed.
pub const MAX_PLAN_BYTES: u64 = 1 << 20;
/// The most paths a dataset glob may visit before it is refused (a loop of links, a glob of the
/// whole disk).
pub const MAX_GLOB_VISITS: usize = 100_000;
/// The expanded plan in a batch folder.
pub const PLAN_FILE: &str = "plan.json";
/// The `format` of [`BatchPlan`].
pub const PLAN_FORMAT: &str = "rmvp-batch-plan";

/// A named set of reconstruction options ([`ReconOptions`], the keys of `rmvp recon`'s flags:
/// `mesh_res` is `--mesh-res`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Variant {
    /// Name (table rows, task folders): letters, digits, `-`, `_`, `.`.
    pub name: String,
    /// The options (their defaults where not given); the seed comes from the plan's `seeds`.
    #[serde(default)]
    pub options: ReconOptions,
}

impl Variant {
    /// The reconstruction options of this variant for one seed.
    pub fn recon_options(&self, seed: u64) -> ReconOptions {
        ReconOptions { seed, ..self.options.clone() }
    }
}

/// How tasks are evaluated against their dataset's ground truth.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct EvaluationOptions {
    /// Evaluate at all (then every dataset needs a ground-truth mesh).
    #[serde(default = "yes")]
    pub enabled: bool,
    /// Surface samples per mesh at most.
    #[serde(default = "default_max_samples")]
    pub max_samples: usize,
    /// F-score threshold (default: 1 % of the ground truth's bounding-box diagonal).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub threshold: Option<f64>,
}

fn yes() -> bool {
    true
}

fn default_max_samples() -> usize {
    SurfaceOptions::default().max_samples
}

impl Default for EvaluationOptions {
    fn default() -> Self {
        Self { enabled: true, max_samples: default_max_samples(), threshold: None }
    }
}

impl EvaluationOptions {
    /// Refuse settings no evaluation can run with.
    fn check(&self) -> std::result::Result<(), String> {
        if self.max_samples == 0 {
            return Err("max_samples must be at least 1".into());
        }
        match self.threshold {
            Some(t) if !(t.is_finite() && t > 0.0) => {
                Err(format!("threshold must be a finite positive distance, not {t}"))
            }
            _ => Ok(()),
        }
    }

    /// The surface metrics' options.
    pub fn surface_options(&self) -> SurfaceOptions {
        SurfaceOptions { max_samples: self.max_samples, threshold: self.threshold, ..SurfaceOptions::default() }
    }
}

/// One dataset of a plan.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Dataset {
    /// Name (the folder's, or its parent's for a built dataset's `rmvp/` or `nersp/`).
    pub name: String,
    /// The scene folder, absolute.
    pub scene: PathBuf,
}

/// One reconstruction (and its evaluation) of a batch.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Task {
    /// Position in the plan (the Slurm array index).
    pub index: usize,
    /// `DATASET-VARIANT-sSEED`: the task's folder under `tasks/`.
    pub id: String,
    /// The dataset's name.
    pub dataset: String,
    /// The scene folder.
    pub scene: PathBuf,
    /// The variant.
    pub variant: Variant,
    /// The seed.
    pub seed: u64,
}

/// A plan expanded into tasks (dataset-major, then variant, then seed): `plan.json` of a
/// batch folder, the one file every task reads.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct BatchPlan {
    /// [`PLAN_FORMAT`].
    pub format: String,
    /// The plan file it was read from.
    pub source: PathBuf,
    /// The datasets, globs expanded.
    pub datasets: Vec<Dataset>,
    /// The variants, in the file's order.
    pub variants: Vec<Variant>,
    /// The seeds.
    pub seeds: Vec<u64>,
    /// Evaluation settings.
    pub evaluation: EvaluationOptions,
    /// Every task.
    pub tasks: Vec<Task>,
}

/// `batch.toml` as written.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct PlanFile {
    datasets: Vec<Spanned<String>>,
    #[serde(default = "default_seeds")]
    seeds: Vec<u64>,
    variant: Vec<Spanned<Variant>>,
    #[serde(default)]
    evaluation: EvaluationOptions,
}

fn default_seeds() -> Vec<u64> {
    vec![0]
}

/// The 1-based line of a byte offset.
fn line_of(text: &str, offset: usize) -> usize {
    text[..offset.min(text.len())].bytes().filter(|&b| b == b'\n').count() + 1
}

impl BatchPlan {
    /// Read and expand a plan file. Every fault is refused here, naming the file and line: a
    /// syntax error, an unknown option, a dataset path or glob that finds no scene, a dataset
    /// without the ground truth evaluation needs, a variant with both cues off, duplicate names.
    pub fn read(path: &Path) -> Result<Self> {
        let text = rmvp_dataset::io::input::read_text_limited(path, MAX_PLAN_BYTES)?;
        let fault = |span: Option<Range<usize>>, why: String| Error::Plan {
            path: path.to_path_buf(),
            line: span.map(|s| line_of(&text, s.start)),
            why,
        };
        let file: PlanFile = toml::from_str(&text)
            .map_err(|e| fault(e.span(), rmvp_recon::options::explain_removed(e.message().trim())))?;
        let parent = path.parent().filter(|p| !p.as_os_str().is_empty()).unwrap_or(Path::new("."));
        let base = parent.canonicalize().map_err(|e| rmvp_dataset::Error::io(path, e))?;

        let mut datasets: Vec<(Dataset, Range<usize>)> = Vec::new();
        for entry in &file.datasets {
            let span = entry.span();
            let found = expand_dataset(&base, entry.get_ref()).map_err(|why| fault(Some(span.clone()), why))?;
            for dataset in found {
                if file.evaluation.enabled && !ground_truth_mesh(&dataset.scene).is_file() {
                    let why = format!(
                        "dataset {} has no ground-truth mesh ({}); evaluation needs one (or set enabled = false under [evaluation])",
                        dataset.scene.display(),
                        ground_truth_mesh(&dataset.scene).display()
                    );
                    return Err(fault(Some(span), why));
                }
                if let Some((_, first)) = datasets.iter().find(|(d, _)| d.name == dataset.name) {
                    let why = format!(
                        "two datasets named {:?} (the other on line {}); give them folders of different names",
                        dataset.name,
                        line_of(&text, first.start)
                    );
                    return Err(fault(Some(span), why));
                }
                datasets.push((dataset, span.clone()));
            }
        }
        if datasets.is_empty() {
            return Err(fault(None, "no datasets".into()));
        }
        if file.variant.is_empty() {
            return Err(fault(None, "no [[variant]]".into()));
        }
        if file.seeds.is_empty() {
            return Err(fault(None, "seeds is empty".into()));
        }
        if let Err(why) = file.evaluation.check() {
            return Err(fault(None, format!("[evaluation] {why}")));
        }
        let count = datasets.len().saturating_mul(file.variant.len()).saturating_mul(file.seeds.len());
        if count > MAX_TASKS {
            let why = format!(
                "{} datasets x {} variants x {} seeds make {count} tasks, more than the {MAX_TASKS} a plan may hold; split it",
                datasets.len(),
                file.variant.len(),
                file.seeds.len()
            );
            return Err(fault(None, why));
        }
        let mut variants: Vec<Variant> = Vec::new();
        for entry in &file.variant {
            let (variant, span) = (entry.get_ref(), entry.span());
            let valid_name = !variant.name.is_empty()
                && variant.name.chars().all(|c| c.is_ascii_alphanumeric() || "-_.".contains(c));
            if !valid_name {
                let why = format!("variant name {:?}: use letters, digits, '-', '_' or '.'", variant.name);
                return Err(fault(Some(span), why));
            }
            if variants.iter().any(|v| v.name == variant.name) {
                return Err(fault(Some(span), format!("two variants named {:?}", variant.name)));
            }
            if variant.options.seed != ReconOptions::default().seed {
                let why = format!("variant {:?} sets a seed; give the seeds at the top of the plan", variant.name);
                return Err(fault(Some(span), why));
            }
            if let Err(e) = variant.options.validate() {
                return Err(fault(Some(span), format!("variant {:?}: {e}", variant.name)));
            }
            variants.push(variant.clone());
        }

        let mut tasks = Vec::new();
        for (dataset, _) in &datasets {
            for variant in &variants {
                for &seed in &file.seeds {
                    tasks.push(Task {
                        index: tasks.len(),
                        id: format!("{}-{}-s{seed}", dataset.name, variant.name),
                        dataset: dataset.name.clone(),
                        scene: dataset.scene.clone(),
                        variant: variant.clone(),
                        seed,
                    });
                }
            }
        }
        Ok(Self {
            format: PLAN_FORMAT.into(),
            source: base.join(path.file_name().unwrap_or_default()),
            datasets: datasets.into_iter().map(|(d, _)| d).collect(),
            variants,
            seeds: file.seeds,
            evaluation: file.evaluation,
            tasks,
        })
    }

    /// The task folder of task `index` in batch folder `dir`.
    pub fn task_dir(&self, dir: &Path, index: usize) -> PathBuf {
        dir.join(TASKS_FOLDER).join(&self.tasks[index].id)
    }

    /// Read `plan.json` of a batch folder.
    pub fn load(dir: &Path) -> Result<Self> {
        let plan: Self = rmvp_dataset::io::json::read_json(&dir.join(PLAN_FILE), "a batch plan")?;
        if plan.format != PLAN_FORMAT {
            let why = format!("format {:?}, expected {PLAN_FORMAT:?}", plan.format);
            return Err(rmvp_dataset::Error::format(dir.join(PLAN_FILE), why).into());
        }
        // Task ids become folder names under tasks/.
        for task in &plan.tasks {
            rmvp_dataset::io::input::file_name(&task.id)
                .map_err(|why| rmvp_dataset::Error::format(dir.join(PLAN_FILE), format!("task {why}")))?;
        }
        Ok(plan)
    }

    /// Write `plan.json` into a batch folder (created if needed).
    pub fn save(&self, dir: &Path) -> Result<()> {
        std::fs::create_dir_all(dir).map_err(|e| rmvp_dataset::Error::io(dir, e))?;
        Ok(rmvp_dataset::io::json::write_json(&dir.join(PLAN_FILE), self)?)
    }
}

/// The folder of task folders in a batch folder.
pub const TASKS_FOLDER: &str = "tasks";

/// Where a scene folder keeps its ground-truth mesh.
pub fn ground_truth_mesh(scene: &Path) -> PathBuf {
    match Layout::detect(scene) {
        Ok(Layout::Rmvp) => scene.join("mesh.ply"),
        _ => scene.join("gt/mesh.ply"),
    }
}

/// The scenes one `datasets` entry names: a scene folder, a dataset built by `rmvp dataset
/// build` (its `rmvp/` layout), or a glob of either.
fn expand_dataset(base: &Path, entry: &str) -> std::result::Result<Vec<Dataset>, String> {
    let pattern = base.join(entry);
    let is_glob = entry.contains(['*', '?', '[']);
    let paths: Vec<PathBuf> = if is_glob {
        glob_folders(&pattern).map_err(|why| format!("dataset glob {entry:?}: {why}"))?
    } else {
        vec![pattern.clone()]
    };
    if paths.is_empty() {
        return Err(format!("dataset glob {entry:?} matches no folder (looked in {})", base.display()));
    }
    paths
        .into_iter()
        .map(|path| {
            let scene = if Layout::detect(&path).is_err() && Layout::detect(&path.join("rmvp")).is_ok() {
                path.join("rmvp")
            } else {
                path.clone()
            };
            Layout::detect(&scene).map_err(|e| format!("dataset {entry:?}: {e}"))?;
            let named = if scene == path { &path } else { &scene };
            let folder = |p: &Path| p.file_name().map(|n| n.to_string_lossy().into_owned());
            let mut name = folder(named).unwrap_or_default();
            if name == "rmvp" || name == "nersp" {
                name = named.parent().and_then(folder).unwrap_or(name);
            }
            let name: String =
                name.chars().map(|c| if c.is_ascii_alphanumeric() || "-_.".contains(c) { c } else { '_' }).collect();
            Ok(Dataset { name, scene })
        })
        .collect()
}

/// The folders an absolute glob pattern matches (`*`, `?`, `[...]` within a component, `**`
/// for any number of folders), in path order. The walk follows no symbolic link to a folder
/// under `**`, and gives up after [`MAX_GLOB_VISITS`] folders, so it ends on any tree.
fn glob_folders(pattern: &Path) -> std::result::Result<Vec<PathBuf>, String> {
    let parts: Vec<String> = pattern.components().map(|c| c.as_os_str().to_string_lossy().into_owned()).collect();
    let literal = parts.iter().position(|c| c.contains(['*', '?', '['])).unwrap_or(parts.len());
    let base: PathBuf = parts[..literal].iter().collect();
    let rest = parts[literal..]
        .iter()
        .map(|c| if c == "**" { Ok(None) } else { glob::Pattern::new(c).map(Some) })
        .collect::<std::result::Result<Vec<_>, _>>()
        .map_err(|e| e.to_string())?;
    let mut found = std::collections::BTreeSet::new();
    let mut stack = vec![(base, 0usize)];
    let mut visits = 0usize;
    while let Some((dir, at)) = stack.pop() {
        visits += 1;
        if visits > MAX_GLOB_VISITS {
            return Err(format!("visits more than {MAX_GLOB_VISITS} folders (a loop of links, or too wide a glob)"));
        }
        let Some(part) = rest.get(at) else {
            found.insert(dir);
            continue;
        };
        if part.is_none() {
            stack.push((dir.clone(), at + 1)); // `**` as no folder at all
        }
        let Ok(entries) = std::fs::read_dir(&dir) else { continue };
        for entry in entries.flatten() {
            let path = entry.path();
            match part {
                // `**` descends only into real folders: a link to a folder may lead back up.
                None if entry.file_type().is_ok_and(|t| t.is_dir()) => stack.push((path, at)),
                Some(p) if p.matches(&entry.file_name().to_string_lossy()) && path.is_dir() => {
                    stack.push((path, at + 1))
                }
                _ => {}
            }
        }
    }
    Ok(found.into_iter().collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A scene folder in the NeRSP layout (the index file is all detection needs), with or
    /// without a ground-truth mesh.
    fn fake_scene(dir: &Path, with_mesh: bool) {
        std::fs::create_dir_all(dir.join("gt")).unwrap();
        std::fs::write(dir.join("cameras.npz"), b"").unwrap();
        if with_mesh {
            std::fs::write(dir.join("gt/mesh.ply"), b"").unwrap();
        }
    }

    fn plan_in(dir: &Path, text: &str) -> Result<BatchPlan> {
        let path = dir.join("batch.toml");
        std::fs::write(&path, text).unwrap();
        BatchPlan::read(&path)
    }

    fn refusal(result: Result<BatchPlan>) -> (Option<usize>, String) {
        match result {
            Err(Error::Plan { line, why, .. }) => (line, why),
            other => panic!("expected a plan error, got {other:?}"),
        }
    }

    #[test]
    fn expands_globs_variants_and_seeds_in_order() {
        let dir = tempfile::tempdir().unwrap();
        fake_scene(&dir.path().join("scenes/b_nersp"), true);
        fake_scene(&dir.path().join("scenes/a_nersp"), true);
        fake_scene(&dir.path().join("built/cow/rmvp"), false);
        std::fs::write(dir.path().join("built/cow/rmvp/scene.json"), b"{}").unwrap();
        std::fs::write(dir.path().join("built/cow/rmvp/mesh.ply"), b"").unwrap();
        let plan = plan_in(
            dir.path(),
            "datasets = [\"scenes/*_nersp\", \"built/cow\"]\nseeds = [3, 4]\n\n[[variant]]\nname = \"full\"\noptions = { iters = 50 }\n\n[[variant]]\nname = \"no-geo\"\n[variant.options]\nno_geometric = true\n",
        )
        .unwrap();
        let ids: Vec<&str> = plan.tasks.iter().map(|t| t.id.as_str()).collect();
        assert_eq!(ids.len(), 3 * 2 * 2);
        assert_eq!(&ids[..4], ["a_nersp-full-s3", "a_nersp-full-s4", "a_nersp-no-geo-s3", "a_nersp-no-geo-s4"]);
        assert_eq!(ids[8], "cow-full-s3");
        assert!(plan.tasks[8].scene.ends_with("built/cow/rmvp"));
        assert!(plan.tasks.iter().enumerate().all(|(i, t)| t.index == i));
        let options = plan.tasks[2].variant.recon_options(plan.tasks[2].seed);
        assert!(options.no_geometric && !options.no_photometric && options.seed == 3);
        assert_eq!(plan.tasks[0].variant.recon_options(0).iters, Some(50));
    }

    #[test]
    fn refuses_faults_naming_the_line() {
        let dir = tempfile::tempdir().unwrap();
        fake_scene(&dir.path().join("spot"), true);
        fake_scene(&dir.path().join("nomesh"), false);
        let variant = "\n[[variant]]\nname = \"full\"\n[variant.options]\n";

        let (line, why) = refusal(plan_in(dir.path(), &format!("datasets = [\"spot\"]{variant}iter = 10\n")));
        assert_eq!(line, Some(5), "{why}");
        assert!(why.contains("unknown field `iter`"), "{why}");

        let removed = format!("datasets = [\"spot\"]{variant}aop_reliability = 0.05\n");
        let (line, why) = refusal(plan_in(dir.path(), &removed));
        assert_eq!(line, Some(5), "{why}");
        assert!(why.contains("`aop_reliability` was removed"), "{why}");

        let text = format!("datasets = [\n  \"spot\",\n  \"missing\",\n]{variant}");
        let (line, why) = refusal(plan_in(dir.path(), &text));
        assert_eq!(line, Some(3), "{why}");
        assert!(why.contains("missing") && why.contains("no such scene folder"), "{why}");

        let (line, why) = refusal(plan_in(dir.path(), &format!("datasets = [\"no*\"]{variant}")));
        assert_eq!(line, Some(1));
        assert!(why.contains("ground-truth mesh"), "{why}");

        let (line, why) = refusal(plan_in(dir.path(), &format!("datasets = [\"x*\"]{variant}")));
        assert_eq!(line, Some(1));
        assert!(why.contains("matches no folder"), "{why}");

        let both_off = format!("datasets = [\"spot\"]{variant}no_geometric = true\nno_photometric = true\n");
        let (line, why) = refusal(plan_in(dir.path(), &both_off));
        assert_eq!(line, Some(2), "{why}"); // the variant's [[variant]] header
        assert!(why.contains("both cues"), "{why}");

        let (line, why) = refusal(plan_in(dir.path(), &format!("datasets = [\"spot\"]{variant}preset = \"slow\"\n")));
        assert_eq!(line, Some(5), "{why}");
        assert!(why.contains("slow"), "{why}");

        let twice = format!("datasets = [\"spot\", \"./spot\"]{variant}");
        let (line, why) = refusal(plan_in(dir.path(), &twice));
        assert_eq!(line, Some(1));
        assert!(why.contains("two datasets named \"spot\""), "{why}");
    }
}
