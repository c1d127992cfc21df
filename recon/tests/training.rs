//! Training behaviour: an analytic sphere converges, resume is bit-exact, non-finite values are
//! caught.

use nalgebra::Vector3;
use rmvp_dataset::rng::Rng;
use rmvp_dataset::{Scene, Split};
use rmvp_recon::checkpoint;
use rmvp_recon::data::TrainingSet;
use rmvp_recon::extract::{extract_mesh, CpuSdf};
use rmvp_recon::model::neus_initial_radius;
use rmvp_recon::occupancy::OccupancyGrid;
use rmvp_recon::options::{ReconOptions, RunControl};
use rmvp_recon::output::{render_view as render_outputs, SurfaceGuide};
use rmvp_recon::presets::{self, Preset};
use rmvp_recon::reconstruct::{reconstruct, write_mesh};
use rmvp_recon::samples::FieldSamples;
use rmvp_recon::step::{Batch, CpuStep, StepCompute};
use rmvp_recon::train::{StepEvent, TrainConfig, Trainer};
use rmvp_recon::volume::{sample_depths, Forward};
use rmvp_recon::Error;
use rmvp_render::pbrdf::{Interface, Lobes};
use rmvp_render::rig::{framing_distance, look_at, rig_intrinsics, Rig};
use rmvp_render::shapes::icosphere;
use rmvp_render::{geometry_maps, render_view, EnvMap, Object, Settings};
use std::ops::ControlFlow;

const RADIUS: f32 = 0.6;

/// The glossy sphere of radius 0.6.
fn sphere() -> Object {
    let mut mesh = icosphere(5);
    mesh.positions.iter_mut().for_each(|p| *p = p.map(|v| v * RADIUS));
    Object::new(&mesh, Interface::Dielectric(1.5), Lobes::Plastic).unwrap()
}

/// The glossy sphere seen by 6 cameras at 64x64 under the procedural environment.
fn sphere_scene() -> Scene {
    let object = sphere();
    let size = 64;
    let k = rig_intrinsics(size, size);
    let distance = framing_distance(&k, size, size, RADIUS as f64, 0.7);
    let mut scene = Scene::new();
    for (i, eye) in (Rig::Sphere { views: 6 }).eyes(distance, 3).into_iter().enumerate() {
        let camera = look_at(k, eye, Vector3::zeros(), Vector3::y(), size, size);
        let settings = Settings { spp: 8, seed: 1 + rmvp_testkit::test_seed() };
        let view = render_view(&object, &EnvMap::procedural(), &camera, settings, i as u32);
        scene.views.push(view.into_view(format!("{i:03}"), Split::Train, camera, 1.0));
    }
    scene
}

fn small_config(iterations: u32) -> TrainConfig {
    let mut config = presets::training(Preset::Fast, iterations);
    config.batch_rays = 256;
    config
}

/// The spot fixture's training set and a configuration of 64 rays a step without the
/// diffuse-only warm-up, for tests of one step's compute.
fn spot_steps(iterations: u32) -> (TrainConfig, TrainingSet) {
    let scene = rmvp_dataset::layout::read_scene(&rmvp_testkit::fixture("spot_nersp")).unwrap();
    let mut config = small_config(iterations);
    config.batch_rays = 64;
    config.diffuse_only = 0;
    let set = TrainingSet::from_scene(&scene, config.margin).unwrap();
    (config, set)
}

/// A trainer of `config` on `set` after 30 steps, its surface as sharp as after a few hundred
/// iterations, so that a step leaves most samples out.
fn sharpened(config: &TrainConfig, set: &TrainingSet) -> Trainer {
    let mut trainer = Trainer::new(config.clone(), set.clone());
    for _ in 0..30 {
        trainer.step();
    }
    let variance = trainer.model.variance;
    trainer.params[variance] = 200f32.ln() / rmvp_recon::model::VARIANCE_SCALE;
    trainer
}

/// A batch of the configured number of rays that `rng` draws from the training set's pool at
/// `trainer`'s iteration, read through `occupancy` (None: the field everywhere).
fn random_batch(trainer: &Trainer, rng: &mut Rng, use_geometric: bool, occupancy: Option<&OccupancyGrid>) -> Batch {
    let pool = &trainer.set.pool;
    let rays: Vec<(u32, u32)> =
        (0..trainer.config.batch_rays).map(|_| pool[rng.next_u32() as usize % pool.len()]).collect();
    let level_weight = trainer.level_weight();
    Batch {
        jitter: rays.iter().map(|_| rng.next_f32()).collect(),
        rays,
        fd_step: trainer.fd_step(&level_weight),
        curvature_share: trainer.curvature_share(&level_weight),
        level_weight,
        warm: false,
        use_geometric,
        occupancy: occupancy.cloned().map(std::sync::Arc::new),
        left_out_draws: Vec::new(),
        tangent_view_draws: Vec::new(),
    }
}

