//! The documentation as a reader meets it: every relative link in the README and `docs/` leads
//! to a file that exists (and to a heading of it, when the link names one), `docs/benchmarks.md`
//! is what the benchmarks' results generate, every figure the pages quote with a marker is its
//! result's, and nothing in the repository speaks of how it was made (working sessions,
//! numbered issues).

use rmvp_testkit::results::{all_results, anchor, benchmarks_page, check_quote, quoted_figures};
use std::collections::BTreeSet;
use std::path::{Path, PathBuf};

const ROOT: &str = env!("CARGO_MANIFEST_DIR");

/// The Markdown pages a reader opens: the README, the changelog and `docs/`.
fn pages() -> Vec<PathBuf> {
    let root = Path::new(ROOT);
    let mut pages = vec![root.join("README.md"), root.join("CHANGELOG.md")];
    for entry in std::fs::read_dir(root.join("docs")).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().is_some_and(|e| e == "md") {
            pages.push(path);
        }
    }
    pages.sort();
    pages
}

/// The anchors GitHub gives a page's headings ([`anchor`]).
fn anchors(page: &str) -> BTreeSet<String> {
    let mut inside_code = false;
    let mut anchors = BTreeSet::new();
    for line in page.lines() {
        if line.starts_with("```") {
            inside_code = !inside_code;
        }
        if inside_code || !line.starts_with('#') {
            continue;
        }
        anchors.insert(anchor(line.trim_start_matches('#').trim()));
    }
    anchors
}

/// The targets of a page's inline links `[text](target)`, but for web addresses.
fn links(page: &str) -> Vec<String> {
    let mut found = Vec::new();
    let mut rest = page;
    while let Some(at) = rest.find("](") {
        rest = &rest[at + 2..];
        let Some(end) = rest.find(')') else { break };
        let target = &rest[..end];
        if !target.contains("://") && !target.starts_with("mailto:") && !target.contains(' ') {
            found.push(target.to_string());
        }
    }
    found
}

#[test]
fn every_relative_link_in_the_docs_leads_to_a_file_and_heading_that_exist() {
    let mut broken = Vec::new();
    let mut checked = 0;
    for page in pages() {
        let text = std::fs::read_to_string(&page).unwrap();
        for link in links(&text) {
            let (file, anchor) = link.split_once('#').map_or((link.as_str(), None), |(f, a)| (f, Some(a)));
            let target = if file.is_empty() { page.clone() } else { page.parent().unwrap().join(file) };
            checked += 1;
            if !target.exists() {
                broken.push(format!("{}: {link} (no such file)", page.display()));
                continue;
            }
            if let Some(anchor) = anchor {
                let headings = anchors(&std::fs::read_to_string(&target).unwrap());
                if !headings.contains(anchor) {
                    broken.push(format!("{}: {link} (no such heading)", page.display()));
                }
            }
        }
    }
    assert!(checked > 50, "only {checked} links found: the link reader is broken");
    assert!(broken.is_empty(), "broken links:\n{}", broken.join("\n"));
}

/// The line where `text` has `word`, a space and a digit, in any case.
fn numbered(text: &str, word: &str) -> Option<String> {
    let lower = text.to_lowercase();
    let pattern = format!("{word} ");
    lower.match_indices(&pattern).find_map(|(at, _)| {
        let after = &lower[at + pattern.len()..];
        after.starts_with(|c: char| c.is_ascii_digit()).then(|| {
            let line_start = lower[..at].rfind('\n').map_or(0, |n| n + 1);
            let line_end = after.find('\n').map_or(lower.len(), |n| at + pattern.len() + n);
            text[line_start..line_end].to_string()
        })
    })
}

/// Every text file of the repository: sources, tests, scripts, docs (not `target/` or `.git`).
fn repository_files(dir: &Path, found: &mut Vec<PathBuf>) {
    for entry in std::fs::read_dir(dir).unwrap() {
        let path = entry.unwrap().path();
        let name = path.file_name().unwrap().to_string_lossy().to_string();
        if name == "target" || name.starts_with('.') && name != ".ci" {
            continue;
        }
        if path.is_dir() {
            repository_files(&path, found);
        } else if ["rs", "md", "toml", "sh", "py", "xml", "rules"].iter().any(|e| name.ends_with(&format!(".{e}")))
            || name == "run"
        {
            found.push(path);
        }
    }
}

#[test]
fn nothing_in_the_repository_speaks_of_working_sessions_or_numbered_issues() {
    let mut files = Vec::new();
    repository_files(Path::new(ROOT), &mut files);
    assert!(files.len() > 100, "only {} files found", files.len());
    let mut narration = Vec::new();
    for file in &files {
        let text = std::fs::read_to_string(file).unwrap_or_default();
        for word in ["session", "issue"] {
            if let Some(line) = numbered(&text, word) {
                narration.push(format!("{}: {}", file.display(), line.trim()));
            }
        }
    }
    assert!(narration.is_empty(), "the repository should speak of the software:\n{}", narration.join("\n"));
}

#[test]
fn the_narration_check_finds_what_it_looks_for() {
    // Built from parts, so that this file does not hold what it looks for.
    assert!(numbered(&format!("measured in Session {}, then", 12), "session").is_some());
    assert!(numbered(&format!("as {} {} asks", "issue", 3), "issue").is_some());
    assert!(numbered("a capture session, 540 MB", "session").is_none());
    assert!(numbered("[x](a.md#the-dataset-stage)", "issue").is_none());
    assert_eq!(links("see [a](a.md), [b](https://x.org) and [c](c.md#h)"), ["a.md", "c.md#h"]);
    assert!(anchors("# Title\n## Calibration, poses and masks\n").contains("calibration-poses-and-masks"));
}

#[test]
fn the_benchmarks_page_is_what_the_results_generate() {
    let results = all_results().unwrap_or_else(|e| panic!("{e}"));
    let page = std::fs::read_to_string(Path::new(ROOT).join("docs/benchmarks.md")).unwrap();
    assert!(
        page == benchmarks_page(&results),
        "docs/benchmarks.md differs from bench/results: run `cargo run -p rmvp-testkit --bin benchmarks-page`"
    );
}

#[test]
fn every_quoted_figure_is_its_results() {
    let results = all_results().unwrap_or_else(|e| panic!("{e}"));
    let mut quotes = Vec::new();
    for page in pages().into_iter().filter(|p| !p.ends_with("docs/benchmarks.md")) {
        quotes.extend(quoted_figures(&page, &std::fs::read_to_string(&page).unwrap()));
    }
    assert!(quotes.len() >= 8, "only {} quoted figures found: the marker reader is broken", quotes.len());
    let wrong: Vec<String> = quotes.iter().filter_map(|q| check_quote(q, &results).err()).collect();
    assert!(wrong.is_empty(), "quoted figures that are not their results':\n{}", wrong.join("\n"));
}
