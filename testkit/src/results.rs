//! Benchmark results as files: each benchmark command writes what it measured to
//! `bench/results/NAME.json` ([`BenchResult`]: its tables, its named figures, the command, the
//! commit, the machine and the date), and `docs/benchmarks.md` is generated from those files
//! ([`benchmarks_page`]; `cargo run -p rmvp-testkit --bin benchmarks-page` writes it). A figure
//! quoted elsewhere in the docs carries a marker `<!-- figure: NAME.FIGURE -->` right after it
//! ([`quoted_figures`]), and the docs test checks the quote against the file.

use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// The benchmarks, in the order the page lists them: each is `bench/results/NAME.json`.
pub const BENCHMARKS: [&str; 14] = [
    "frame",
    "render",
    "align",
    "recon-step",
    "recon-time",
    "quality-mitsuba",
    "quality-ours",
    "lab",
    "photographs",
    "dataset",
    "demo",
    "suite",
    "batch",
    "acquisition",
];

/// The benchmarks that run only where a machine has what they need (a GPU), listed after the
/// others when their file exists.
pub const OPTIONAL_BENCHMARKS: [&str; 1] = ["cuda"];

/// The machine a benchmark ran on, as `lscpu` names it.
#[derive(Clone, Debug, PartialEq, Eq, PartialOrd, Ord, Serialize, Deserialize)]
pub struct Machine {
    /// `lscpu`'s model name (`AMD EPYC`).
    pub model: String,
    /// `lscpu`'s CPU family (AMD's 25 is Zen 3 and 4, 26 Zen 5); empty where unknown.
    pub family: String,
    /// Logical cores (`nproc`).
    pub cores: usize,
    /// A GPU the benchmark used (`nvidia-smi`'s name), empty for none.
    #[serde(default, skip_serializing_if = "String::is_empty")]
    pub gpu: String,
}

impl Machine {
    /// The machine this process runs on (`lscpu`, `nproc`), without a GPU.
    pub fn this() -> Self {
        let lscpu =
            std::process::Command::new("lscpu").output().map(|o| String::from_utf8_lossy(&o.stdout).into_owned());
        let field = |name: &str| {
            lscpu.as_deref().unwrap_or("").lines().find_map(|line| {
                let (key, value) = line.split_once(':')?;
                (key.trim() == name).then(|| value.trim().to_string())
            })
        };
        let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
        Machine {
            model: field("Model name").unwrap_or_else(|| "unknown".into()),
            family: field("CPU family").unwrap_or_default(),
            cores,
            gpu: String::new(),
        }
    }

    /// The machine in words: `AMD EPYC (family 25), 2 cores`, with its GPU where it has one.
    pub fn label(&self) -> String {
        let family = if self.family.is_empty() { String::new() } else { format!(" (family {})", self.family) };
        let gpu = if self.gpu.is_empty() { String::new() } else { format!(", {}", self.gpu) };
        format!("{}{family}, {} cores{gpu}", self.model, self.cores)
    }
}

/// One table of a result: its columns and rows of text, as the page prints them.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Table {
    /// The column headings.
    pub columns: Vec<String>,
    /// The rows, each as long as `columns`.
    pub rows: Vec<Vec<String>>,
}

impl Table {
    /// A table with these column headings and no rows.
    pub fn new(columns: &[&str]) -> Self {
        Table { columns: columns.iter().map(|c| c.to_string()).collect(), rows: Vec::new() }
    }

    /// Add a row (as many cells as columns).
    pub fn row(&mut self, cells: Vec<String>) {
        assert_eq!(
            cells.len(),
            self.columns.len(),
            "a row of {} cells under {} columns",
            cells.len(),
            self.columns.len()
        );
        self.rows.push(cells);
    }

    fn markdown(&self) -> String {
        let line = |cells: &[String]| format!("| {} |\n", cells.join(" | "));
        let mut out = line(&self.columns);
        out += &line(&vec!["---".to_string(); self.columns.len()]);
        for row in &self.rows {
            out += &line(row);
        }
        out
    }
}

