//! The build's identity for evaluation workers (`workers::build`): a hash of every source
//! file of the workspace, the lock file, the compiler and the target, so a worker and an optimiser agree only when
//! they run the same code compiled the same way (the same code on the same bits gives the same
//! values; the same version number alone does not promise that). It is run again when what it
//! hashes changes, and only then: without `rerun-if-changed` lines Cargo ran it for any file of
//! the package, so editing a test recompiled the library and every binary.

use std::collections::hash_map::DefaultHasher;
use std::hash::Hasher;
use std::path::Path;

fn files(dir: &Path, out: &mut Vec<std::path::PathBuf>) {
    let Ok(rd) = std::fs::read_dir(dir) else {
        return;
    };
    for e in rd.flatten() {
        let p = e.path();
        if p.is_dir() {
            files(&p, out);
        } else if p.extension().is_some_and(|x| x == "rs")
            || p.file_name().is_some_and(|n| n == "Cargo.toml")
        {
            out.push(p);
        }
    }
}

fn main() {
    // This crate is crates/evoloop-net of the workspace; the identity covers every crate's code.
    let manifest = Path::new(env!("CARGO_MANIFEST_DIR"));
    let root = manifest.ancestors().nth(2).unwrap_or(manifest);
    let mut list = Vec::new();
    for d in ["src", "bin", "crates"] {
        files(&root.join(d), &mut list);
    }
    list.push(root.join("Cargo.toml"));
    list.push(root.join("Cargo.lock"));
    list.sort();
    // SipHash with fixed keys: the same inputs give the same id on every machine.
    let mut h = DefaultHasher::new();
    for p in &list {
        h.write(
            p.strip_prefix(root)
                .unwrap_or(p)
                .to_string_lossy()
                .as_bytes(),
        );
        h.write(&std::fs::read(p).unwrap_or_default());
    }
    for var in [
        "TARGET",
        "PROFILE",
        "OPT_LEVEL",
        "DEBUG",
        "CARGO_CFG_TARGET_FEATURE",
    ] {
        h.write(std::env::var(var).unwrap_or_default().as_bytes());
    }
    let rustc = std::env::var("RUSTC").unwrap_or_else(|_| "rustc".into());
    if let Ok(o) = std::process::Command::new(rustc).arg("-vV").output() {
        h.write(&o.stdout);
    }
    println!("cargo:rustc-env=EVOLOOP_BUILD_ID={:016x}", h.finish());
    // A directory is scanned whole, so a new source file counts too. The compiler and the
    // target are in Cargo's own fingerprint: a change of either rebuilds this anyway.
    for p in ["src", "bin", "crates", "Cargo.toml", "Cargo.lock"] {
        println!("cargo:rerun-if-changed={}", root.join(p).display());
    }
}
