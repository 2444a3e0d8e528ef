//! The layout rules of ARCHITECTURE.md, checked on the source tree:
//! - no source file over 800 lines, tests excluded (a file named
//!   `tests.rs` or under a `tests/` folder, and everything after a file's
//!   `#[cfg(test)]` module);
//! - the compiler's stage modules (`compiler/src/<stage>/`) import each
//!   other without a cycle, and only through stage paths (`crate::<stage>`).

use std::collections::{BTreeMap, BTreeSet};
use std::fs;
use std::path::{Path, PathBuf};

/// The longest a source file may be, tests excluded.
const MAX_LINES: usize = 800;

/// The workspace's source folders.
const SOURCE_DIRS: [&str; 4] = ["compiler/src", "runtime/src", "lab/src", "src"];

fn rust_files(dir: &Path, out: &mut Vec<PathBuf>) {
    let Ok(entries) = fs::read_dir(dir) else { return };
    let mut entries: Vec<_> = entries.flatten().map(|e| e.path()).collect();
    entries.sort();
    for path in entries {
        if path.is_dir() {
            rust_files(&path, out);
        } else if path.extension().is_some_and(|e| e == "rs") {
            out.push(path);
        }
    }
}

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn is_test_file(path: &Path) -> bool {
    path.file_name().is_some_and(|n| n == "tests.rs") || path.components().any(|c| c.as_os_str() == "tests")
}

/// Lines of `text` before its first `#[cfg(test)]` (the whole text if none).
fn lines_outside_tests(text: &str) -> usize {
    text.lines().take_while(|l| l.trim() != "#[cfg(test)]").count()
}

#[test]
fn no_source_file_is_longer_than_the_limit() {
    let mut files = Vec::new();
    for dir in SOURCE_DIRS {
        rust_files(&root().join(dir), &mut files);
    }
    assert!(files.len() > 50, "found only {} source files under {SOURCE_DIRS:?}", files.len());
    let long: Vec<String> = files
        .iter()
        .filter(|f| !is_test_file(f))
        .filter_map(|f| {
            let n = lines_outside_tests(&fs::read_to_string(f).unwrap());
            (n > MAX_LINES).then(|| format!("{} ({n} lines)", f.strip_prefix(root()).unwrap().display()))
        })
        .collect();
    assert!(long.is_empty(), "source files over {MAX_LINES} lines outside tests: {long:?}");
}

/// For each stage module of the compiler, the other stage modules its
/// files name as `crate::<module>`; `Err` lists paths that name no stage.
fn stage_imports() -> Result<BTreeMap<String, BTreeSet<String>>, Vec<String>> {
    let src = root().join("compiler/src");
    let stages: BTreeSet<String> = fs::read_dir(&src)
        .unwrap()
        .flatten()
        .map(|e| e.path())
        .filter(|p| p.file_name().unwrap() != "lib.rs")
        .map(|p| p.file_stem().unwrap().to_string_lossy().into_owned())
        .collect();
    let mut graph: BTreeMap<String, BTreeSet<String>> = stages.iter().map(|s| (s.clone(), BTreeSet::new())).collect();
    let mut stray = Vec::new();
    for stage in &stages {
        let mut files = Vec::new();
        let dir = src.join(stage);
        if dir.is_dir() {
            rust_files(&dir, &mut files);
        } else {
            files.push(src.join(format!("{stage}.rs")));
        }
        for file in files {
            let text = fs::read_to_string(&file).unwrap();
            for (at, _) in text.match_indices("crate::") {
                let name: String = text[at + 7..].chars().take_while(|c| c.is_ascii_alphanumeric() || *c == '_').collect();
                if name.chars().next().is_some_and(|c| c.is_ascii_uppercase()) {
                    continue; // an item re-exported at the root, such as `crate::Program`
                }
                if stages.contains(&name) {
                    if name != *stage {
                        graph.get_mut(stage).unwrap().insert(name);
                    }
                } else {
                    stray.push(format!("{}: crate::{name}", file.strip_prefix(&src).unwrap().display()));
                }
            }
        }
    }
    if stray.is_empty() {
        Ok(graph)
    } else {
        Err(stray)
    }
}

/// A cycle in `graph`, if there is one (as the list of its nodes).
fn find_cycle(graph: &BTreeMap<String, BTreeSet<String>>) -> Option<Vec<String>> {
    fn visit(
        node: &str,
        graph: &BTreeMap<String, BTreeSet<String>>,
        path: &mut Vec<String>,
        done: &mut BTreeSet<String>,
    ) -> Option<Vec<String>> {
        if let Some(i) = path.iter().position(|n| n == node) {
            return Some(path[i..].iter().cloned().chain([node.to_string()]).collect());
        }
        if done.contains(node) {
            return None;
        }
        path.push(node.to_string());
        for next in &graph[node] {
            if let Some(c) = visit(next, graph, path, done) {
                return Some(c);
            }
        }
        path.pop();
        done.insert(node.to_string());
        None
    }
    let mut done = BTreeSet::new();
    graph.keys().find_map(|n| visit(n, graph, &mut Vec::new(), &mut done))
}

#[test]
fn compiler_stages_import_each_other_without_a_cycle() {
    let graph = stage_imports().unwrap_or_else(|stray| panic!("paths that name no stage module: {stray:?}"));
    for stage in ["front", "check", "ir", "passes", "codegen", "kernels", "driver"] {
        assert!(graph.contains_key(stage), "no stage `{stage}` in compiler/src: {:?}", graph.keys());
    }
    // The front end and the IR are the bottom layers.
    assert!(graph["front"].is_empty(), "front imports {:?}", graph["front"]);
    assert!(graph["ir"].is_empty(), "ir imports {:?}", graph["ir"]);
    assert_eq!(find_cycle(&graph), None, "import graph: {graph:?}");
}

#[test]
fn the_cycle_finder_finds_a_cycle() {
    let edges = [("a", "b"), ("b", "c"), ("c", "a"), ("c", "d")];
    let mut graph: BTreeMap<String, BTreeSet<String>> = BTreeMap::new();
    for (from, to) in edges {
        graph.entry(from.into()).or_default().insert(to.into());
        graph.entry(to.into()).or_default();
    }
    assert_eq!(find_cycle(&graph), Some(vec!["a".into(), "b".into(), "c".into(), "a".into()]));
    graph.get_mut("c").unwrap().remove("a");
    assert_eq!(find_cycle(&graph), None);
}
