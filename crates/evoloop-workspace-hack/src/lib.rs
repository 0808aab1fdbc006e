//! No code: this crate exists for its Cargo.toml, which turns on, in every build of the workspace,
//! the features of third-party crates that some build would otherwise turn on alone (cargo
//! compiles a crate once per set of features), so `cargo run --release`, `cargo test --release`,
//! the `zenoh` feature's build and the ROS 2 peer share one compiled copy of each dependency.
#![forbid(unsafe_code)]
