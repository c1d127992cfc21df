//! No code: this crate only asks for features of third-party crates (see its `Cargo.toml`), so
//! that every build of the workspace compiles them, and the crates above them, alike.
