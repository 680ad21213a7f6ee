//! The layout the workspace keeps in the crates that grew fastest (reduced-sim, freeform, eval):
//! no source file over 600 lines and no function over 120, in the library, its tests and its
//! examples alike.
//!
//! Functions are measured on rustfmt's layout: from the line of `fn` to the first line after it
//! that is a closing brace at the same indentation. A declaration without a body (a trait
//! method ending in `;`) is not a function here.

use std::path::{Path, PathBuf};

const CRATES: [&str; 3] = ["reduced-sim", "freeform", "eval"];
const MAX_FILE_LINES: usize = 600;
const MAX_FUNCTION_LINES: usize = 120;

fn rust_files(dir: &Path, out: &mut Vec<PathBuf>) {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    for entry in entries.flatten() {
        let path = entry.path();
        if path.is_dir() {
            rust_files(&path, out);
        } else if path.extension().is_some_and(|e| e == "rs") {
            out.push(path);
        }
    }
}

fn workspace_files() -> Vec<PathBuf> {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let mut files = Vec::new();
    for krate in CRATES {
        for part in ["src", "tests", "examples"] {
            rust_files(&root.join(krate).join(part), &mut files);
        }
    }
    files.sort();
    files
}

/// The indentation of `line` if it starts a function (`fn`, after `pub`, `pub(crate)`,
/// `const`, `async`, `unsafe`).
fn function_start(line: &str) -> Option<&str> {
    let trimmed = line.trim_start();
    let indent = &line[..line.len() - trimmed.len()];
    let mut rest = trimmed;
    for qualifier in [
        "pub(crate) ",
        "pub(super) ",
        "pub ",
        "const ",
        "async ",
        "unsafe ",
    ] {
        rest = rest.strip_prefix(qualifier).unwrap_or(rest);
    }
    rest.starts_with("fn ").then_some(indent)
}

/// (first line, length in lines, signature) of every function with a body in `text`.
fn functions(text: &str) -> Vec<(usize, usize, String)> {
    let lines: Vec<&str> = text.lines().collect();
    let mut found = Vec::new();
    let mut i = 0;
    while i < lines.len() {
        let Some(indent) = function_start(lines[i]) else {
            i += 1;
            continue;
        };
        // The signature ends at the first line ending in `{` (a body) or `;` (none).
        let Some(open) = (i..lines.len()).find(|&j| {
            let l = lines[j].trim_end();
            l.ends_with('{') || l.ends_with(';')
        }) else {
            break;
        };
        if !lines[open].trim_end().ends_with('{') {
            i = open + 1;
            continue;
        }
        let close_line = format!("{indent}}}");
        let close = (open + 1..lines.len())
            .find(|&k| lines[k] == close_line)
            .unwrap_or(lines.len() - 1);
        found.push((i + 1, close - i + 1, lines[i].trim().to_string()));
        i += 1;
    }
    found
}

#[test]
fn the_function_finder_measures_a_body_and_skips_a_declaration() {
    let text = "trait T {\n    fn declared(&self);\n}\n\npub(crate) fn three(\n    x: u8,\n) -> u8 {\n    x\n}\n";
    assert_eq!(
        functions(text),
        vec![(5, 5, "pub(crate) fn three(".to_string())]
    );
}

#[test]
fn no_file_exceeds_600_lines_and_no_function_120_in_reduced_sim_freeform_and_eval() {
    let files = workspace_files();
    assert!(
        files.len() > 100,
        "found only {} source files: the crates moved?",
        files.len()
    );
    let mut problems = Vec::new();
    for path in &files {
        let text = std::fs::read_to_string(path).unwrap();
        let lines = text.lines().count();
        if lines > MAX_FILE_LINES {
            problems.push(format!("{}: {lines} lines", path.display()));
        }
        for (line, length, signature) in functions(&text) {
            if length > MAX_FUNCTION_LINES {
                problems.push(format!(
                    "{}:{line}: `{signature}` is {length} lines",
                    path.display()
                ));
            }
        }
    }
    assert!(problems.is_empty(), "{}", problems.join("\n"));
}

