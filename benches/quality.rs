//! Reconstruction quality on two sets of scenes, reconstructed with the default preset and its
//! two ablations and evaluated; one Markdown table: scene, seed, minutes (training + outputs),
//! Chamfer, F-score, normal MAE over the training views, the held-out views and all views, and
//! each set's mean.
//!
//! - `mitsuba`, the main set: the scenes rendered by Mitsuba 3, an independent polarized
//!   renderer whose materials rmvp's model does not match exactly (`../shared/evalset/*` or
//!   `$RMVP_EVALSET`, then `../shared/fixtures/*` or `$RMVP_FIXTURES`), read as they are.
//! - `ours`: `rmvp_pipeline::evaluation_set`'s procedural and public meshes, simulated by rmvp's
//!   own renderer (6 training and 6 held-out views) at `--res`.
//!
//! `cargo bench --bench quality [-- --sets mitsuba,ours --scenes horse,bumps --variants
//! full,no-geometric --res 256x256 --views 6 --iters N --rays N --seed S --preset
//! fast|dense|paper --mesh-res N --curve 250,500 --error-maps]` (part of `./run bench` with its
//! defaults). `--scenes` picks scenes of the sets by name. `--seed 0,1,2` runs each scene and
//! variant at each seed and ends with each one's spread over them: the normal error's and
//! Chamfer's mean and range, and whether a variant's range lies wholly above or below the
//! first variant's (worse or better beyond the seeds' spread). `--views` sets our scenes' training
//! views (the held-out six stay the same). `--curve` also measures the model at those
//! iterations of the run (its mesh; training minutes so far): quality against time.
//! `--error-maps` writes each view's normal error map (`normal_errors/<view>_normal_error.png`)
//! beside the run's mesh; every run keeps its whole evaluation there (`evaluation.json`, with
//! the error by the input's DoP, the true roughness and the depth complexity). Our scenes are
//! simulated once into `target/tmp/bench-quality/<WxH>/<scene>` (`<WxH>-<N>views` for other
//! than 6 training views) and reused; runs of the Mitsuba scenes go into `target/tmp/bench-quality/mitsuba/<scene>`;
//! each row is kept in `results.jsonl` there. The bunny comes from `$RMVP_MESHES` or
//! `../shared/meshes`.
//! Variants not run by default, each the default with one change (`VARIANTS`): `near-surface`
//! 24 uniform and 40 up-sampled samples per ray instead of 32 and 32 (the same samples, more of
//! them near the surface); `wide-margin` the masks dilated by 32 pixels instead of 8;
//! `learned-polarization` and `fixed-polarization` the specular lobe's degree of polarization
//! scaled by a learned number, or NeRSP's fixed dielectric Fresnel. A variant of one's own is
//! `NAME:FIELD=VALUE;...` with any `rmvp recon` option by its field name
//! (`--variants lp2k:learned_polarization=true;iters=2000`).

use rmvp_align::{evaluate, SurfaceOptions};
use rmvp_dataset::layout::read_scene;
use rmvp_dataset::{Mesh, Scene, Split};
use rmvp_pipeline::evaluation_set::{CaptureOptions, SCENES};
use rmvp_recon::options::{ReconOptions, RunControl};
use rmvp_recon::presets::Preset;
use rmvp_recon::reconstruct::{reconstruct, write_mesh, MESH};
use std::io::Write;
use std::ops::ControlFlow;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// One reconstruction of one scene.
struct Row {
    set: &'static str,
    scene: String,
    variant: String,
    seed: u64,
    preset: Preset,
    size: String,
    iterations: u32,
    train_minutes: f64,
    output_minutes: f64,
    chamfer: f64,
    f_score: f64,
    normal_mae_train_deg: f64,
    normal_mae_held_out_deg: f64,
    normal_mae_deg: f64,
}

/// One reconstruction's identity, as its rows show it.
struct Run<'a> {
    set: &'static str,
    scene: &'a str,
    variant: &'a str,
    preset: Preset,
    size: (u32, u32),
    views: usize,
    seed: u64,
}

