//! An empty build script: cargo applies a crate's build-dependencies (and so their pinned
//! features) only to a crate that has one.
fn main() {}