#[test]
fn analytic_sphere_converges_to_the_sphere() {
    let scene = sphere_scene();
    // From NeuS's start: the fast preset's smaller one needs more than 300 iterations to grow
    // out where no silhouette bounds the surface (after 300, 2.5 % of the vertices lie up to
    // 0.15 inside, on the sphere's underside).
    let mut config = small_config(300);
    config.model.initial_radius = neus_initial_radius();
    config.seed += rmvp_testkit::test_seed();
    let set = TrainingSet::from_scene(&scene, config.margin).unwrap();
    let mut trainer = Trainer::new(config, set);
    while trainer.iteration < trainer.config.iterations {
        let r = trainer.step();
        assert!(r.event.is_none(), "{r:?}");
    }
    let lw = trainer.level_weight();
    let sdf = CpuSdf::new(&trainer.model, &trainer.params, &lw);
    let mesh_at = |cells| extract_mesh(&sdf, cells, &trainer.set.frame, trainer.output_fd_step(&lw)).unwrap();
    let mesh = mesh_at(64);
    let radii: Vec<f32> = mesh.positions.iter().map(|p| (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt()).collect();
    let mean_error = radii.iter().map(|r| (r - RADIUS).abs()).sum::<f32>() / radii.len() as f32;
    let worst = radii.iter().map(|r| (r - RADIUS).abs()).fold(0.0, f32::max);
    println!("sphere: mean radial error {mean_error:.4}, worst {worst:.4}, {} vertices", radii.len());
    // The initial SDF is a blob of radius ~0.4 (mean error ~0.2); 300 iterations of 256 rays
    // on six 64x64 views bring it within a few percent of the radius.
    assert!(mean_error < 0.025, "mean radial error {mean_error}");
    assert!(worst < 0.15, "worst radial error {worst}");

    // Outputs, forward only where the surface is, found through the coarse mesh above: the
    // silhouette and normals of the learned surface as a finer extracted mesh, ray cast, has
    // them; and Stokes shaded at the surface as the full NeuS sampling renders them.
    let view = &scene.views[1];
    let guide = SurfaceGuide::new(&mesh, &trainer.set.frame, 64);
    let out = render_outputs(&trainer, &view.camera, &guide, true);
    let fine = mesh_at(160);
    let learned = Object::new(&fine, Interface::Dielectric(1.5), Lobes::Plastic).unwrap();
    let truth = geometry_maps(&learned, &view.camera);
    let (mut inter, mut union, mut angles) = (0, 0, Vec::new());
    for k in 0..truth.mask.data().len() {
        let (want, got) = (truth.mask.data()[k] > 127, out.mask.data()[k] > 127);
        inter += usize::from(want && got);
        union += usize::from(want || got);
        if want && got {
            let (a, b) = (&truth.normals.data()[3 * k..3 * k + 3], &out.normals.data()[3 * k..3 * k + 3]);
            angles.push((a[0] * b[0] + a[1] * b[1] + a[2] * b[2]).clamp(-1.0, 1.0).acos().to_degrees());
        }
    }
    angles.sort_by(f32::total_cmp);
    let (iou, median) = (inter as f32 / union as f32, angles[angles.len() / 2]);
    println!("outputs: silhouette IoU {iou:.3}, normal median error {median:.2} deg over {} pixels", angles.len());
    assert!(iou > 0.98 && median < 2.0, "IoU {iou}, median {median} deg");
    let hits: Vec<usize> = (0..out.mask.data().len()).filter(|&k| out.mask.data()[k] > 127).collect();
    let frame = &trainer.set.frame;
    let w = view.camera.width;
    let rays: Vec<_> =
        hits.iter().map(|&k| frame.pixel_ray(&view.camera, k as u32 % w, k as u32 / w).unwrap()).collect();

    // The normal maps are the field's gradient over the outputs' step, not the training's: at
    // each pixel's own zero crossing (found here by bisection), the rendered normal is the one
    // at the outputs' step to within the secant's placement, and stands apart from the one at
    // the training step by the finest cells' ripple.
    let (model, params) = (&trainer.model, &trainer.params);
    let sdf_at = |points: &[f32]| model.field.sdf(params, points, &lw);
    // A pixel at the rim may be in the mask by a ray that grazes the surface without crossing
    // it; those are left out, and they are few.
    let (crossed, crossings): (Vec<usize>, Vec<[f32; 3]>) = rays
        .iter()
        .zip(&hits)
        .filter_map(|(ray, &k)| {
            let steps = 512;
            let t = |i: usize| ray.near + (ray.far - ray.near) * i as f32 / steps as f32;
            let along: Vec<f32> = (0..=steps).flat_map(|i| ray.at(t(i))).collect();
            let first = sdf_at(&along).windows(2).position(|s| s[0] > 0.0 && s[1] <= 0.0)?;
            let (mut a, mut b) = (t(first), t(first + 1));
            for _ in 0..30 {
                let mid = 0.5 * (a + b);
                if sdf_at(&ray.at(mid))[0] > 0.0 {
                    a = mid;
                } else {
                    b = mid;
                }
            }
            Some((k, ray.at(0.5 * (a + b))))
        })
        .unzip();
    assert!(crossed.len() * 100 >= hits.len() * 99, "{} of {} pixels cross the surface", crossed.len(), hits.len());
    let crossings: Vec<f32> = crossings.into_iter().flatten().collect();
    let median_angle_to = |step: f32| {
        let field = FieldSamples::infer(model, params, &lw, crossings.clone(), step);
        let mut angles: Vec<f32> = crossed
            .iter()
            .zip(field.normals.chunks_exact(3))
            .map(|(&k, n)| {
                let world = frame.dir_to_world([n[0], n[1], n[2]]);
                let r = &out.normals.data()[3 * k..3 * k + 3];
                let cos = world.x * r[0] as f64 + world.y * r[1] as f64 + world.z * r[2] as f64;
                cos.clamp(-1.0, 1.0).acos().to_degrees() as f32
            })
            .collect();
        angles.sort_by(f32::total_cmp);
        angles[angles.len() / 2]
    };
    let (output_step, training_step) = (trainer.output_fd_step(&lw), trainer.fd_step(&lw));
    let (to_output, to_training) = (median_angle_to(output_step), median_angle_to(training_step));
    println!("normal maps: median {to_output:.3} deg from the outputs' step's normals, {to_training:.3} from the training step's");
    assert!(output_step > training_step && to_output < 0.5 * to_training, "{to_output} against {to_training} deg");
    // The written mesh's vertex normals too.
    let options = ReconOptions { mesh_res: 64, ..ReconOptions::default() };
    let dir = tempfile::tempdir().unwrap();
    let written = write_mesh(&trainer, dir.path(), &options).unwrap();
    assert!(written.positions == mesh.positions && written.normals == mesh.normals);
    let at_training_step = extract_mesh(&sdf, 64, frame, training_step).unwrap();
    assert!(at_training_step.normals != mesh.normals);
    let surface = out.stokes.as_ref().unwrap();
    let config = &trainer.config;
    let depths = sample_depths(model, params, &lw, &rays, config.sampling, &vec![0.5; rays.len()]);
    let full = Forward::run(model, params, &lw, &rays, &depths, trainer.fd_step(&lw), false);
    let mut differences: Vec<f32> = hits
        .iter()
        .zip(&full.rays)
        .map(|(&k, o)| {
            let want = o.stokes[1] / o.opacity / trainer.set.stokes_scale;
            (surface.s0.data()[3 * k + 1] - want).abs() / want.abs().max(1e-3)
        })
        .collect();
    differences.sort_by(f32::total_cmp);
    let median = differences[differences.len() / 2];
    println!(
        "surface shading against full sampling: S0 median relative difference {median:.4} over {} pixels",
        hits.len()
    );
    assert!(median < 0.04, "{median}");
}

#[test]
fn resume_continues_bit_for_bit() {
    let scene = rmvp_dataset::layout::read_scene(&rmvp_testkit::fixture("spot_nersp")).unwrap();
    let mut config = small_config(40);
    config.batch_rays = 64;
    config.diffuse_only = 19; // cross the warm-up boundary between stop and resume
    config.tangent_views = 4; // of the six views: each ray's sample drawn
    config.sampling.regularised_left_out = 2; // draws behind what each ray renders
    assert!(config.sampling.regularise_near_surface > 0.0, "the samples left out near the surface regularised");
    assert!(config.sampling.skips_empty_space() && rmvp_recon::occupancy::REFRESH_EVERY == 16);
    let set = TrainingSet::from_scene(&scene, config.margin).unwrap();
    // On one thread here, on two below: the same steps whatever the number of threads.
    let mut straight = Trainer::new(config.clone(), set.clone());
    let reports: Vec<_> = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap()
        .install(|| (0..22).map(|_| straight.step()).collect());
    assert!(reports.iter().all(|r| r.rays == 64 && r.event.is_none()), "every step renders the batch's rays");
    let pool = rayon::ThreadPoolBuilder::new().num_threads(2).build().unwrap();
    let mut first = Trainer::new(config.clone(), set.clone());
    // Stopped after the occupancy grid's refresh at 16, before the next.
    pool.install(|| {
        for _ in 0..18 {
            first.step();
        }
    });
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("checkpoint.bin");
    checkpoint::save(&first, None, &path).unwrap();
    drop(first);
    let mut resumed = checkpoint::load(&path, set.clone(), &config, None).unwrap();
    assert_eq!(resumed.iteration, 18);
    pool.install(|| {
        for _ in 0..4 {
            resumed.step();
        }
    });
    assert_eq!(resumed.iteration, straight.iteration);
    assert!(resumed.params == straight.params, "parameters differ after resume");
    assert!(resumed.adam == straight.adam, "optimiser state differs after resume");

    // A run of another configuration is refused before a model is built from the header.
    let mut other = config.clone();
    other.batch_rays += 1;
    let err = checkpoint::load(&path, set.clone(), &other, None).err().expect("another configuration");
    assert!(matches!(err, Error::CheckpointSettings { .. }), "{err}");

    // One whose recorded options set an option this version removed is refused, saying so;
    // the same option left unset (as an earlier version wrote every option) is passed over.
    let bytes = std::fs::read(&path).unwrap();
    let header_len = u64::from_le_bytes(bytes[8..16].try_into().unwrap()) as usize;
    let with_options = |options: serde_json::Value| {
        let mut header: serde_json::Value = serde_json::from_slice(&bytes[16..16 + header_len]).unwrap();
        header["options"] = options;
        let header = serde_json::to_vec(&header).unwrap();
        let mut edited = bytes[..8].to_vec();
        edited.extend_from_slice(&(header.len() as u64).to_le_bytes());
        edited.extend_from_slice(&header);
        edited.extend_from_slice(&bytes[16 + header_len..]);
        std::fs::write(&path, &edited).unwrap();
    };
    let mut options = serde_json::to_value(ReconOptions::default()).unwrap();
    options["regularise_inside_every"] = serde_json::Value::Null;
    with_options(options.clone());
    assert_eq!(checkpoint::recorded_options(&path).unwrap(), Some(ReconOptions::default()));
    options["regularise_inside_every"] = serde_json::json!(4);
    with_options(options);
    let err = checkpoint::recorded_options(&path).expect_err("a removed option refused");
    let message = err.to_string();
    assert!(matches!(&err, Error::BadCheckpoint { .. }), "{err}");
    assert!(
        message.contains("`regularise_inside_every` was removed") && message.contains("checkpoint.bin"),
        "{message}"
    );

    // One of another format (an older layout of the parameters) is refused, saying so.
    let name = b"rmvp-recon-checkpoint-";
    let at = bytes.windows(name.len()).position(|w| w == name).expect("format in the header") + name.len();
    let mut older = bytes.clone();
    older[at] = b'1';
    std::fs::write(&path, &older).unwrap();
    let err = checkpoint::load(&path, set.clone(), &config, None).err().expect("older format refused");
    assert!(err.to_string().contains("format rmvp-recon-checkpoint-1"), "{err}");

    // A truncated checkpoint is refused with the file's name.
    std::fs::write(&path, &bytes[..bytes.len() - 10]).unwrap();
    let err = checkpoint::load(&path, set, &config, None).err().expect("truncated checkpoint refused");
    assert!(matches!(&err, Error::BadCheckpoint { path: p, problem } if *p == path && problem.contains("truncated")));
    assert!(err.to_string().contains("checkpoint.bin"), "{err}");
}

#[test]
fn non_finite_steps_are_skipped_then_rolled_back() {
    let scene = rmvp_dataset::layout::read_scene(&rmvp_testkit::fixture("spot_nersp")).unwrap();
    let mut config = small_config(20);
    config.batch_rays = 32;
    let set = TrainingSet::from_scene(&scene, config.margin).unwrap();
    let mut trainer = Trainer::new(config, set);
    trainer.step();
    let good = trainer.params.clone();
    let variance = trainer.model.variance;
    trainer.params[variance] = f32::NAN;
    for k in 0..2 {
        let r = trainer.step();
        assert_eq!(r.event, Some(StepEvent::Skipped), "step {k}: {r:?}");
    }
    let r = trainer.step();
    assert_eq!(r.event, Some(StepEvent::RolledBack { to: 0 }), "{r:?}");
    assert!(trainer.params.iter().all(|p| p.is_finite()));
    // Rolled back to the last safe state: the initial parameters, before the first good step.
    assert!(trainer.params != good);
    let r = trainer.step();
    assert!(r.event.is_none() && r.loss.is_finite(), "{r:?}");
}

#[test]
fn unusable_inputs_are_refused_by_kind() {
    let mut scene = rmvp_dataset::layout::read_scene(&rmvp_testkit::fixture("spot_nersp")).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let both_off = ReconOptions { no_photometric: true, no_geometric: true, ..ReconOptions::default() };
    assert!(matches!(
        reconstruct(&scene, dir.path(), &both_off, RunControl::default(), |_, _| ControlFlow::Continue(())),
        Err(Error::BothCuesOff)
    ));
    scene.views[1].mask = None;
    let err = TrainingSet::from_scene(&scene, 8).err().unwrap();
    assert!(matches!(&err, Error::MissingInput { view, what: "mask" } if view == "001"), "{err}");
    scene.views[1].mask = scene.views[0].mask.clone();
    scene.views[2].stokes.as_mut().unwrap().s1.data_mut()[7] = f32::NAN;
    let err = TrainingSet::from_scene(&scene, 8).err().unwrap();
    assert!(matches!(&err, Error::NonFiniteInput { view, x: 2, y: 0, channel: 1 } if view == "002"), "{err}");
    scene.views.iter_mut().for_each(|v| v.split = Split::Eval);
    assert!(matches!(TrainingSet::from_scene(&scene, 8), Err(Error::NoTrainingViews)));
}

#[test]
fn without_the_photometric_cue_the_tangent_loss_takes_each_aop_as_measured() {
    // The lobe's tilt is read from the specular network, which only the photometric cue fits:
    // a geometric-only run with the tilt asked for trains exactly as one without it.
    let scene = rmvp_dataset::layout::read_scene(&rmvp_testkit::fixture("spot_nersp")).unwrap();
    let run = |tilt: bool| {
        let mut config = small_config(20);
        config.batch_rays = 32;
        config.photometric = false;
        config.model.specular_tilt = tilt;
        let set = TrainingSet::from_scene(&scene, config.margin).unwrap();
        let mut trainer = Trainer::new(config, set);
        for _ in 0..6 {
            trainer.step();
        }
        assert!(trainer.iteration > trainer.config.diffuse_only, "the geometric loss has started");
        trainer.params
    };
    assert!(run(true) == run(false), "the untrained specular network turned the AoPs");
}

#[test]
fn the_curvature_term_sees_the_unseen_space_a_step_leaves_out_as_if_each_sample_were_rendered() {
    use rmvp_recon::losses::{curvature, Term};
    use rmvp_recon::samples::FieldSamples;
    use rmvp_recon::step::REGULARISED_CLEARANCE;
    use rmvp_recon::volume::weighted_samples;
    let (mut config, set) = spot_steps(200);
    config.sampling.regularised_left_out = 2;
    let trainer = sharpened(&config, &set);
    // Without the occupancy grid the steps and the reference below take the same depths.
    let mut rng = Rng::for_pixel(7 + rmvp_testkit::test_seed(), 0, 0);
    let mut batch = random_batch(&trainer, &mut rng, false, None);
    let (model, params) = (&trainer.model, &trainer.params);
    let mut grad = vec![0f32; params.len()];
    // The reference: the rendered samples' term (a step without draws) and, over every sample
    // left out behind the last one its ray renders and outside the surface by the clearance,
    // each sample's own, all normalised by the samples a step takes rendering every one.
    let rendered_only = CpuStep.gradient(model, params, &set, &config, &batch, &mut grad);
    let rays: Vec<_> = batch.rays.iter().map(|&(v, p)| set.ray(v, p)).collect();
    let samples = weighted_samples(model, params, &batch.level_weight, &rays, config.sampling, &batch.jitter, None);
    let mut unseen = Vec::new();
    for (ray, (rendered, left_out)) in rays.iter().zip(samples.rendered.iter().zip(&samples.left_out)) {
        if let Some(&last) = rendered.last() {
            left_out.iter().filter(|&&d| d > last).for_each(|&d| unseen.extend(ray.at(d)));
        }
    }
    let field = FieldSamples::evaluate(model, params, &batch.level_weight, unseen, batch.fd_step);
    let every_samples = (batch.rays.len() * (config.sampling.coarse + config.sampling.fine)) as f64;
    let rendered_curvature = rendered_only.losses[Term::Curvature];
    let (mut truth, mut outside, mut inside) = (rendered_curvature, 0, 0);
    for (&sdf, &laplacian) in field.sdf.iter().zip(&field.laplacians) {
        if sdf >= REGULARISED_CLEARANCE {
            truth += curvature(laplacian).0 as f64 / every_samples;
            outside += 1;
        } else if sdf <= -REGULARISED_CLEARANCE {
            inside += 1;
        }
    }
    let total = field.sdf.len();
    assert!(outside > total / 4 && inside > total / 20, "of {total} unseen samples {outside} outside, {inside} inside");
    let draws = 200;
    let mut estimates = Vec::new();
    let mut taken = 0;
    for _ in 0..draws {
        batch.left_out_draws = (0..2 * batch.rays.len()).map(|_| rng.next_f32()).collect();
        let weighted = CpuStep.gradient(model, params, &set, &config, &batch, &mut grad);
        taken = weighted.samples;
        // The Eikonal term stays the rendered samples' own.
        assert_eq!(weighted.losses[Term::Eikonal], rendered_only.losses[Term::Eikonal]);
        estimates.push(weighted.losses[Term::Curvature]);
    }
    assert!((taken as f64) < every_samples / 3.0, "{taken} of {every_samples} samples rendered");
    let mean = estimates.iter().sum::<f64>() / draws as f64;
    let spread = (estimates.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (draws - 1) as f64).sqrt();
    let standard_error = spread / (draws as f64).sqrt();
    let (drawn, unseen_truth) = (mean - rendered_curvature, truth - rendered_curvature);
    println!("curvature: reference {truth:.5} (unseen {unseen_truth:.5}), with draws {mean:.5} +- {standard_error:.5} (one step's spread {spread:.5})");
    // The estimate is unbiased, the unseen samples' part is a real share of the value, and a
    // step's own spread is a fraction of it.
    assert!((mean - truth).abs() < 4.0 * standard_error, "{mean} against {truth}");
    assert!(drawn > 0.1 * truth && unseen_truth > 0.1 * truth, "{drawn} of {truth}");
    assert!(spread < 0.5 * truth, "spread {spread} of {truth}");
}

#[test]
fn the_regularisers_see_every_sample_a_step_leaves_near_the_surface_as_if_it_were_rendered() {
    use rmvp_recon::losses::{curvature, eikonal, Term};
    use rmvp_recon::volume::{weighted_samples, Sampling};
    let (mut config, set) = spot_steps(200);
    config.sampling.regularised_left_out = 0;
    let near = config.sampling.regularise_near_surface;
    assert!(near > 0.0, "the fast preset regularises the samples near the surface");
    let trainer = sharpened(&config, &set);
    let mut rng = Rng::for_pixel(11 + rmvp_testkit::test_seed(), 0, 0);
    let batch = random_batch(&trainer, &mut rng, false, None);
    let (model, params) = (&trainer.model, &trainer.params);
    let step = |sampling: Sampling| {
        let config = TrainConfig { sampling, ..config.clone() };
        let mut grad = vec![0f32; params.len()];
        CpuStep.gradient(model, params, &set, &config, &batch, &mut grad).losses
    };
    let with = |distance: f32| step(Sampling { regularise_near_surface: distance, ..config.sampling });
    // The reference: the rendered samples' terms and each left-out sample's own within the
    // distance, by the SDF the sampling found, normalised as rendering every sample does.
    let rendered_only = with(0.0);
    let rays: Vec<_> = batch.rays.iter().map(|&(v, p)| set.ray(v, p)).collect();
    let samples = weighted_samples(model, params, &batch.level_weight, &rays, config.sampling, &batch.jitter, None);
    let mut points = Vec::new();
    for ((ray, depths), sdf) in rays.iter().zip(&samples.left_out).zip(&samples.left_out_sdf) {
        for (&depth, &sdf) in depths.iter().zip(sdf) {
            if sdf.abs() < near {
                points.extend(ray.at(depth));
            }
        }
    }
    let field = FieldSamples::evaluate(model, params, &batch.level_weight, points, batch.fd_step);
    let left_out: usize = samples.left_out.iter().map(Vec::len).sum();
    println!("{} of {left_out} samples left out lie within {near} of the surface", field.len());
    assert!(field.len() > 50 && field.len() < left_out, "{} of {left_out}", field.len());
    let every_samples = (batch.rays.len() * (config.sampling.coarse + config.sampling.fine)) as f64;
    let mut truth = rendered_only;
    for (i, &laplacian) in field.laplacians.iter().enumerate() {
        let g = &field.gradients[3 * i..3 * i + 3];
        truth[Term::Eikonal] += eikonal([g[0], g[1], g[2]]).0 as f64 / every_samples;
        truth[Term::Curvature] += curvature(laplacian).0 as f64 / every_samples;
    }
    let regularised = with(near);
    // Every sample left out near the surface or none: the terms of every sample rendered.
    let everywhere = with(f32::INFINITY);
    let every_rendered = step(Sampling { min_weight: 0.0, ..config.sampling });
    for term in [Term::Eikonal, Term::Curvature] {
        let (value, truth, rendered) = (regularised[term], truth[term], rendered_only[term]);
        println!("{term:?}: near the surface {value:.5}, reference {truth:.5}, the rendered samples' {rendered:.5}");
        assert!((value - truth).abs() < 1e-4 * truth, "{term:?}: {value} against {truth}");
        assert!(truth - rendered > 0.02 * truth, "{term:?}: the samples near the surface are a real share of it");
        let (all, reference) = (everywhere[term], every_rendered[term]);
        println!("{term:?}: every sample left out {all:.5}, every sample rendered {reference:.5}");
        assert!((all - reference).abs() < 1e-4 * reference, "{term:?}: {all} against {reference}");
    }
    assert_eq!(regularised[Term::Mask], rendered_only[Term::Mask], "the rendering is the same");
}

#[test]
fn a_step_writes_its_whole_gradient_over_the_buffer_it_is_given() {
    let (config, set) = spot_steps(100);
    let trainer = Trainer::new(config.clone(), set.clone());
    // At the start the finer levels are off: their tables' gradients are zeros to be written too.
    let level_weight = trainer.level_weight();
    assert!(level_weight.contains(&0.0) && level_weight.contains(&1.0), "{level_weight:?}");
    let mut rng = Rng::for_pixel(11 + rmvp_testkit::test_seed(), 0, 0);
    let batch = random_batch(&trainer, &mut rng, true, trainer.occupancy());
    let (model, params) = (&trainer.model, &trainer.params);
    let mut fresh = vec![0f32; params.len()];
    CpuStep.gradient(model, params, &set, &config, &batch, &mut fresh);
    // A buffer that still holds another step's numbers: here NaN everywhere.
    let mut reused = vec![f32::NAN; params.len()];
    CpuStep.gradient(model, params, &set, &config, &batch, &mut reused);
    assert!(fresh.iter().any(|&g| g != 0.0));
    let differ = fresh.iter().zip(&reused).filter(|(a, b)| a.to_bits() != b.to_bits()).count();
    assert_eq!(differ, 0, "{differ} of {} entries differ", params.len());
}

#[test]
fn the_tangent_loss_over_a_sample_of_the_views_estimates_its_mean_over_every_view() {
    use rmvp_recon::geometric::{tangent_loss, tangents, ViewSample};
    let (config, set) = spot_steps(10);
    let trainer = Trainer::new(config, set);
    let level_weight = trainer.level_weight();
    // Points on the initial sphere, facing the views from several sides.
    let radius = presets::FAST_INITIAL_RADIUS;
    let normals: Vec<[f32; 3]> = (0..64)
        .map(|i| {
            let (a, z) = (i as f32 * 0.9, (i as f32 * 0.37).sin() * 0.8);
            let r = (1.0 - z * z).sqrt();
            [r * a.cos(), z, r * a.sin()]
        })
        .collect();
    let points: Vec<[f32; 3]> = normals.iter().map(|n| n.map(|x| x * radius)).collect();
    let every = |sample: Option<ViewSample<'_>>| {
        tangents(&trainer.set, &trainer.model, &trainer.params, &level_weight, &points, &normals, false, sample)
    };
    let all = every(None);
    let (views, offsets) = (2, 512);
    let mut sums = vec![(0f64, [0f64; 3]); points.len()];
    // The sample is drawn before the occlusion test: where a view that faces a point is
    // occluded, a sample may keep fewer views (a ratio estimate); the points without one are
    // compared exactly.
    let mut whole = vec![true; points.len()];
    for k in 0..offsets {
        let u = vec![(k as f32 + 0.5) / offsets as f32; points.len()];
        for (i, at) in every(Some(ViewSample { views, offsets: &u })).iter().enumerate() {
            assert!(at.views.len() <= views, "point {i}: {} views", at.views.len());
            whole[i] &= at.views.len() == all[i].views.len().min(views);
            let (loss, d) = tangent_loss(normals[i], &at.views, true, 0.0);
            sums[i].0 += loss as f64 / offsets as f64;
            (0..3).for_each(|c| sums[i].1[c] += d[c] as f64 / offsets as f64);
        }
    }
    let sampled = (0..points.len()).filter(|&i| whole[i] && all[i].views.len() > views).count();
    assert!(sampled >= 6, "{sampled} of the points face more than {views} views, none occluded");
    for (i, at) in all.iter().enumerate().filter(|(i, _)| whole[*i]) {
        let (loss, d) = tangent_loss(normals[i], &at.views, true, 0.0);
        let scale = loss.abs().max(1e-4) as f64;
        assert!((sums[i].0 - loss as f64).abs() < 0.01 * scale, "point {i}: {} vs {loss}", sums[i].0);
        let (len, off) = (
            d.iter().map(|x| x * x).sum::<f32>().sqrt() as f64,
            (0..3).map(|c| (sums[i].1[c] - d[c] as f64).powi(2)).sum::<f64>().sqrt(),
        );
        assert!(off < 0.01 * len.max(1e-4), "point {i}: gradient off by {off} of {len}");
    }
}

