//! Write a benchmark's result, `bench/results/NAME.json`, from what a script measured:
//! `bench-result NAME < MEASURED.json`, where the JSON holds the result's `title`, `command`,
//! `headline`, `about`, `tables` and `figures` ([`BenchResult`]), and the `commit` measured
//! where it is not this checkout's (a fresh clone's); the machine and the date are this
//! machine's, now. The shell benchmarks (`bench/*.sh`) write theirs with it.

use rmvp_testkit::results::{BenchResult, Table};
use serde::Deserialize;
use std::collections::BTreeMap;

/// What a script measured: a result without its commit, machine and date.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct Measured {
    title: String,
    command: String,
    headline: String,
    #[serde(default)]
    about: String,
    #[serde(default)]
    tables: Vec<Table>,
    #[serde(default)]
    figures: BTreeMap<String, String>,
    /// The commit measured, where it is not this checkout's.
    #[serde(default)]
    commit: Option<String>,
}

fn main() {
    let fail = |message: String| -> ! {
        eprintln!("bench-result: {message}");
        std::process::exit(2)
    };
    let args: Vec<String> = std::env::args().skip(1).collect();
    let [name] = args.as_slice() else { fail("usage: bench-result NAME < MEASURED.json".into()) };
    let measured: Measured =
        serde_json::from_reader(std::io::stdin().lock()).unwrap_or_else(|e| fail(format!("standard input: {e}")));
    let mut result = BenchResult::now(&measured.title, &measured.command);
    result.headline = measured.headline;
    result.about = measured.about;
    result.tables = measured.tables;
    result.figures = measured.figures;
    if let Some(commit) = measured.commit {
        result.commit = commit;
    }
    result.write(name);
}
