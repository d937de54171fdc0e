//! The house's shape, checked: crates depend only on crates on a lower floor (so no arrow points
//! up and no two crates depend on each other), codec crates never on one another, and inside
//! every crate the modules import each other without a circle (README "Workspace").
//!
//! Reads the manifests and the sources of the workspace beside this crate; no build metadata
//! needed, so it runs in a second.

use std::collections::{BTreeMap, BTreeSet};
use std::fs;
use std::path::{Path, PathBuf};

fn workspace() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// Every workspace crate by folder: its package name and floor. A crate may depend only on
/// crates of a lower floor.
const FLOORS: &[(&str, &str, u8)] = &[
    ("codec-core", "codec-core", 0),
    // The synthetic animations: only the data model below them, beside the codecs.
    ("synth", "animcodec-synth", 1),
    ("codec-quant-delta", "codec-quant-delta", 1),
    ("codec-pca-aoi", "codec-pca-aoi", 1),
    ("codec-hosvd", "codec-hosvd", 1),
    ("codec-sac", "codec-sac", 1),
    ("codec-stseg", "codec-stseg", 1),
    ("metrics", "metrics", 1),
    ("io", "animcodec-io", 2),
    ("eval", "animcodec-eval", 3),
    ("animcodec", "animcodec", 4),
    ("cli", "animcodec-cli", 5),
    // The C library over the facade, beside the command line.
    ("capi", "animcodec-capi", 5),
    ("tests", "conformance-tests", 5),
    // The codec template `cargo xtask new-codec` copies: a codec crate like the others.
    ("xtask/template", "codec-template", 1),
    ("xtask", "xtask", 5),
];

/// [`FLOORS`] plus every other workspace member named `codec-*` (a codec made by the scaffold,
/// whose folder is its package name) on the codec floor.
fn floors(members_manifest: &str) -> Vec<(String, String, u8)> {
    let mut out: Vec<(String, String, u8)> =
        FLOORS.iter().map(|&(folder, package, floor)| (folder.to_owned(), package.to_owned(), floor)).collect();
    for member in workspace_members(members_manifest) {
        if member.starts_with("codec-") && !out.iter().any(|(folder, _, _)| *folder == member) {
            out.push((member.clone(), member, 1));
        }
    }
    out
}

/// The `members` list of the root manifest.
fn workspace_members(manifest: &str) -> Vec<String> {
    let block = manifest.split("members").nth(1).and_then(|s| s.split(']').next()).unwrap_or("");
    block.split('"').skip(1).step_by(2).map(str::to_owned).collect()
}

/// Names in the `[dependencies]` table of a manifest (not dev- or build-dependencies: a test
/// may use a crate above, as the harness's tests use codec crates).
fn normal_dependencies(manifest: &str) -> BTreeSet<String> {
    let mut out = BTreeSet::new();
    let mut inside = false;
    for line in manifest.lines() {
        let line = line.trim();
        if line.starts_with('[') {
            inside = line == "[dependencies]";
            continue;
        }
        if inside && !line.is_empty() && !line.starts_with('#') {
            let name = line.split(['=', '.', ' ']).next().unwrap_or("").trim();
            out.insert(name.to_owned());
        }
    }
    out
}

#[test]
fn crates_depend_only_on_lower_floors() {
    let root = workspace();
    let members = fs::read_to_string(root.join("Cargo.toml")).unwrap();
    let floors = floors(&members);
    let floor_of: BTreeMap<&str, u8> = floors.iter().map(|(_, package, floor)| (package.as_str(), *floor)).collect();
    let mut problems = Vec::new();
    for (folder, package, floor) in &floors {
        let manifest = fs::read_to_string(root.join(folder).join("Cargo.toml")).unwrap();
        assert!(manifest.contains(&format!("name = \"{package}\"")), "{folder}/Cargo.toml is not package {package}");
        for dep in normal_dependencies(&manifest) {
            if let Some(&dep_floor) = floor_of.get(dep.as_str()) {
                if dep_floor >= *floor {
                    problems.push(format!("{package} (floor {floor}) depends on {dep} (floor {dep_floor})"));
                }
            }
        }
    }
    // Every workspace member stands on a floor (a new crate must say where it stands), and
    // every crate listed is a member.
    let listed: BTreeSet<&str> = floors.iter().map(|(folder, _, _)| folder.as_str()).collect();
    let members = workspace_members(&members);
    for member in &members {
        if !listed.contains(member.as_str()) {
            problems.push(format!("workspace member {member} has no floor in tests/tests/architecture.rs"));
        }
    }
    for folder in listed {
        if !members.iter().any(|m| m == folder) {
            problems.push(format!("{folder} is not a workspace member: update FLOORS"));
        }
    }
    assert!(problems.is_empty(), "arrows pointing up or sideways:\n{}", problems.join("\n"));
}