#[test]
fn the_fast_presets_curvature_weight_ramps_up_then_falls_as_the_grids_levels_open() {
    let scene = rmvp_dataset::layout::read_scene(&rmvp_testkit::fixture("spot_nersp")).unwrap();
    let config = presets::training(Preset::Fast, Preset::Fast.default_iterations());
    assert!(config.curvature_follows_levels);
    let set = TrainingSet::from_scene(&scene, config.margin).unwrap();
    let mut trainer = Trainer::new(config.clone(), set.clone());
    let mut share_at = |iteration: u32| {
        trainer.iteration = iteration;
        let level_weight = trainer.level_weight();
        (trainer.curvature_share(&level_weight), trainer.model.field.finest_active(&level_weight).unwrap() as f32)
    };
    let (warmup, every) = (config.adam.warmup, config.anneal_every);
    assert!(warmup > 0 && warmup < every, "the warm-up ends before the first level opens");
    // From 0 over the learning rate's warm-up, then the full weight while the start's levels
    // alone are open.
    assert_eq!(share_at(0).0, 0.0);
    assert!((share_at(warmup / 2).0 - (warmup / 2) as f32 / warmup as f32).abs() < 1e-6);
    let (full, start_cells) = share_at(warmup);
    assert_eq!(full, 1.0);
    assert_eq!(share_at(every - 1).0, 1.0);
    // Each level that opens: the start's finest cell over the finest open one.
    let mut last = 1.0;
    for opened in 1..=4 {
        let (share, cells) = share_at(opened * every);
        let want = (start_cells / cells).powf(presets::FAST_CURVATURE_CELL_POWER);
        assert!(cells > start_cells && (share - want).abs() < 1e-6, "{share} at {cells} cells");
        assert!(share < last, "falls as each level opens: {share} after {last}");
        last = share;
    }
    // All eight open (16 to 256 cells): about a seventh of the start's weight to the end.
    let (end, cells) = share_at(config.iterations - 1);
    assert_eq!(cells, 256.0);
    assert!((0.13..0.145).contains(&end) && end == last, "{end}");
    // The other presets keep their weight throughout.
    for preset in [Preset::Dense, Preset::Paper] {
        let config = presets::training(preset, 3000);
        let mut trainer = Trainer::new(config, set.clone());
        for iteration in [0, 100, 2999] {
            trainer.iteration = iteration;
            assert_eq!(trainer.curvature_share(&trainer.level_weight()), 1.0, "{preset:?} at {iteration}");
        }
    }
}