/// Evaluate `dir`'s mesh (the model after `iterations`, trained and written in `seconds`)
/// against the scene's truth (its mesh and normal maps), with the views' error maps when
/// `error_maps`; print the row and keep it in `log`.
fn measure(
    log: &mut std::fs::File,
    run: &Run,
    data: &Scene,
    dir: &Path,
    iterations: u32,
    seconds: (f64, f64),
    error_maps: bool,
) -> Row {
    let pred = Mesh::read(&dir.join(MESH)).expect("reconstructed mesh");
    let gt = data.mesh.as_ref().expect("ground-truth mesh");
    let evaluation = evaluate(&pred, gt, Some(data), &SurfaceOptions::default()).expect("evaluation");
    if error_maps {
        evaluation.write_error_maps(&dir.join("normal_errors")).expect("error maps");
    }
    evaluation.write(&dir.join("evaluation.json")).expect("evaluation record");
    let row = Row {
        set: run.set,
        scene: run.scene.to_string(),
        variant: run.variant.to_string(),
        seed: run.seed,
        preset: run.preset,
        size: format!("{}x{}", run.size.0, run.size.1),
        iterations,
        train_minutes: seconds.0 / 60.0,
        output_minutes: seconds.1 / 60.0,
        chamfer: evaluation.surface.chamfer,
        f_score: evaluation.surface.fscore,
        normal_mae_train_deg: evaluation.split_normal_mae_deg(Split::Train).unwrap_or(f64::NAN),
        normal_mae_held_out_deg: evaluation.split_normal_mae_deg(Split::Eval).unwrap_or(f64::NAN),
        normal_mae_deg: evaluation.normal_mae_deg.unwrap_or(f64::NAN),
    };
    println!(
        "| {} | {} | {} | {} | {} | {:.1} + {:.2} | {:.4} | {:.3} | {:.2} | {:.2} | {:.2} |",
        row.set,
        row.scene,
        row.variant,
        row.seed,
        row.iterations,
        row.train_minutes,
        row.output_minutes,
        row.chamfer,
        row.f_score,
        row.normal_mae_train_deg,
        row.normal_mae_held_out_deg,
        row.normal_mae_deg
    );
    let line = serde_json::json!({
        "set": row.set, "scene": row.scene, "variant": row.variant, "preset": row.preset, "size": row.size, "views": run.views,
        "iterations": row.iterations, "seed": run.seed, "train_minutes": row.train_minutes,
        "output_minutes": row.output_minutes, "chamfer": row.chamfer, "f_score": row.f_score,
        "normal_mae_train_deg": row.normal_mae_train_deg, "normal_mae_held_out_deg": row.normal_mae_held_out_deg,
        "normal_mae_deg": row.normal_mae_deg,
    });
    writeln!(log, "{line}").expect("results log");
    row
}

/// What the command line asked for.
struct Plan {
    /// The sets of scenes, in order: `mitsuba`, `ours`.
    sets: Vec<String>,
    /// Only the scenes of these names (empty: every scene of the sets).
    scenes: Vec<String>,
    variants: Vec<String>,
    size: (u32, u32),
    /// Training views.
    views: usize,
    iterations: Option<u32>,
    /// Rays per iteration (default: the preset's).
    rays: Option<usize>,
    /// Each scene and variant runs at each of these seeds.
    seeds: Vec<u64>,
    preset: Preset,
    mesh_resolution: usize,
    /// Iterations at which the model is measured too.
    curve: Vec<u32>,
    /// Write each view's normal error map.
    error_maps: bool,
}

fn plan() -> Plan {
    let mut plan = Plan {
        sets: vec!["mitsuba".into(), "ours".into()],
        scenes: Vec::new(),
        variants: ["full", "no-geometric", "no-photometric"].map(String::from).to_vec(),
        size: (256, 256),
        views: CaptureOptions::default().views,
        iterations: None,
        rays: None,
        seeds: vec![0],
        preset: Preset::Fast,
        mesh_resolution: ReconOptions::default().mesh_res,
        curve: Vec::new(),
        error_maps: false,
    };
    let mut args: Vec<String> = std::env::args().skip(1).filter(|a| a != "--bench").collect();
    if let Some(at) = args.iter().position(|a| a == "--error-maps") {
        plan.error_maps = true;
        args.remove(at);
    }
    for pair in args.chunks(2) {
        let value = pair.get(1).unwrap_or_else(|| panic!("{} needs a value", pair[0]));
        let list = || value.split(',').map(String::from).collect::<Vec<_>>();
        match pair[0].as_str() {
            "--sets" => plan.sets = list(),
            "--scenes" => plan.scenes = list(),
            "--variants" => plan.variants = list(),
            "--res" => {
                let (w, h) = value.split_once('x').expect("--res WxH");
                plan.size = (w.parse().expect("width"), h.parse().expect("height"));
            }
            "--views" => plan.views = value.parse().expect("--views N"),
            "--iters" => plan.iterations = Some(value.parse().expect("--iters N")),
            "--rays" => plan.rays = Some(value.parse().expect("--rays N")),
            "--seed" => plan.seeds = list().iter().map(|v| v.parse().expect("--seed N,N")).collect(),
            "--preset" => {
                plan.preset = serde_json::from_value(value.as_str().into()).expect("--preset fast|dense|paper")
            }
            "--mesh-res" => plan.mesh_resolution = value.parse().expect("--mesh-res N"),
            "--curve" => plan.curve = list().iter().map(|v| v.parse().expect("--curve N,N")).collect(),
            other => panic!("unknown argument {other}"),
        }
    }
    plan
}

