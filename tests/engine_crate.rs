//! The engine is a crate of its own with no middleware and no I/O in its dependency tree:
//! its rule "no I/O, no ROS types" is a boundary the build keeps, not a comment.
//!
//! `cargo tree -p tracer_calib_engine -e normal,build` (features resolved for the engine
//! alone, as `cargo build -p tracer_calib_engine` builds it) must name none of the crates
//! that carry a middleware, a file format, a network or the ROS shell, and the engine's own
//! sources must not reach `std::fs`, `std::net`, `std::process` or `std::io`.

use std::path::Path;
use std::process::Command;

/// Crates (or name prefixes, ending in `-` or `_`) that have no place under the engine.
const FORBIDDEN: &[&str] = &[
    "tracer_calib ",
    "ros2-client",
    "rustdds",
    "zenoh",
    "mcap",
    "rusqlite",
    "libsqlite3-sys",
    "openssl",
    "smol",
    "async-",
    "tokio",
    "mio",
    "socket2",
    "polling",
    "futures",
    "serde_json",
    "yaml-rust2",
    "clap",
    "env_logger",
    "ctrlc",
    "getrandom",
];

fn engine_tree() -> Vec<String> {
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let out = Command::new(cargo)
        .current_dir(root)
        .args(["tree", "--offline", "--locked", "-p", "tracer_calib_engine", "-e", "normal,build"])
        .args(["--prefix", "none", "--format", "{p}"])
        .output()
        .expect("cargo tree runs");
    assert!(out.status.success(), "cargo tree failed: {}", String::from_utf8_lossy(&out.stderr));
    String::from_utf8(out.stdout).unwrap().lines().map(|l| l.trim().to_string()).filter(|l| !l.is_empty()).collect()
}

#[test]
fn the_engine_depends_on_no_middleware_and_no_io() {
    let tree = engine_tree();
    assert!(
        tree.first().is_some_and(|p| p.starts_with("tracer_calib_engine ")),
        "cargo tree did not start at the engine: {tree:?}"
    );
    assert!(tree.iter().any(|p| p.starts_with("nalgebra ")), "the engine's tree lacks nalgebra: {tree:?}");
    let bad: Vec<&String> = tree.iter().filter(|p| FORBIDDEN.iter().any(|f| p.starts_with(f))).collect();
    assert!(bad.is_empty(), "the engine's dependency tree holds {bad:?}");
    println!("the engine's tree: {} crates", tree.iter().collect::<std::collections::BTreeSet<_>>().len());
}

#[test]
fn the_engine_sources_do_no_io() {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("crates/tracer_calib_engine/src");
    let mut files = vec![];
    let mut dirs = vec![src];
    while let Some(dir) = dirs.pop() {
        for entry in std::fs::read_dir(&dir).unwrap() {
            let path = entry.unwrap().path();
            if path.is_dir() {
                dirs.push(path);
            } else if path.extension().is_some_and(|e| e == "rs") {
                files.push(path);
            }
        }
    }
    assert!(files.len() > 10, "the engine's sources were not found: {files:?}");
    for file in files {
        let text = std::fs::read_to_string(&file).unwrap();
        for (n, line) in text.lines().enumerate() {
            let code = line.split("//").next().unwrap();
            for io in ["std::fs", "std::net", "std::process", "std::io", "std::env", "println!", "eprintln!"] {
                assert!(
                    !code.contains(io),
                    "{}:{}: the engine does no I/O, but: {}",
                    file.display(),
                    n + 1,
                    line.trim()
                );
            }
        }
    }
}