/// The top-level modules of `krate` (files and folders of `src/` but `lib.rs`, `main.rs`,
/// `bin/`) and, for each, the other top-level modules its files name as `crate::…` outside
/// comments and their unit-test modules.
fn module_graph(
    krate: &str,
) -> std::collections::BTreeMap<String, std::collections::BTreeSet<String>> {
    let src = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("..")
        .join(krate)
        .join("src");
    let mut modules = std::collections::BTreeMap::new();
    for entry in std::fs::read_dir(&src).unwrap().flatten() {
        let name = entry.file_name().to_string_lossy().into_owned();
        let module = match name.strip_suffix(".rs") {
            Some("lib" | "main") => continue,
            Some(stem) => stem.to_string(),
            None if name == "bin" => continue,
            None => name,
        };
        modules.insert(module, std::collections::BTreeSet::new());
    }
    let names: Vec<String> = modules.keys().cloned().collect();
    for module in &names {
        let mut files = Vec::new();
        let file = src.join(format!("{module}.rs"));
        if file.exists() {
            files.push(file);
        }
        rust_files(&src.join(module), &mut files);
        for file in files {
            let text = std::fs::read_to_string(&file).unwrap();
            let text = text
                .split("#[cfg(test)]\nmod tests")
                .next()
                .unwrap_or_default();
            for line in text.lines().filter(|l| !l.trim_start().starts_with("//")) {
                for (at, _) in line.match_indices("crate::") {
                    let rest = &line[at + "crate::".len()..];
                    let used: String = rest
                        .chars()
                        .take_while(|c| c.is_ascii_alphanumeric() || *c == '_')
                        .collect();
                    if &used != module && names.contains(&used) {
                        modules.get_mut(module).unwrap().insert(used);
                    }
                }
            }
        }
    }
    modules
}

/// A circle in `graph`, if any, as the modules along it.
fn circle(
    graph: &std::collections::BTreeMap<String, std::collections::BTreeSet<String>>,
) -> Option<Vec<String>> {
    fn visit(
        graph: &std::collections::BTreeMap<String, std::collections::BTreeSet<String>>,
        node: &str,
        path: &mut Vec<String>,
        done: &mut std::collections::BTreeSet<String>,
    ) -> Option<Vec<String>> {
        if let Some(at) = path.iter().position(|n| n == node) {
            let mut found = path[at..].to_vec();
            found.push(node.to_string());
            return Some(found);
        }
        if done.contains(node) {
            return None;
        }
        path.push(node.to_string());
        for next in &graph[node] {
            if let Some(found) = visit(graph, next, path, done) {
                return Some(found);
            }
        }
        path.pop();
        done.insert(node.to_string());
        None
    }
    let mut done = std::collections::BTreeSet::new();
    graph
        .keys()
        .find_map(|start| visit(graph, start, &mut Vec::new(), &mut done))
}

#[test]
fn the_circle_finder_finds_a_circle_and_none_in_a_chain() {
    let graph = |edges: &[(&str, &str)]| {
        let mut g = std::collections::BTreeMap::<String, std::collections::BTreeSet<String>>::new();
        for (a, b) in edges {
            g.entry(a.to_string()).or_default().insert(b.to_string());
            g.entry(b.to_string()).or_default();
        }
        g
    };
    assert_eq!(circle(&graph(&[("a", "b"), ("b", "c")])), None);
    assert_eq!(
        circle(&graph(&[("a", "b"), ("b", "c"), ("c", "a")])),
        Some(vec!["a".into(), "b".into(), "c".into(), "a".into()])
    );
}

#[test]
fn no_import_circle_between_the_top_level_modules_of_reduced_sim_freeform_and_eval() {
    for krate in CRATES {
        let graph = module_graph(krate);
        assert!(
            graph.len() > 5,
            "{krate}: only {} modules found",
            graph.len()
        );
        assert_eq!(circle(&graph), None, "{krate}");
    }
}

#[test]
fn the_eval_experiments_import_the_common_layer_and_never_each_other() {
    const EXPERIMENTS: [&str; 7] = [
        "ablation",
        "beam",
        "bench",
        "convergence",
        "pins",
        "shapes",
        "stress",
    ];
    let graph = module_graph("eval");
    // The scanner sees imports at all: Table 1 renders through the report layer.
    assert!(graph["beam"].contains("report"), "{:?}", graph["beam"]);
    for experiment in EXPERIMENTS {
        let imported = &graph[experiment];
        let others: Vec<&String> = imported
            .iter()
            .filter(|m| EXPERIMENTS.contains(&m.as_str()))
            .collect();
        assert!(others.is_empty(), "{experiment} imports {others:?}");
    }
}