/// The module of a source file: `src/a/b.rs` and `src/a/b/mod.rs` are `a::b`; `lib.rs` and
/// `main.rs` are the crate root (empty path).
fn module_of(src: &Path, file: &Path) -> Vec<String> {
    let rel = file.strip_prefix(src).unwrap().with_extension("");
    let mut parts: Vec<String> = rel.iter().map(|p| p.to_string_lossy().into_owned()).collect();
    if matches!(parts.last().map(String::as_str), Some("mod" | "lib" | "main")) {
        parts.pop();
    }
    parts
}

fn rust_files(dir: &Path, out: &mut Vec<PathBuf>) {
    for entry in fs::read_dir(dir).unwrap().flatten() {
        let path = entry.path();
        if path.is_dir() {
            rust_files(&path, out);
        } else if path.extension().is_some_and(|e| e == "rs") {
            out.push(path);
        }
    }
}

/// Paths a source names through `crate::a::b…` or `super::a…` (resolved against `module`),
/// outside comments and outside its `#[cfg(test)] mod tests` (tests may look anywhere).
fn named_paths(text: &str, module: &[String]) -> Vec<Vec<String>> {
    let code = text.split("#[cfg(test)]\nmod tests").next().unwrap_or(text);
    let mut out = Vec::new();
    for line in code.lines() {
        let line = line.split("//").next().unwrap_or("");
        for (prefix, base) in [("crate::", Vec::new()), ("super::", module[..module.len().saturating_sub(1)].to_vec())]
        {
            let mut rest = line;
            while let Some(at) = rest.find(prefix) {
                let preceded_by_ident =
                    rest[..at].chars().next_back().is_some_and(|c| c.is_alphanumeric() || c == '_' || c == ':');
                rest = &rest[at + prefix.len()..];
                if preceded_by_ident {
                    continue;
                }
                if let Some(group) = rest.strip_prefix('{') {
                    // `super::{a, b::c}`: each first segment.
                    let inner = group.split('}').next().unwrap_or("");
                    for item in inner.split(',') {
                        let first = item.trim().split("::").next().unwrap_or("").trim();
                        if !first.is_empty() && first != "self" {
                            out.push([base.clone(), vec![first.to_owned()]].concat());
                        }
                    }
                    continue;
                }
                let path: Vec<String> = rest
                    .split(|c: char| !(c.is_alphanumeric() || c == '_' || c == ':'))
                    .next()
                    .unwrap_or("")
                    .split("::")
                    .filter(|s| !s.is_empty())
                    .map(str::to_owned)
                    .collect();
                if !path.is_empty() {
                    out.push([base.clone(), path].concat());
                }
            }
        }
    }
    out
}

/// Groups of modules that import each other, directly or around a circle (Tarjan's strongly
/// connected components of size > 1).
fn circles(graph: &BTreeMap<String, BTreeSet<String>>) -> Vec<Vec<String>> {
    struct State<'a> {
        graph: &'a BTreeMap<String, BTreeSet<String>>,
        index: BTreeMap<&'a str, usize>,
        low: BTreeMap<&'a str, usize>,
        stack: Vec<&'a str>,
        next: usize,
        found: Vec<Vec<String>>,
    }
    fn visit<'a>(s: &mut State<'a>, v: &'a str) {
        s.index.insert(v, s.next);
        s.low.insert(v, s.next);
        s.next += 1;
        s.stack.push(v);
        for w in s.graph.get(v).into_iter().flatten() {
            let w = w.as_str();
            if !s.index.contains_key(w) {
                visit(s, w);
                let lw = s.low[w];
                s.low.entry(v).and_modify(|l| *l = (*l).min(lw));
            } else if s.stack.contains(&w) {
                let iw = s.index[w];
                s.low.entry(v).and_modify(|l| *l = (*l).min(iw));
            }
        }
        if s.low[v] == s.index[v] {
            let mut group = Vec::new();
            while let Some(w) = s.stack.pop() {
                group.push(w.to_owned());
                if w == v {
                    break;
                }
            }
            if group.len() > 1 {
                group.sort();
                s.found.push(group);
            }
        }
    }
    let mut s =
        State { graph, index: BTreeMap::new(), low: BTreeMap::new(), stack: Vec::new(), next: 0, found: Vec::new() };
    for v in graph.keys() {
        if !s.index.contains_key(v.as_str()) {
            visit(&mut s, v);
        }
    }
    s.found
}

