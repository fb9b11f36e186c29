//! The floors of the crate (docs/architecture.md) import downwards only: no module names a
//! module of a floor above its own. Read from the sources (code lines, not comments), so a new
//! upward `use crate::…` fails here with the file and line that holds it.

use std::fs;
use std::path::{Path, PathBuf};

/// Each floor, bottom to top, with the modules (directories or files under `src/`) it holds.
const FLOORS: &[(&str, &[&str])] = &[
    ("spatial", &["spatial", "linalg"]),
    ("model", &["model"]),
    ("algorithms", &["algorithms", "operators", "dynamics"]),
    ("state", &["state"]),
    ("control", &["control"]),
    ("flex", &["flex"]),
    ("integrate", &["integrate", "lanes"]),
    ("capture", &["capture"]),
    ("planning", &["planning"]),
    ("analysis", &["analysis"]),
    ("python", &["python"]),
];

fn sources(path: &Path) -> Vec<PathBuf> {
    if path.is_dir() {
        let mut out = Vec::new();
        for entry in fs::read_dir(path).unwrap() {
            out.extend(sources(&entry.unwrap().path()));
        }
        out
    } else if path.extension().is_some_and(|e| e == "rs") {
        vec![path.to_path_buf()]
    } else {
        Vec::new()
    }
}

fn module_files(name: &str) -> Vec<PathBuf> {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let dir = src.join(name);
    let files = if dir.is_dir() {
        sources(&dir)
    } else {
        vec![src.join(format!("{name}.rs"))]
    };
    assert!(
        files.iter().all(|f| f.exists()) && !files.is_empty(),
        "module {name} not found under src/"
    );
    files
}

#[test]
fn no_floor_imports_from_a_floor_above_it() {
    let mut upward = Vec::new();
    for (level, (floor, modules)) in FLOORS.iter().enumerate() {
        let above: Vec<&str> = FLOORS[level + 1..]
            .iter()
            .flat_map(|(_, m)| m.iter().copied())
            .collect();
        for file in modules.iter().flat_map(|m| module_files(m)) {
            let text = fs::read_to_string(&file).unwrap();
            for (i, line) in text.lines().enumerate() {
                let code = line.trim_start();
                if code.starts_with("//") {
                    continue;
                }
                for upper in &above {
                    let path = format!("crate::{upper}");
                    let hit = code.match_indices(&path).any(|(at, _)| {
                        !code[at + path.len()..]
                            .starts_with(|c: char| c.is_alphanumeric() || c == '_')
                    });
                    if hit {
                        upward.push(format!(
                            "{}:{}: the {floor} floor names {path}: {code}",
                            file.display(),
                            i + 1
                        ));
                    }
                }
            }
        }
    }
    assert!(upward.is_empty(), "upward imports:\n{}", upward.join("\n"));
}

/// The model does not know its integrator (`integrate` is above `flex`): the check above, said
/// on its own because the next capabilities lean on it.
#[test]
fn flex_does_not_name_integrate() {
    for file in module_files("flex") {
        let text = fs::read_to_string(&file).unwrap();
        for line in text.lines().filter(|l| !l.trim_start().starts_with("//")) {
            assert!(
                !line.contains("crate::integrate"),
                "{}: {line}",
                file.display()
            );
        }
    }
}