/// What one benchmark measured, as its command writes it.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct BenchResult {
    /// The section's heading.
    pub title: String,
    /// The command that measures it, as a reader runs it.
    pub command: String,
    /// Its main figure in a few words, for the page's index.
    pub headline: String,
    /// What is measured and how, in Markdown.
    pub about: String,
    /// Its tables.
    pub tables: Vec<Table>,
    /// Named figures, as the docs quote them (`seconds`: `163`).
    pub figures: BTreeMap<String, String>,
    /// The commit measured (`git rev-parse --short HEAD`).
    pub commit: String,
    /// The machine it ran on.
    pub machine: Machine,
    /// The day it ran (UTC, `YYYY-MM-DD`).
    pub date: String,
}

impl BenchResult {
    /// A result of `command` measured now, on this machine at this checkout's commit, with
    /// nothing in it yet.
    pub fn now(title: &str, command: &str) -> Self {
        BenchResult {
            title: title.into(),
            command: command.into(),
            headline: String::new(),
            about: String::new(),
            tables: Vec::new(),
            figures: BTreeMap::new(),
            commit: commit(),
            machine: Machine::this(),
            date: today(),
        }
    }

    /// Record figure `name` as the docs quote it.
    pub fn figure(&mut self, name: &str, value: impl std::fmt::Display) -> String {
        let text = value.to_string();
        self.figures.insert(name.into(), text.clone());
        text
    }

