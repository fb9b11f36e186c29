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

/// The longest a library function may be, in lines from its `fn` line to its closing brace.
const MAX_FUNCTION_LINES: usize = 80;

/// The numeric kernels allowed past [`MAX_FUNCTION_LINES`]: each written as the equations it
/// cites, which read best in one piece. Each entry is `(file under src/, function, citation)`;
/// the function's doc comment must contain the citation, and the entry must still be needed.
const KERNELS: &[(&str, &str, &str)] = &[
    ("operators.rs", "new", "(A.19)"),
    (
        "algorithms/derivatives/inverse.rs",
        "id_derivatives",
        "∂τ_i/∂q_k = α_i · c_k + β_i · u_k",
    ),
    ("linalg.rs", "double_shift_step", "EISPACK `hqr`"),
    (
        "flex/jacobians.rs",
        "stage_chain",
        "dk_s = K_s (𝟙 + h_s dk_{s−1})",
    ),
    ("flex/jacobians.rs", "jacobians_into", "model §4"),
    ("analysis/linear.rs", "held_jacobians", "(A.19)"),
    ("lanes/step.rs", "aba", "(A.6)"),
];

/// `text` with the insides of comments, strings and character literals blanked (newlines
/// kept), so that braces and keywords are only the code's.
fn code_only(text: &str) -> Vec<u8> {
    let b = text.as_bytes();
    let mut out = b.to_vec();
    let blank = |out: &mut Vec<u8>, from: usize, to: usize| {
        for c in &mut out[from..to] {
            if *c != b'\n' {
                *c = b' ';
            }
        }
    };
    let ident = |c: u8| c.is_ascii_alphanumeric() || c == b'_';
    let mut i = 0;
    while i < b.len() {
        let rest = &b[i..];
        let start = i;
        if rest.starts_with(b"//") {
            while i < b.len() && b[i] != b'\n' {
                i += 1;
            }
        } else if rest.starts_with(b"/*") {
            let mut depth = 0;
            while i < b.len() {
                if b[i..].starts_with(b"/*") {
                    depth += 1;
                    i += 2;
                } else if b[i..].starts_with(b"*/") {
                    depth -= 1;
                    i += 2;
                    if depth == 0 {
                        break;
                    }
                } else {
                    i += 1;
                }
            }
        } else if b[i] == b'r'
            && (i == 0 || !ident(b[i - 1]) || b[i - 1] == b'b')
            && rest[1..]
                .iter()
                .position(|&c| c != b'#')
                .map(|k| rest[1 + k])
                == Some(b'"')
        {
            // a raw string r#"…"#: it ends at a quote followed by as many hashes
            let hashes = rest[1..].iter().take_while(|&&c| c == b'#').count();
            let close: Vec<u8> = std::iter::once(b'"')
                .chain(std::iter::repeat(b'#').take(hashes))
                .collect();
            i += 2 + hashes;
            while i < b.len() && !b[i..].starts_with(&close) {
                i += 1;
            }
            i += close.len();
        } else if b[i] == b'"' {
            i += 1;
            while i < b.len() && b[i] != b'"' {
                i += if b[i] == b'\\' { 2 } else { 1 };
            }
            i += 1;
        } else if b[i] == b'\'' && rest.get(1) == Some(&b'\\') {
            // an escaped character literal: '\n', '\'', '\u{…}'
            i += 3;
            while i < b.len() && b[i] != b'\'' {
                i += 1;
            }
            i += 1;
        } else if b[i] == b'\'' {
            // a character literal 'x' (x possibly several bytes), or a lifetime 'a
            let width = text[i + 1..].chars().next().map_or(1, char::len_utf8);
            if b.get(i + 1 + width) == Some(&b'\'') {
                i += 2 + width;
            } else {
                i += 1;
                continue;
            }
        } else {
            i += 1;
            continue;
        }
        let to = i.min(b.len());
        blank(&mut out, start, to);
    }
    out
}

/// The end (exclusive) of the item whose header starts at `from` in `code`: past its matching
/// closing brace, or past the `;` of a declaration without a body. Brackets and parentheses
/// are skipped, so `[u8; 3]` does not end a header.
fn item_end(code: &[u8], from: usize) -> usize {
    let mut nesting = 0i64;
    let mut i = from;
    while i < code.len() {
        match code[i] {
            b'(' | b'[' => nesting += 1,
            b')' | b']' => nesting -= 1,
            b';' if nesting == 0 => return i + 1,
            b'{' if nesting == 0 => {
                let mut depth = 0i64;
                for (j, &c) in code.iter().enumerate().skip(i) {
                    depth += (c == b'{') as i64 - (c == b'}') as i64;
                    if depth == 0 {
                        return j + 1;
                    }
                }
                return code.len();
            }
            _ => {}
        }
        i += 1;
    }
    code.len()
}