#[test]
fn a_steps_curvature_gradient_is_its_share_of_the_weight() {
    use rmvp_recon::losses::Term;
    use rmvp_recon::train::LossWeights;
    let (mut config, set) = spot_steps(200);
    // The curvature term alone, on the samples rendered and those regularised near the surface.
    config.weights = LossWeights::from_fn(|term| if term == Term::Curvature { 0.01 } else { 0.0 });
    let trainer = sharpened(&config, &set);
    let mut rng = Rng::for_pixel(13 + rmvp_testkit::test_seed(), 0, 0);
    let mut batch = random_batch(&trainer, &mut rng, false, None);
    let (model, params) = (&trainer.model, &trainer.params);
    let mut gradient = |share: f32| {
        batch.curvature_share = share;
        let mut grad = vec![0f32; params.len()];
        let losses = CpuStep.gradient(model, params, &set, &config, &batch, &mut grad).losses;
        (losses, grad)
    };
    let (losses, whole) = gradient(1.0);
    let (quarter_losses, quarter) = gradient(0.25);
    assert_eq!(losses[Term::Curvature], quarter_losses[Term::Curvature], "the losses are unweighted");
    let scale = whole.iter().fold(0f32, |m, g| m.max(g.abs()));
    assert!(scale > 0.0);
    let worst = whole.iter().zip(&quarter).map(|(w, q)| (q - 0.25 * w).abs()).fold(0f32, f32::max);
    assert!(worst <= 1e-6 * scale, "{worst} of {scale}");
}
