//! The crate's modules in layers that import only downwards: each module's code (its tests
//! aside) names only modules of the layers before it. The order is the model's: the engine,
//! the physics and networks, rendering, the data, the losses, training, the run's options and
//! what a run writes.

use std::collections::BTreeSet;
use std::path::Path;

/// The modules from the bottom up; a module may use the ones before it.
const LAYERS: [&str; 25] = [
    "error",
    "engine",
    "pbrdf",
    "model",
    "occupancy",
    "ray",
    "samples",
    "volume",
    "trace",
    "data",
    "geometric",
    "losses",
    "config",
    "step",
    "train",
    "presets",
    "extract",
    "unseen",
    "cuda",
    "options",
    "checkpoint",
    "output",
    "residuals",
    "tracking",
    "reconstruct",
];

/// The crate's modules a source file's code names (`crate::name`, `use crate::{a, b::c}`;
/// `Error` and `Result` are the `error` module's), comments and the tests module left out.
fn used_modules(source: &str) -> BTreeSet<String> {
    let code: String = source
        .split("#[cfg(test)]")
        .next()
        .unwrap()
        .lines()
        .filter(|l| !l.trim_start().starts_with("//"))
        .collect::<Vec<_>>()
        .join("\n");
    let mut used = BTreeSet::new();
    let mut rest = code.as_str();
    while let Some(at) = rest.find("crate::") {
        rest = &rest[at + "crate::".len()..];
        let names: Vec<&str> = if let Some(group) = rest.strip_prefix('{') {
            let end = group.find('}').unwrap();
            group[..end].split(',').map(|item| item.trim().split("::").next().unwrap().trim()).collect()
        } else {
            vec![rest.split(|c: char| !(c.is_alphanumeric() || c == '_')).next().unwrap()]
        };
        for name in names.into_iter().filter(|n| !n.is_empty()) {
            let module = if name.starts_with(char::is_uppercase) { "error" } else { name };
            used.insert(module.to_string());
        }
    }
    used
}

/// The module a source file belongs to: `model/field.rs` is `model`.
fn module_of(relative: &Path) -> String {
    let first = relative.components().next().unwrap().as_os_str().to_string_lossy().into_owned();
    first.trim_end_matches(".rs").to_string()
}

fn sources(dir: &Path, out: &mut Vec<std::path::PathBuf>) {
    for entry in std::fs::read_dir(dir).unwrap() {
        let path = entry.unwrap().path();
        if path.is_dir() {
            sources(&path, out);
        } else if path.extension().is_some_and(|e| e == "rs") {
            out.push(path);
        }
    }
}

#[test]
fn modules_import_only_the_layers_below_them() {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let mut files = Vec::new();
    sources(&src, &mut files);
    let mut faults = Vec::new();
    let mut seen = BTreeSet::new();
    for file in &files {
        let relative = file.strip_prefix(&src).unwrap();
        let module = module_of(relative);
        if module == "lib" {
            continue;
        }
        seen.insert(module.clone());
        let Some(level) = LAYERS.iter().position(|m| *m == module) else {
            faults.push(format!("{}: module {module} is in no layer", relative.display()));
            continue;
        };
        for used in used_modules(&std::fs::read_to_string(file).unwrap()) {
            match LAYERS.iter().position(|m| *m == used) {
                Some(l) if l <= level => {}
                Some(_) => faults.push(format!("{}: {module} uses {used}, a layer above it", relative.display())),
                None => faults.push(format!("{}: uses crate::{used}, in no layer", relative.display())),
            }
        }
    }
    let missing: Vec<&&str> = LAYERS.iter().filter(|m| !seen.contains(**m)).collect();
    assert!(missing.is_empty(), "layers without a module: {missing:?}");
    assert!(faults.is_empty(), "{}", faults.join("\n"));
}

#[test]
fn the_check_finds_an_upward_import() {
    let source = "use crate::engine::Adam;\nuse crate::{train::Trainer, Result};\n// crate::reconstruct\n#[cfg(test)]\nuse crate::options;";
    let used: Vec<String> = used_modules(source).into_iter().collect();
    assert_eq!(used, ["engine", "error", "train"]);
}