/// The named variants: each the plan's options with the changes given, as TOML assignments
/// of [`ReconOptions`] fields.
const VARIANTS: [(&str, &str); 7] = [
    ("full", ""),
    ("no-geometric", "no_geometric = true"),
    ("no-photometric", "no_photometric = true"),
    ("near-surface", "coarse_samples = 24\nfine_samples = 40"),
    ("wide-margin", "margin = 32"),
    ("learned-polarization", "learned_polarization = true"),
    ("fixed-polarization", "learned_polarization = false"),
];

/// The options of `variant` at `seed`: a name of [`VARIANTS`], or `NAME:FIELD=VALUE;FIELD=VALUE`
/// (any [`ReconOptions`] fields, TOML values) for a variant of one's own.
fn options(variant: &str, plan: &Plan, seed: u64) -> ReconOptions {
    let base = ReconOptions {
        preset: plan.preset,
        iters: plan.iterations,
        batch: plan.rays,
        seed,
        mesh_res: plan.mesh_resolution,
        ..ReconOptions::default()
    };
    let changes = match variant.split_once(':') {
        Some((_, assignments)) => assignments.replace(';', "\n"),
        None => match VARIANTS.iter().find(|(name, _)| *name == variant) {
            Some((_, changes)) => changes.to_string(),
            None => {
                let names: Vec<&str> = VARIANTS.iter().map(|(name, _)| *name).collect();
                panic!("unknown variant {variant} ({}, or NAME:FIELD=VALUE;...)", names.join(", "))
            }
        },
    };
    base.with_toml(&changes).unwrap_or_else(|e| panic!("variant {variant}: {e}"))
}

