//! `docs/architecture.md`'s crate graph is the one the manifests declare, and runs one way; no
//! module of a crate imports one that imports it back.
#![allow(clippy::indexing_slicing, reason = "test helpers: an index out of range fails the test, as it should")]
#![allow(clippy::unwrap_used)] // tests fail loudly by design

use std::collections::BTreeMap;
use std::path::Path;

fn repo() -> &'static Path {
    Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/.."))
}

/// Each crate's name and the crates of ours in its `[dependencies]`, as the doc lists them.
fn documented() -> Vec<(String, Vec<String>)> {
    let doc = std::fs::read_to_string(repo().join("docs/architecture.md")).unwrap();
    let graph = doc.split("## The crate graph").nth(1).unwrap().split("```text").nth(1).unwrap().split("```").next().unwrap();
    graph
        .lines()
        .filter_map(|l| l.split_once("->"))
        .map(|(name, deps)| {
            let deps = deps.split(',').map(str::trim).filter(|d| !d.is_empty()).map(str::to_owned).collect();
            (name.trim().to_owned(), deps)
        })
        .collect()
}

/// The same, from every workspace member's `Cargo.toml`.
fn declared() -> BTreeMap<String, Vec<String>> {
    let workspace: toml::Table = std::fs::read_to_string(repo().join("Cargo.toml")).unwrap().parse().unwrap();
    let members = workspace["workspace"]["members"].as_array().unwrap();
    members
        .iter()
        .map(|member| {
            let manifest: toml::Table =
                std::fs::read_to_string(repo().join(member.as_str().unwrap()).join("Cargo.toml")).unwrap().parse().unwrap();
            let name = manifest["package"]["name"].as_str().unwrap().to_owned();
            // `[dependencies]` and every `[target.'cfg(..)'.dependencies]`.
            let mut tables: Vec<&toml::Value> = manifest.get("dependencies").into_iter().collect();
            if let Some(targets) = manifest.get("target").and_then(toml::Value::as_table) {
                tables.extend(targets.values().filter_map(|t| t.get("dependencies")));
            }
            let mut deps: Vec<String> =
                tables.iter().filter_map(|t| t.as_table()).flat_map(|t| t.keys().filter(|k| k.starts_with("mimicgen-")).cloned()).collect();
            deps.sort();
            deps.dedup();
            (name, deps)
        })
        .collect()
}

#[test]
fn the_documented_crate_graph_is_the_declared_one_and_points_down() {
    let documented = documented();
    let declared = declared();
    let listed: BTreeMap<String, Vec<String>> = documented.iter().cloned().collect();
    assert_eq!(listed, declared, "docs/architecture.md's crate graph and the manifests differ");
    for (i, (name, deps)) in documented.iter().enumerate() {
        for dep in deps {
            assert!(
                documented[..i].iter().any(|(above, _)| above == dep),
                "{name} depends on {dep}, which the doc lists below it: the graph must only point down"
            );
        }
    }
}

/// Every `.rs` file below `dir`, as (module path, text without comment lines and tests).
fn modules(dir: &Path, src: &Path, out: &mut BTreeMap<String, String>) {
    for entry in std::fs::read_dir(dir).unwrap() {
        let path = entry.unwrap().path();
        if path.is_dir() {
            modules(&path, src, out);
        } else if path.extension().is_some_and(|e| e == "rs") {
            let relative = path.strip_prefix(src).unwrap().with_extension("");
            let name = relative.to_string_lossy().replace('/', "::");
            let name = name.strip_suffix("::mod").unwrap_or(&name).to_owned();
            let text = std::fs::read_to_string(&path).unwrap();
            let code = text.split("#[cfg(test)]\nmod tests").next().unwrap_or_default();
            let code: Vec<&str> = code.lines().filter(|l| !l.trim_start().starts_with("//")).collect();
            out.insert(name, code.join("\n"));
        }
    }
}

/// The modules of the crate at `src` that each module names (`crate::x`, `super::x`).
fn module_graph(src: &Path) -> BTreeMap<String, Vec<String>> {
    let mut texts = BTreeMap::new();
    modules(src, src, &mut texts);
    let known = |path: &[&str]| (1..=path.len()).rev().map(|k| path[..k].join("::")).find(|c| texts.contains_key(c));
    texts
        .iter()
        .map(|(name, text)| {
            let parent: Vec<&str> = name.split("::").collect();
            let parent = &parent[..parent.len() - 1];
            let mut uses: Vec<String> = Vec::new();
            for (prefix, base) in [("crate::", &[][..]), ("super::", parent)] {
                for piece in text.split(prefix).skip(1) {
                    let path: Vec<&str> = piece
                        .split(|c: char| !(c.is_ascii_alphanumeric() || c == '_' || c == ':'))
                        .next()
                        .unwrap_or("")
                        .split("::")
                        .filter(|p| !p.is_empty())
                        .collect();
                    let full: Vec<&str> = base.iter().copied().chain(path).collect();
                    if let Some(m) = known(&full).filter(|m| m != name && m != "lib" && m != "main") {
                        uses.push(m);
                    }
                }
            }
            uses.sort();
            uses.dedup();
            (name.clone(), uses)
        })
        .collect()
}

/// A module never imports one that imports it back (`docs/architecture.md`): a circle means two
/// files are one idea, or one idea is split wrong.
#[test]
fn no_module_imports_one_that_imports_it_back() {
    let workspace: toml::Table = std::fs::read_to_string(repo().join("Cargo.toml")).unwrap().parse().unwrap();
    let mut circles = Vec::new();
    for member in workspace["workspace"]["members"].as_array().unwrap() {
        let src = repo().join(member.as_str().unwrap()).join("src");
        let graph = module_graph(&src);
        // A circle exists when a module reaches itself; report each module on one once.
        for start in graph.keys() {
            let mut seen = std::collections::BTreeSet::new();
            let mut stack: Vec<(String, Vec<String>)> = graph[start].iter().map(|m| (m.clone(), vec![start.clone(), m.clone()])).collect();
            while let Some((at, path)) = stack.pop() {
                if at == *start {
                    circles.push(format!("{}: {}", member.as_str().unwrap(), path.join(" -> ")));
                    break;
                }
                if seen.insert(at.clone()) {
                    stack.extend(
                        graph.get(&at).into_iter().flatten().map(|m| (m.clone(), path.iter().cloned().chain([m.clone()]).collect())),
                    );
                }
            }
        }
    }
    assert!(circles.is_empty(), "import circles:\n{}", circles.join("\n"));
}