/// The functions of one source file outside `#[cfg(test)]` items: `(name, line, length in
/// lines, doc comment)`. A function nested in another counts as part of it.
fn functions(text: &str) -> Vec<(String, usize, usize, String)> {
    let code = code_only(text);
    let line_of = |at: usize| 1 + code[..at].iter().filter(|&&c| c == b'\n').count();
    let lines: Vec<&str> = text.lines().collect();
    let ident = |c: u8| c.is_ascii_alphanumeric() || c == b'_';
    let mut out = Vec::new();
    let mut i = 0;
    while i < code.len() {
        if code[i..].starts_with(b"#[cfg(test)]") {
            i = item_end(&code, i + b"#[cfg(test)]".len());
            continue;
        }
        let keyword = code[i..].starts_with(b"fn ")
            && (i == 0 || !ident(code[i - 1]))
            && code.get(i + 3).is_some_and(|&c| ident(c));
        if !keyword {
            i += 1;
            continue;
        }
        let name: String = code[i + 3..]
            .iter()
            .take_while(|&&c| ident(c))
            .map(|&c| c as char)
            .collect();
        let end = item_end(&code, i);
        let (first, last) = (line_of(i), line_of(end - 1));
        let doc: Vec<&str> = lines[..first - 1]
            .iter()
            .rev()
            .map(|l| l.trim())
            .skip_while(|l| l.starts_with("#[") || l.starts_with("//") && !l.starts_with("///"))
            .take_while(|l| l.starts_with("///") || l.starts_with("#[") || l.starts_with("//"))
            .collect();
        let doc: Vec<&str> = doc
            .into_iter()
            .rev()
            .filter(|l| l.starts_with("///"))
            .collect();
        let doc = doc.join("\n");
        if code[end - 1] == b'}' {
            out.push((name, first, last - first + 1, doc));
        }
        i = end;
    }
    out
}

/// Issue 25: no library function over [`MAX_FUNCTION_LINES`] lines, except the numeric kernels
/// of [`KERNELS`], each citing its equations in its doc comment.
#[test]
fn no_library_function_is_over_80_lines() {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let mut long = Vec::new();
    let mut kernels_seen = Vec::new();
    let mut files = sources(&src);
    files.sort();
    for file in files {
        let relative = file
            .strip_prefix(&src)
            .unwrap()
            .to_string_lossy()
            .replace('\\', "/");
        // files of unit tests, included by `#[cfg(test)] mod tests;`
        if relative.ends_with("tests.rs") || relative.split('/').any(|p| p == "tests") {
            continue;
        }
        let text = fs::read_to_string(&file).unwrap();
        for (name, line, length, doc) in functions(&text) {
            if length <= MAX_FUNCTION_LINES {
                continue;
            }
            let is = |(f, n): (&str, &str)| f == relative && n == name;
            if let Some((_, _, cites)) = KERNELS.iter().find(|(f, n, _)| is((f, n))) {
                assert!(
                    doc.contains(cites),
                    "src/{relative}:{line}: the kernel {name} is allowed {length} lines for the \
                     equations it cites, but its doc comment does not cite {cites}"
                );
                kernels_seen.push((relative.clone(), name));
            } else {
                long.push(format!(
                    "src/{relative}:{line}: fn {name} is {length} lines (at most \
                     {MAX_FUNCTION_LINES}): split it by concept, or, for a numeric kernel that \
                     cites its equations, add it to KERNELS in tests/architecture.rs"
                ));
            }
        }
    }
    assert!(long.is_empty(), "functions too long:\n{}", long.join("\n"));
    for (file, name, _) in KERNELS {
        assert!(
            kernels_seen.iter().any(|(f, n)| f == file && n == name),
            "src/{file}: {name} is in KERNELS but is no longer over {MAX_FUNCTION_LINES} lines \
             (or is gone): take it off the list"
        );
    }
}

/// The scanner of the test above, on code written to trip it.
#[test]
fn the_function_scanner_counts_code_not_text() {
    let text = "/// Doc.\n/// Cites (A.1).\n#[inline]\npub(crate) fn first(x: [u8; 3]) -> u8 {\n    \
                let s = \"}\\\" {\";\n    let r = r#\"}\"}\"#;\n    let c = ('}', '\\'', '{');\n    // }\n    \
                /* } { */\n    fn inner<'a>(v: &'a str) -> &'a str {\n        v\n    }\n    x[0]\n}\n\
                fn declared(&self);\n#[cfg(test)]\nmod tests {\n    fn hidden() {\n    }\n}\n\
                const fn last() {}\n";
    let found = functions(text);
    let summary: Vec<(&str, usize, usize)> = found
        .iter()
        .map(|(n, line, len, _)| (n.as_str(), *line, *len))
        .collect();
    assert_eq!(summary, [("first", 4, 11), ("last", 21, 1)]);
    assert_eq!(found[0].3, "/// Doc.\n/// Cites (A.1).");
}