fn meshes() -> PathBuf {
    std::env::var_os("RMVP_MESHES")
        .map(PathBuf::from)
        .unwrap_or_else(|| Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/meshes"))
}

/// A scene to reconstruct: its set, its name, its folder and where its runs go.
struct Subject {
    set: &'static str,
    name: String,
    scene: PathBuf,
    runs: PathBuf,
}

/// The plan's scenes, set by set: the Mitsuba scenes as they are, ours simulated (once) into
/// `root/<WxH>`. Each is read when its turn comes.
fn subjects(plan: &Plan, root: &Path) -> Vec<Subject> {
    let wanted = |name: &str| plan.scenes.is_empty() || plan.scenes.iter().any(|s| s == name);
    let mut subjects = Vec::new();
    for set in &plan.sets {
        match set.as_str() {
            "mitsuba" => {
                let found = rmvp_testkit::mitsuba_scenes();
                assert!(!found.is_empty(), "no Mitsuba scenes: set RMVP_EVALSET and RMVP_FIXTURES");
                for dir in found {
                    let name = dir.file_name().expect("a folder name").to_string_lossy().to_string();
                    if wanted(&name) {
                        subjects.push(Subject {
                            set: "mitsuba",
                            runs: root.join("mitsuba").join(&name),
                            name,
                            scene: dir,
                        });
                    }
                }
            }
            "ours" => {
                let (w, h) = plan.size;
                let defaults = CaptureOptions::default();
                let folder = match plan.views {
                    n if n == defaults.views => format!("{w}x{h}"),
                    n => format!("{w}x{h}-{n}views"),
                };
                let capture = CaptureOptions { size: plan.size, views: plan.views, meshes: meshes(), ..defaults };
                for entry in SCENES.iter().filter(|s| wanted(s.name)) {
                    let dir = root.join(&folder).join(entry.name);
                    let dataset = dir.join("nersp");
                    if read_scene(&dataset).is_err() {
                        let _ = std::fs::remove_dir_all(&dir);
                        entry.simulate(&dir, &capture).unwrap_or_else(|e| panic!("simulating {}: {e}", entry.name));
                    }
                    subjects.push(Subject { set: "ours", name: entry.name.to_string(), scene: dataset, runs: dir });
                }
            }
            other => panic!("unknown set {other} (mitsuba, ours)"),
        }
    }
    assert!(!subjects.is_empty(), "no scene of the sets {:?} is named {:?}", plan.sets, plan.scenes);
    subjects
}

fn main() {
    if !std::env::args().any(|a| a == "--bench") {
        return; // run by `cargo test --all-targets` (no `--bench`): measure only under `cargo bench`
    }
    let plan = plan();
    // The commit, machine and date of the results: the checkout's as the run starts.
    let started = rmvp_testkit::results::BenchResult::now("", "");
    let root = Path::new(env!("CARGO_TARGET_TMPDIR")).join("bench-quality");
    let subjects = subjects(&plan, &root);
    println!(
        "| set | scene | variant | seed | iterations | minutes (train + outputs) | Chamfer | F-score | normal MAE train | held out | all |"
    );
    println!("| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |");
    let mut rows = Vec::new();
    for subject in &subjects {
        let name = &subject.name;
        let data = &read_scene(&subject.scene).unwrap_or_else(|e| panic!("{}: {e}", subject.scene.display()));
        std::fs::create_dir_all(&subject.runs).expect("bench folder");
        let log = subject.runs.parent().expect("a set folder").join("results.jsonl");
        let mut results = std::fs::OpenOptions::new().create(true).append(true).open(&log).expect("results log");
        let size = data.views.first().map_or((0, 0), |v| (v.camera.width, v.camera.height));
        for (variant, &seed) in plan.variants.iter().flat_map(|v| plan.seeds.iter().map(move |s| (v, s))) {
            let options = options(variant, &plan, seed);
            let variant_name = variant.split(':').next().unwrap_or(variant).to_string();
            let mut label = match plan.preset {
                Preset::Fast => variant_name,
                other => format!("{}-{variant_name}", serde_json::to_value(other).expect("a name")).replace('"', ""),
            };
            // Runs of other lengths or batches keep their own folders and rows.
            if let Some(n) = plan.iterations {
                label += &format!("-{n}it");
            }
            if let Some(n) = plan.rays {
                label += &format!("-{n}rays");
            }
            let out = subject.runs.join(format!("{label}-seed{seed}"));
            let _ = std::fs::remove_dir_all(&out);
            let run = Run {
                set: subject.set,
                scene: name,
                variant: &label,
                preset: plan.preset,
                size,
                views: data.views.iter().filter(|v| v.split == Split::Train).count(),
                seed,
            };
            let start = Instant::now();
            // Training time so far: the wall time less the time spent measuring the curve.
            let (mut trained, mut measuring) = (0.0, 0.0);
            let trainer = reconstruct(data, &out, &options, RunControl::default(), |_, trainer| {
                trained = start.elapsed().as_secs_f64() - measuring;
                if plan.curve.contains(&trainer.iteration) && trainer.iteration < trainer.config.iterations {
                    let at = out.join(format!("at-{}", trainer.iteration));
                    write_mesh(trainer, &at, &options).expect("mesh during training");
                    let seconds = start.elapsed().as_secs_f64() - measuring - trained;
                    let iteration = trainer.iteration;
                    measure(&mut results, &run, data, &at, iteration, (trained, seconds), plan.error_maps);
                    measuring = start.elapsed().as_secs_f64() - trained;
                }
                ControlFlow::Continue(())
            })
            .unwrap_or_else(|e| panic!("{name} {variant}: {e}"));
            let outputs = start.elapsed().as_secs_f64() - measuring - trained;
            let iterations = trainer.config.iterations;
            let seconds = (trained, outputs);
            rows.push(measure(&mut results, &run, data, &out, iterations, seconds, plan.error_maps));
        }
    }
    for (set, variant) in distinct(rows.iter().map(|r| (r.set, r.variant.as_str()))) {
        let of: Vec<&Row> = rows.iter().filter(|r| r.set == set && r.variant == variant).collect();
        println!(
            "| {set} | mean of {} | {variant} | | | {:.1} + {:.2} | {:.4} | {:.3} | {:.2} | {:.2} | {:.2} |",
            of.len(),
            mean(&of, |r| r.train_minutes),
            mean(&of, |r| r.output_minutes),
            mean(&of, |r| r.chamfer),
            mean(&of, |r| r.f_score),
            mean(&of, |r| r.normal_mae_train_deg),
            mean(&of, |r| r.normal_mae_held_out_deg),
            mean(&of, |r| r.normal_mae_deg)
        );
    }
    if plan.seeds.len() > 1 {
        print_spreads(&rows);
    }
    if plan.is_reference() {
        for set in distinct(rows.iter().map(|r| r.set)) {
            write_results(set, &rows, &started);
        }
    }
}

impl Plan {
    /// Whether the plan is the one `docs/benchmarks.md` states: the full model alone at seed 0
    /// with every default (its rows go into `bench/results/quality-SET.json`).
    fn is_reference(&self) -> bool {
        let defaults = ReconOptions::default();
        self.variants == ["full"]
            && self.seeds == [0]
            && self.preset == Preset::Fast
            && self.iterations.is_none()
            && self.rays.is_none()
            && self.size == (256, 256)
            && self.views == CaptureOptions::default().views
            && self.mesh_resolution == defaults.mesh_res
            && self.curve.is_empty()
    }
}

/// The columns of a set's results table.
const RESULT_COLUMNS: [&str; 7] = ["scene", "size", "Chamfer", "F-score", "normal MAE train", "held out", "all views"];

/// Write `bench/results/quality-SET.json` with `rows`' scenes of `set`, keeping the scenes of
/// an earlier run that this one did not reconstruct (a set is often run as two halves side by
/// side), in the set's order, and the mean normal error over them; its commit, machine and
/// date are `started`'s.
fn write_results(set: &str, rows: &[Row], started: &rmvp_testkit::results::BenchResult) {
    use rmvp_testkit::results::{BenchResult, Table};
    let name = format!("quality-{set}");
    let order: Vec<String> = match set {
        "mitsuba" => rmvp_testkit::mitsuba_scenes()
            .iter()
            .map(|d| d.file_name().expect("a folder name").to_string_lossy().to_string())
            .collect(),
        _ => SCENES.iter().map(|s| s.name.to_string()).collect(),
    };
    let earlier: Vec<Vec<String>> = BenchResult::read(&name)
        .and_then(|r| r.tables.into_iter().next())
        .filter(|t| t.columns == RESULT_COLUMNS)
        .map_or(Vec::new(), |t| t.rows);
    let mut result = BenchResult::now(
        &format!(
            "Reconstruction quality on {}",
            if set == "mitsuba" { "Mitsuba's renders" } else { "rmvp's own scenes" }
        ),
        &format!("cargo bench --bench quality -- --sets {set} --variants full"),
    );
    (result.commit, result.machine, result.date) =
        (started.commit.clone(), started.machine.clone(), started.date.clone());
    let mut table = Table::new(&RESULT_COLUMNS);
    let mut all_views = Vec::new();
    for scene in &order {
        let cells = match rows.iter().find(|r| r.set == set && &r.scene == scene) {
            Some(r) => vec![
                r.scene.clone(),
                r.size.clone(),
                format!("{:.4}", r.chamfer),
                format!("{:.3}", r.f_score),
                format!("{:.2}", r.normal_mae_train_deg),
                format!("{:.2}", r.normal_mae_held_out_deg),
                format!("{:.2}", r.normal_mae_deg),
            ],
            None => match earlier.iter().find(|cells| &cells[0] == scene) {
                Some(cells) => cells.clone(),
                None => continue,
            },
        };
        all_views.push(cells[6].parse::<f64>().expect("a normal error"));
        result.figure(scene, &cells[6]);
        table.row(cells);
    }
    let count = all_views.len();
    let mean = result.figure("mean", format!("{:.2}", all_views.iter().sum::<f64>() / count as f64));
    table.row(vec![format!("mean of {count}"), "".into(), "".into(), "".into(), "".into(), "".into(), mean.clone()]);
    result.headline = format!("mean normal error {mean} degrees on {count} scenes");
    result.about = match set {
        "mitsuba" => "Normal MAE is the mean angle, in degrees, between the reconstruction's normals and the true ones \
            over every pixel of every ground-truth view; Chamfer is in units of the unit sphere. The scenes of \
            `../shared/evalset` and `../shared/fixtures`, rendered by Mitsuba 3, an independent polarized renderer whose \
            materials rmvp's model does not match exactly (Mitsuba's `pplastic`, a 30 % gold blend on the teapot): \
            256x256 (the fixtures 128x128), 6 training and 4 held-out views (the fixtures 2), the fast preset's \
            defaults, seed 0, one thread a run (`RAYON_NUM_THREADS=1`), the two sets side by side. Over seeds: [`design.md`](design.md#coarse-to-fine)."
            .into(),
        _ => "The scenes of `rmvp_pipeline::evaluation_set`, whose reflectance model is the one the reconstruction \
            fits, rendered by `rmvp simulate` at 256x256 (6 training views, the ring's from the turntable's rings at \
            10 and 35 degrees, the others' from -20 to 70; 6 held-out views; 32 spp, the studio light), the fast \
            preset's defaults, seed 0, as the Mitsuba set. Bumps: fine bumps, rough and bright; knot: a trefoil tube \
            with narrow gaps, smooth and dark; gear: sixteen sharp teeth of gold; bowl: a deep concavity that the \
            masks do not show; spot: a smooth cow; bunny: the Stanford bunny, both of varying albedo and roughness; \
            float: a glossy ring seen only from above, where a blob can grow under it where no view sees \
            ([`design.md`](design.md#space-no-view-sees))."
            .into(),
    };
    result.tables = vec![table];
    result.write(&name);
}

/// `items` without repeats, in the order they first come.
fn distinct<T: PartialEq>(items: impl Iterator<Item = T>) -> Vec<T> {
    let mut kept = Vec::new();
    for item in items {
        if !kept.contains(&item) {
            kept.push(item);
        }
    }
    kept
}

/// The mean of figure `f` over `rows`.
fn mean(rows: &[&Row], f: fn(&Row) -> f64) -> f64 {
    rows.iter().map(|r| f(r)).sum::<f64>() / rows.len() as f64
}

/// The least and largest of `values`.
fn range(values: impl Iterator<Item = f64>) -> (f64, f64) {
    values.fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| (lo.min(v), hi.max(v)))
}