    /// Write it to `bench/results/NAME.json` of the checkout (atomically), and say where.
    pub fn write(&self, name: &str) -> PathBuf {
        let path = results_dir().join(format!("{name}.json"));
        std::fs::create_dir_all(results_dir()).expect("bench/results");
        let part = path.with_extension("json.part");
        let text = serde_json::to_string_pretty(self).expect("a result as JSON") + "\n";
        std::fs::write(&part, text).unwrap_or_else(|e| panic!("{}: {e}", part.display()));
        std::fs::rename(&part, &path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        eprintln!("results: {}", path.display());
        path
    }

    /// Read `bench/results/NAME.json` of the checkout (None where there is none).
    pub fn read(name: &str) -> Option<Self> {
        let path = results_dir().join(format!("{name}.json"));
        let text = std::fs::read_to_string(&path).ok()?;
        Some(serde_json::from_str(&text).unwrap_or_else(|e| panic!("{}: {e}", path.display())))
    }
}

/// The checkout this crate is part of.
pub fn checkout() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// The checkout's `bench/results`.
pub fn results_dir() -> PathBuf {
    checkout().join("bench/results")
}

/// The checkout's commit, short, with `-dirty` where tracked files differ from it (the
/// benchmarks' own outputs, `bench/results` and `docs/benchmarks.md`, apart).
fn commit() -> String {
    let git = |args: &[&str]| {
        std::process::Command::new("git")
            .args(args)
            .current_dir(checkout())
            .output()
            .ok()
            .filter(|o| o.status.success())
            .map(|o| String::from_utf8_lossy(&o.stdout).trim().to_string())
    };
    let Some(head) = git(&["rev-parse", "--short", "HEAD"]) else { return "unknown".into() };
    let changed =
        ["status", "--porcelain", "--untracked-files=no", "--", ".", ":!bench/results", ":!docs/benchmarks.md"];
    let dirty = git(&changed).is_some_and(|s| !s.is_empty());
    if dirty {
        head + "-dirty"
    } else {
        head
    }
}

/// Today's date, UTC, `YYYY-MM-DD` (`date -u +%F`).
fn today() -> String {
    std::process::Command::new("date")
        .args(["-u", "+%F"])
        .output()
        .ok()
        .filter(|o| o.status.success())
        .map_or_else(|| "unknown".into(), |o| String::from_utf8_lossy(&o.stdout).trim().to_string())
}

/// The results the page lists, in its order: every one of [`BENCHMARKS`] (a missing one is a
/// fault) and those of [`OPTIONAL_BENCHMARKS`] that exist; a file in `bench/results` that is
/// neither is a fault too.
pub fn all_results() -> Result<Vec<(String, BenchResult)>, String> {
    let mut results = Vec::new();
    for name in BENCHMARKS {
        let result = BenchResult::read(name).ok_or_else(|| format!("bench/results/{name}.json is missing"))?;
        results.push((name.to_string(), result));
    }
    for name in OPTIONAL_BENCHMARKS {
        if let Some(result) = BenchResult::read(name) {
            results.push((name.to_string(), result));
        }
    }
    let entries = std::fs::read_dir(results_dir()).map_err(|e| format!("bench/results: {e}"))?;
    for entry in entries {
        let name = entry.map_err(|e| e.to_string())?.file_name().to_string_lossy().into_owned();
        let known = name.strip_suffix(".json").is_some_and(|stem| results.iter().any(|(n, _)| n == stem));
        if !known {
            return Err(format!("bench/results/{name} is not a benchmark's result (BENCHMARKS lists them)"));
        }
    }
    Ok(results)
}

/// The anchor GitHub gives a heading: lower case, punctuation dropped, spaces to `-`.
pub fn anchor(title: &str) -> String {
    title
        .to_lowercase()
        .chars()
        .filter(|c| c.is_alphanumeric() || *c == ' ' || *c == '-' || *c == '_')
        .map(|c| if c == ' ' { '-' } else { c })
        .collect()
}

/// `docs/benchmarks.md`, generated from `results`: the machines once, an index of the
/// benchmarks with their main figures, then one section each (its command, machine, commit and
/// date once, what it measures, its tables).
pub fn benchmarks_page(results: &[(String, BenchResult)]) -> String {
    let mut machines: Vec<&Machine> = results.iter().map(|(_, r)| &r.machine).collect();
    machines.sort();
    machines.dedup();
    let mut page = String::from(
        "# Benchmarks\n\n\
         <!-- Generated from bench/results/*.json by `cargo run -p rmvp-testkit --bin benchmarks-page`; \
         each benchmark's command writes its file. Do not edit by hand. -->\n\n\
         Each benchmark's command writes what it measured to `bench/results/NAME.json`; this page is made \
         from those files (`cargo run -p rmvp-testkit --bin benchmarks-page`), and the docs test fails when \
         it differs from them. What a change bought is a line in [`CHANGELOG.md`](../CHANGELOG.md); why \
         the defaults are what they are, [`design.md`](design.md#why-the-reconstructions-defaults-are-what-they-are). \
         `./run bench` runs those that need nothing of their own: not the training step's (it takes a \
         checkpoint), a whole reconstruction's (it compares two binaries), the demo's, the suite's or the GPU's.\n\n\
         The machines are shared virtual machines (Debian 12, 24 GiB or more); a command's time varies by \
         up to 30 % from day to day on one of them, so compare times within a table.\n\n",
    );
    let mut machines_table = Table::new(&["machine (`lscpu`)", "benchmarks"]);
    for machine in &machines {
        let names: Vec<String> = results
            .iter()
            .filter(|(_, r)| &r.machine == *machine)
            .map(|(_, r)| format!("[{}](#{})", r.title, anchor(&r.title)))
            .collect();
        machines_table.row(vec![machine.label(), names.join(", ")]);
    }
    page += &machines_table.markdown();
    page += "\n";
    let mut index = Table::new(&["benchmark", "command", "figure"]);
    for (_, r) in results {
        index.row(vec![
            format!("[{}](#{})", r.title, anchor(&r.title)),
            format!("`{}`", r.command),
            r.headline.clone(),
        ]);
    }
    page += &index.markdown();
    for (name, r) in results {
        page += &format!("\n## {}\n\n", r.title);
        page += &format!(
            "`{}`, {}, {}, commit {} (`bench/results/{name}.json`).\n\n",
            r.command,
            r.date,
            r.machine.label(),
            r.commit
        );
        if !r.about.is_empty() {
            page += r.about.trim_end();
            page += "\n\n";
        }
        for (k, table) in r.tables.iter().enumerate() {
            if k > 0 {
                page += "\n";
            }
            page += &table.markdown();
        }
    }
    page
}

/// A figure quoted in a page: the page, its line, the figure's name (`demo.seconds`) and the
/// text just before the marker.
#[derive(Clone, Debug, PartialEq)]
pub struct Quote {
    /// The page.
    pub page: PathBuf,
    /// Its line, from 1.
    pub line: usize,
    /// `NAME.FIGURE`.
    pub figure: String,
    /// The text before the marker on its line.
    pub before: String,
}

/// The marker that follows a quoted figure: `<!-- figure: NAME.FIGURE -->`.
pub const FIGURE_MARKER: &str = "<!-- figure: ";

/// Every figure `page` (its text `text`) quotes with a marker.
pub fn quoted_figures(page: &Path, text: &str) -> Vec<Quote> {
    let mut quotes = Vec::new();
    for (n, line) in text.lines().enumerate() {
        let mut rest = line;
        let mut consumed = 0;
        while let Some(at) = rest.find(FIGURE_MARKER) {
            let after = &rest[at + FIGURE_MARKER.len()..];
            let Some(end) = after.find("-->") else { break };
            quotes.push(Quote {
                page: page.to_path_buf(),
                line: n + 1,
                figure: after[..end].trim().to_string(),
                before: line[..consumed + at].to_string(),
            });
            let step = at + FIGURE_MARKER.len() + end + 3;
            consumed += step;
            rest = &rest[step..];
        }
    }
    quotes
}

/// Whether `quote` states its figure as `results` hold it: the text before the marker ends with
/// the figure's value (`Err` says what is wrong).
pub fn check_quote(quote: &Quote, results: &[(String, BenchResult)]) -> Result<(), String> {
    let at = format!("{}:{}", quote.page.display(), quote.line);
    let (name, figure) =
        quote.figure.split_once('.').ok_or_else(|| format!("{at}: `{}` is not NAME.FIGURE", quote.figure))?;
    let result = results
        .iter()
        .find(|(n, _)| n == name)
        .ok_or_else(|| format!("{at}: no benchmark `{name}` (bench/results/{name}.json)"))?;
    let value = result
        .1
        .figures
        .get(figure)
        .ok_or_else(|| format!("{at}: bench/results/{name}.json has no figure `{figure}`"))?;
    if quote.before.trim_end().ends_with(value.as_str()) {
        Ok(())
    } else {
        Err(format!("{at}: quotes {} as {:?}, but it is {value}", quote.figure, quote.before.trim_end()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quotes_are_found_and_checked_against_their_figures() {
        let text = "The demo takes 163 s<!-- figure: demo.seconds --> and 2.63 degrees <!-- figure: demo.normal -->.";
        let quotes = quoted_figures(Path::new("README.md"), text);
        assert_eq!(quotes.len(), 2);
        assert_eq!(quotes[1].figure, "demo.normal");
        let mut result = BenchResult::now("The demo", "./run demo");
        result.figure("seconds", "163 s");
        result.figure("normal", 2.64);
        let results = vec![("demo".to_string(), result)];
        assert_eq!(check_quote(&quotes[0], &results), Ok(()));
        let wrong = check_quote(&quotes[1], &results).unwrap_err();
        assert!(wrong.contains("README.md:1") && wrong.contains("2.64"), "{wrong}");
        let missing = Quote { figure: "demo.minutes".into(), ..quotes[0].clone() };
        assert!(check_quote(&missing, &results).unwrap_err().contains("no figure `minutes`"));
    }
}