/// The module-import graph of one crate: an edge from each module to each other module whose
/// items it names, a parent naming its child's items included (a child naming its parent's
/// items is not an edge, except to the crate root).
fn module_graph(src: &Path) -> BTreeMap<String, BTreeSet<String>> {
    let mut files = Vec::new();
    rust_files(src, &mut files);
    let modules: BTreeSet<Vec<String>> = files.iter().map(|f| module_of(src, f)).collect();
    let mut graph: BTreeMap<String, BTreeSet<String>> = BTreeMap::new();
    for file in &files {
        let module = module_of(src, file);
        let text = fs::read_to_string(file).unwrap();
        let entry = graph.entry(module.join("::")).or_default();
        for path in named_paths(&text, &module) {
            // The longest module prefix of the path is the module it names.
            let Some(target) = (1..=path.len()).rev().map(|k| path[..k].to_vec()).find(|p| modules.contains(p)) else {
                continue;
            };
            // A child naming its parent's items is inside that room; the crate root is not a
            // parent to lean on (a module naming the root's items is an edge to it).
            let inside_parent = !target.is_empty() && module.starts_with(&target);
            if target != module && !inside_parent {
                entry.insert(target.join("::"));
            }
        }
    }
    graph
}

#[test]
fn modules_import_each_other_without_circles() {
    let root = workspace();
    let mut problems = Vec::new();
    let members = fs::read_to_string(root.join("Cargo.toml")).unwrap();
    for (folder, _, _) in floors(&members) {
        for group in circles(&module_graph(&root.join(&folder).join("src"))) {
            problems.push(format!("{folder}: {}", group.join(" ↔ ")));
        }
    }
    assert!(problems.is_empty(), "modules importing each other:\n{}", problems.join("\n"));
}

/// The front ends (the command line and the Python extension) reach the library through the
/// `animcodec` facade only: no direct dependency on a crate below it.
#[test]
fn front_ends_depend_on_the_facade_only() {
    let root = workspace();
    let members = fs::read_to_string(root.join("Cargo.toml")).unwrap();
    let below: BTreeSet<String> =
        floors(&members).into_iter().filter(|(_, _, floor)| *floor < 4).map(|(_, package, _)| package).collect();
    let mut problems = Vec::new();
    for front in ["cli", "python"] {
        let manifest = fs::read_to_string(root.join(front).join("Cargo.toml")).unwrap();
        let deps = normal_dependencies(&manifest);
        assert!(deps.contains("animcodec"), "{front} does not depend on the facade: {deps:?}");
        for dep in deps.intersection(&below) {
            problems.push(format!("{front} depends on {dep} directly: use animcodec::… instead"));
        }
    }
    assert!(problems.is_empty(), "{}", problems.join("\n"));
}

/// No module of a binary names an item of its root (`main.rs`): the root calls the modules,
/// the modules own their arguments and never call back.
#[test]
fn binary_modules_do_not_import_their_root() {
    let root = workspace();
    let mut problems = Vec::new();
    for folder in ["cli", "xtask"] {
        let src = root.join(folder).join("src");
        if !src.join("main.rs").is_file() {
            continue;
        }
        let mut files = Vec::new();
        rust_files(&src, &mut files);
        let modules: BTreeSet<Vec<String>> = files.iter().map(|f| module_of(&src, f)).collect();
        for file in &files {
            let module = module_of(&src, file);
            if module.is_empty() {
                continue;
            }
            let text = fs::read_to_string(file).unwrap();
            for path in named_paths(&text, &module) {
                let target = (1..=path.len()).rev().map(|k| path[..k].to_vec()).find(|p| modules.contains(p));
                if target.is_none_or(|t| t.is_empty()) {
                    problems.push(format!("{folder}: {} names crate::{}", module.join("::"), path.join("::")));
                }
            }
        }
    }
    assert!(problems.is_empty(), "modules of a binary importing its root:\n{}", problems.join("\n"));
}

#[test]
fn the_circle_finder_finds_a_circle() {
    let graph: BTreeMap<String, BTreeSet<String>> = [
        ("a".to_owned(), BTreeSet::from(["b".to_owned()])),
        ("b".to_owned(), BTreeSet::from(["c".to_owned()])),
        ("c".to_owned(), BTreeSet::from(["a".to_owned()])),
        ("d".to_owned(), BTreeSet::from(["a".to_owned()])),
    ]
    .into();
    assert_eq!(circles(&graph), vec![vec!["a".to_owned(), "b".to_owned(), "c".to_owned()]]);
    let module = vec!["formats".to_owned(), "gltf_scene".to_owned()];
    assert_eq!(
        named_paths("use super::gltf_buffers::{bad, Budget};\nuse crate::output::x; // crate::no", &module),
        vec![vec!["formats".to_owned(), "gltf_buffers".to_owned()], vec!["output".to_owned(), "x".to_owned()]]
    );
    assert_eq!(
        named_paths("use super::{check, name};", &module),
        vec![vec!["formats".to_owned(), "check".to_owned()], vec!["formats".to_owned(), "name".to_owned()]]
    );
}