/// How the range `of` of a figure where lower is better stands against the range `base`:
/// worse or better beyond the seeds' spread where the two do not overlap.
fn against(of: (f64, f64), base: (f64, f64)) -> &'static str {
    if of.0 > base.1 {
        "worse"
    } else if of.1 < base.0 {
        "better"
    } else {
        "within"
    }
}

/// Each scene's and variant's normal error and Chamfer over the seeds (mean, least and
/// largest), each variant's ranges against the first variant's of the same scene.
fn print_spreads(rows: &[Row]) {
    println!();
    println!("| set | scene | variant | seeds | normal MAE mean | range | Chamfer mean | range | against the first variant (normal, Chamfer) |");
    println!("| --- | --- | --- | --- | --- | --- | --- | --- | --- |");
    let groups = distinct(rows.iter().map(|r| (r.set, r.scene.as_str(), r.variant.as_str())));
    let of = |set: &str, scene: &str, variant: &str| -> Vec<&Row> {
        rows.iter().filter(|r| r.set == set && r.scene == scene && r.variant == variant).collect()
    };
    for &(set, scene, variant) in &groups {
        let runs = of(set, scene, variant);
        let seeds: Vec<String> = runs.iter().map(|r| r.seed.to_string()).collect();
        let normal = range(runs.iter().map(|r| r.normal_mae_deg));
        let chamfer = range(runs.iter().map(|r| r.chamfer));
        let first = groups.iter().find(|g| g.0 == set && g.1 == scene).expect("its own group").2;
        let verdict = if first == variant {
            String::new()
        } else {
            let base = of(set, scene, first);
            let base_normal = range(base.iter().map(|r| r.normal_mae_deg));
            let base_chamfer = range(base.iter().map(|r| r.chamfer));
            format!("{}, {}", against(normal, base_normal), against(chamfer, base_chamfer))
        };
        println!(
            "| {set} | {scene} | {variant} | {} | {:.2} | {:.2}-{:.2} | {:.4} | {:.4}-{:.4} | {verdict} |",
            seeds.join(","),
            mean(&runs, |r| r.normal_mae_deg),
            normal.0,
            normal.1,
            mean(&runs, |r| r.chamfer),
            chamfer.0,
            chamfer.1,
        );
    }
}
