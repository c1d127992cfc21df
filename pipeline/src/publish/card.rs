//! A release's `README.md` as a dataset card: YAML front matter as the Hugging Face Hub reads
//! it (licence, pretty name, task categories, tags, size category, one config whose splits are
//! the views' tables and one of the objects) above the datasheet.

use super::index::{views_table, OBJECTS_TABLE, SPLITS};
use super::metadata::ReleaseMetadata;

/// The Hub's size category of a dataset of `records` records.
pub fn size_category(records: usize) -> &'static str {
    match records {
        0..1_000 => "n<1K",
        1_000..10_000 => "1K<n<10K",
        10_000..100_000 => "10K<n<100K",
        100_000..1_000_000 => "100K<n<1M",
        _ => "n>1M",
    }
}

/// A YAML double-quoted scalar (JSON's escapes are YAML's).
fn quoted(text: &str) -> String {
    serde_json::to_string(text).expect("a string serialises")
}

/// The front matter of a release of `views` views in all, `---` lines included.
pub fn front_matter(metadata: &ReleaseMetadata, views: usize) -> String {
    let mut yaml = String::from("---\n");
    // The Hub's licence identifiers are SPDX's, in lower case.
    yaml += &format!("license: {}\n", metadata.license.to_lowercase());
    yaml += &format!("pretty_name: {}\n", quoted(&metadata.title));
    yaml += "task_categories:\n- image-to-3d\n";
    yaml += "tags:\n";
    for keyword in &metadata.keywords {
        yaml += &format!("- {}\n", quoted(keyword));
    }
    yaml += &format!("size_categories:\n- {}\n", quoted(size_category(views)));
    yaml += "configs:\n- config_name: views\n  default: true\n  data_files:\n";
    for split in SPLITS {
        yaml += &format!("  - split: {split}\n    path: {}\n", views_table(split));
    }
    yaml += &format!("- config_name: objects\n  data_files:\n  - split: all\n    path: {OBJECTS_TABLE}\n");
    yaml + "---\n\n"
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn size_categories_have_the_hubs_bounds() {
        assert_eq!(
            [0, 999, 1000, 99_999, 2_000_000].map(size_category),
            ["n<1K", "n<1K", "1K<n<10K", "10K<n<100K", "n>1M"]
        );
    }
}
