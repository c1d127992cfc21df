//! Every reconstruction option is one field of `ReconOptions`, accepted under the same name by
//! `rmvp recon` (its flag), a batch plan (a variant's `options`) and the quality bench (its
//! TOML variants), and recorded in the checkpoint: a field added without reaching one of them
//! fails here.

use clap::Parser;
use rmvp_pipeline::batch::plan::BatchPlan;
use rmvp_recon::checkpoint::recorded_options;
use rmvp_recon::options::{ReconOptions, RunControl, REMOVED_OPTIONS};
use rmvp_recon::reconstruct::{reconstruct, CHECKPOINT};
use std::ops::ControlFlow;

mod common;
use common::{ok, s};

/// `rmvp recon`'s options alone, as the command flattens them.
#[derive(Parser)]
struct Flags {
    #[command(flatten)]
    options: ReconOptions,
}

/// A value other than the default for each field, as a flag's argument and as TOML. A field
/// without one here fails the test: give it one.
fn changed(field: &str) -> (&'static str, &'static str) {
    match field {
        "preset" => ("dense", "\"dense\""),
        "iters" => ("3", "3"),
        "no_geometric" | "no_photometric" | "mesh_only" | "keep_unseen_parts" => ("", "true"),
        "batch" => ("48", "48"),
        "coarse_samples" => ("20", "20"),
        "fine_samples" => ("12", "12"),
        "min_sample_weight" => ("0.001", "0.001"),
        "margin" => ("5", "5"),
        "tangent_robust_angle" => ("10", "10.0"),
        "tangent_views" => ("6", "6"),
        "curvature_weight" => ("0.02", "0.02"),
        "initial_radius" => ("0.3", "0.3"),
        "learned_polarization" | "diffuse_transmission" | "tangent_azimuth_only" | "specular_tilt" => ("true", "true"),
        "downscale" => ("2", "2"),
        "seed" => ("7", "7"),
        "mesh_res" => ("40", "40"),
        "mesh_device" => ("cuda", "\"cuda\""),
        "checkpoint_every" => ("9", "9"),
        other => panic!("no test value for the option {other}: add one to `changed`"),
    }
}

fn fields() -> Vec<String> {
    let serde_json::Value::Object(map) = serde_json::to_value(ReconOptions::default()).unwrap() else { panic!() };
    // Options without a default value serialise as null: all fields are there.
    map.keys().cloned().collect()
}

#[test]
fn every_option_has_one_name_on_the_command_line_in_plans_in_the_bench_and_in_the_checkpoint() {
    let help = ok(&["recon", "--help"]);
    let tmp = tempfile::tempdir().unwrap();
    let scene = tmp.path().join("spot");
    rmvp_testkit::copy_tree(&rmvp_testkit::fixture("spot_nersp"), &scene);
    let data = rmvp_dataset::layout::read_scene(&scene).unwrap();
    let fields = fields();
    assert!(fields.len() >= 16, "{fields:?}");
    for field in &fields {
        let (argument, toml) = changed(field);
        let flag = format!("--{}", field.replace('_', "-"));
        assert!(help.contains(&format!("{flag} ")) || help.contains(&format!("{flag}\n")), "rmvp recon has no {flag}");

        // The command line.
        let mut args = vec!["recon", flag.as_str()];
        if !argument.is_empty() {
            args.push(argument);
        }
        let from_flags = Flags::try_parse_from(&args).unwrap_or_else(|e| panic!("{flag}: {e}")).options;
        assert_ne!(from_flags, ReconOptions::default(), "{flag} {argument} changed nothing");

        // The bench's TOML variants.
        let from_toml = ReconOptions::default().with_toml(&format!("{field} = {toml}")).unwrap();
        assert_eq!(from_toml, from_flags, "{field}");

        // A batch plan's variant (its seeds are the plan's).
        let plan = tmp.path().join("batch.toml");
        let seeds = if field == "seed" { format!("seeds = [{argument}]\n") } else { String::new() };
        let options = if field == "seed" { String::new() } else { format!("options = {{ {field} = {toml} }}\n") };
        std::fs::write(
            &plan,
            format!(
                "datasets = [\"spot\"]\n{seeds}[evaluation]\nenabled = false\n[[variant]]\nname = \"v\"\n{options}"
            ),
        )
        .unwrap();
        let plan = BatchPlan::read(&plan).unwrap_or_else(|e| panic!("{field}: {e}"));
        assert_eq!(plan.tasks[0].variant.recon_options(plan.tasks[0].seed), from_flags, "{field}");

        // The checkpoint, after one iteration of 32 rays (a GPU for the mesh is asked for
        // before training: that field's run keeps the CPU).
        let out = tmp.path().join(format!("run-{field}"));
        let control = RunControl { resume: false, stop_after: Some(1) };
        let mut options = from_flags.clone();
        if field != "batch" {
            options.batch = Some(32);
        }
        if field == "mesh_device" {
            options.mesh_device = ReconOptions::default().mesh_device;
        }
        let trained = reconstruct(&data, &out, &options, control, |_, _| ControlFlow::Continue(()));
        trained.unwrap_or_else(|e| panic!("{field}: {e}"));
        assert_eq!(recorded_options(&out.join(CHECKPOINT)).unwrap(), Some(options), "{field}");
    }
}

