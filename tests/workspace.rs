//! The workspace's builds share their crates: the Python wheel's build (`-p rmvp-python`, what
//! `pip install ./python` runs) asks for each third-party crate with features the test build
//! (`--workspace`) asks for too, so `./run test` compiles the dependency tree once
//! (`workspace-hack/Cargo.toml`).

use std::collections::{BTreeMap, BTreeSet};
use std::process::Command;

/// A crate as cargo compiles it: its name and version, and whether it is built for the host
/// (build scripts' and proc-macros' dependencies, compiled apart from the target's, with the
/// `build-override` profile) or for the target.
type Unit = (String, bool);

/// Each crate in `cargo tree`'s graph for `args`, with the features it is compiled with: cargo
/// compiles one unit per crate and side with the union of what its dependents ask for, where the
/// tree lists each dependent's request (a dev-dependency's apart).
///
/// Reads the tree's indentation: a `[build-dependencies]` label sits at its parent's column,
/// and what is under a build dependency or a proc-macro is built for the host.
fn units(args: &[&str]) -> BTreeMap<Unit, BTreeSet<String>> {
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
    let output = Command::new(cargo)
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .args(["tree", "--offline", "--locked", "--no-dedupe", "--format", "{p}|{f}"])
        .args(args)
        .output()
        .expect("cargo runs");
    assert!(output.status.success(), "cargo tree {args:?}: {}", String::from_utf8_lossy(&output.stderr));
    let mut units: BTreeMap<Unit, BTreeSet<String>> = BTreeMap::new();
    // The open ancestors of the current line: column, built for the host, and whether the
    // children listed next are build dependencies.
    let mut ancestors: Vec<(usize, bool, bool)> = Vec::new();
    for line in String::from_utf8(output.stdout).unwrap().lines() {
        let column = line.chars().take_while(|c| "│├└─ ".contains(*c)).count();
        let text: String = line.chars().skip(column).collect();
        if text.is_empty() {
            ancestors.clear();
            continue;
        }
        while ancestors.last().is_some_and(|&(at, ..)| at > column || (at == column && !text.starts_with('['))) {
            ancestors.pop();
        }
        if text.starts_with('[') {
            let parent = ancestors.last_mut().expect("a label follows its parent");
            parent.2 = text == "[build-dependencies]";
            continue;
        }
        let (package, features) = text.split_once('|').expect("the format's separator");
        let host = package.contains("(proc-macro)") || ancestors.last().is_some_and(|&(_, host, build)| host || build);
        ancestors.push((column, host, false));
        let name = package.split(" (").next().unwrap().trim().to_string();
        let features = features.trim().split(',').filter(|feature| !feature.is_empty()).map(String::from);
        units.entry((name, host)).or_default().extend(features);
    }
    units
}

#[test]
fn the_wheel_asks_for_each_crate_as_the_test_build_does() {
    let workspace = units(&["--workspace", "--exclude", "rmvp-python", "--edges", "normal,build,dev"]);
    let wheel = units(&["-p", "rmvp-python", "--features", "pyo3/extension-module", "--edges", "normal,build"]);
    // The reading sees both kinds of unit: syn only for the host, bitflags on both sides.
    for (package, host) in [("opencv", false), ("syn", true), ("bitflags", false), ("bitflags", true)] {
        assert!(
            wheel.keys().any(|(name, on_host)| name.starts_with(&format!("{package} v")) && *on_host == host),
            "{package} for the host: {host}, among {:?}",
            wheel.keys()
        );
    }
    // Crates only the wheel uses are compiled once anyway; of the rest, only the capture crate
    // (without its camera, sessions and preview) and the wheel itself differ.
    let own = |package: &str| package.starts_with("rmvp-python ") || package.starts_with("rmvp-capture ");
    let differing: Vec<String> = wheel
        .iter()
        .filter(|((package, _), _)| !own(package))
        .filter_map(|(unit, features)| Some((unit, features, workspace.get(unit)?)))
        .filter(|(_, features, built)| features != built)
        .map(|((package, host), features, built)| {
            let side = if *host { "host" } else { "target" };
            format!("{package} ({side}): the wheel asks for {features:?}, the test build for {built:?}")
        })
        .collect();
    assert!(
        differing.is_empty(),
        "these crates would be compiled a second time for the wheel (add their features to workspace-hack/Cargo.toml, or \
         the rmvp crates' to python/Cargo.toml):\n{}",
        differing.join("\n")
    );
}
