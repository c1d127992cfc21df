//! Write `docs/benchmarks.md` from the benchmarks' results in `bench/results`
//! (`cargo run -p rmvp-testkit --bin benchmarks-page`).

use rmvp_testkit::results::{all_results, benchmarks_page, checkout};

fn main() {
    let results = all_results().unwrap_or_else(|e| {
        eprintln!("benchmarks-page: {e}");
        std::process::exit(1)
    });
    let path = checkout().join("docs/benchmarks.md");
    std::fs::write(&path, benchmarks_page(&results)).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    eprintln!("wrote {}", path.display());
}