#[test]
fn resuming_with_other_options_names_them_and_the_mesh_options_may_change() {
    let tmp = tempfile::tempdir().unwrap();
    let scene = rmvp_testkit::fixture("spot_nersp");
    let out = tmp.path().join("out");
    let run = |extra: &[&str], expect: fn(&[&str]) -> String| {
        let mut args = vec!["recon", s(&scene), "-o", s(&out), "--iters", "4", "--batch", "32", "--stop-after", "2"];
        args.extend_from_slice(extra);
        expect(&args)
    };
    run(&[], ok);
    let err = run(&["--resume", "--seed", "3", "--margin", "4"], common::fails);
    assert!(
        err.contains("checkpoint.bin") && err.contains("seed: 0 -> 3") && err.contains("margin: null -> 4"),
        "{err}"
    );
    run(&["--resume", "--mesh-res", "24", "--checkpoint-every", "1"], ok);
}

#[test]
fn an_option_that_was_removed_is_refused_in_plans_and_the_bench_saying_so() {
    let tmp = tempfile::tempdir().unwrap();
    rmvp_testkit::copy_tree(&rmvp_testkit::fixture("spot_nersp"), &tmp.path().join("spot"));
    let plan = tmp.path().join("batch.toml");
    let fields = fields();
    for (name, _) in REMOVED_OPTIONS {
        assert!(!fields.iter().any(|f| f == name), "{name} is still an option");
        let help = ok(&["recon", "--help"]);
        assert!(!help.contains(&format!("--{} ", name.replace('_', "-"))), "rmvp recon still has --{name}");
        let removed = format!("`{name}` was removed");
        let err = ReconOptions::default().with_toml(&format!("{name} = 1")).expect_err(name);
        assert!(err.contains(&removed), "{err}");
        std::fs::write(
            &plan,
            format!("datasets = [\"spot\"]\n[evaluation]\nenabled = false\n[[variant]]\nname = \"v\"\noptions = {{ {name} = 1 }}\n"),
        )
        .unwrap();
        let err = BatchPlan::read(&plan).expect_err(name).to_string();
        assert!(err.contains(&removed) && err.contains("batch.toml") && err.contains("line 6"), "{err}");
    }
    // An option another name away from a removed one is refused as unknown, as any other.
    let err = ReconOptions::default().with_toml("regularise_near_surfaces = 0").expect_err("unknown");
    assert!(err.contains("unknown field") && !err.contains("was removed"), "{err}");
}
