//! `docs/architecture.md`'s crate graph is the one the manifests declare, and runs one way.
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
