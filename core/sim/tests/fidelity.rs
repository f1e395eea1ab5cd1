//! Our task files against the reference's numbers (`docs/fidelity.toml`, described in
//! `docs/fidelity.md`): every row names a value of the reference's code (with its citation) and
//! the field of our task or spec file that must hold it. A row marked `same` fails when our file
//! drifts from the reference; a row marked `differs` must say why, and fails once the two agree
//! (so the table never claims a difference that is gone).
#![allow(clippy::unwrap_used)] // tests fail loudly by design

use std::path::{Path, PathBuf};

use toml::Value;

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// The value at `path` in `doc`: dot-separated keys; `[i]` indexes an array, `[name]` picks the
/// table of an array whose `name` is `name`.
fn lookup<'a>(doc: &'a Value, path: &str) -> Result<&'a Value, String> {
    let mut here = doc;
    for part in path.split('.') {
        let (key, index) = match part.split_once('[') {
            Some((key, rest)) => (key, Some(rest.strip_suffix(']').ok_or_else(|| format!("{part}: unclosed ["))?)),
            None => (part, None),
        };
        here = here.get(key).ok_or_else(|| format!("no field {key:?} (in {path})"))?;
        if let Some(index) = index {
            let items = here.as_array().ok_or_else(|| format!("{key} is not an array (in {path})"))?;
            here = match index.parse::<usize>() {
                Ok(i) => items.get(i).ok_or_else(|| format!("{key}[{i}]: only {} items (in {path})", items.len()))?,
                Err(_) => items
                    .iter()
                    .find(|item| item.get("name").and_then(Value::as_str) == Some(index))
                    .ok_or_else(|| format!("{key}: none named {index:?} (in {path})"))?,
            };
        }
    }
    Ok(here)
}

/// Numbers compare within `tol` (integers and floats alike); lists item by item; the rest exactly.
fn agree(ours: &Value, reference: &Value, tol: f64) -> bool {
    let number = |v: &Value| v.as_float().or_else(|| v.as_integer().map(|i| i as f64));
    match (number(ours), number(reference)) {
        (Some(a), Some(b)) => (a - b).abs() <= tol,
        _ => match (ours.as_array(), reference.as_array()) {
            (Some(a), Some(b)) => a.len() == b.len() && a.iter().zip(b).all(|(x, y)| agree(x, y, tol)),
            _ => ours == reference,
        },
    }
}

struct Row {
    label: String,
    file: String,
    field: String,
    reference: Value,
    tol: f64,
    status: String,
    why: Option<String>,
}

fn rows(table: &Value) -> Vec<Row> {
    let values = table.get("value").and_then(Value::as_array).expect("docs/fidelity.toml: [[value]] rows");
    values
        .iter()
        .enumerate()
        .filter_map(|(i, row)| {
            let text = |key: &str| row.get(key).and_then(Value::as_str).map(str::to_owned);
            let label = format!(
                "value[{i}] ({} {} {})",
                text("task").unwrap_or_default(),
                text("variant").unwrap_or_default(),
                text("what").unwrap_or_default()
            );
            for key in ["task", "what", "repo", "commit", "file", "lines"] {
                assert!(
                    text(key).is_some_and(|s| !s.is_empty()),
                    "{label}: no {key} (every value is cited: repository, commit, file, lines)"
                );
            }
            // A full hash, or a release tag (robosuite's rows: its v1.4.1 release as PyPI ships it).
            let commit = text("commit").unwrap_or_default();
            let hash = commit.len() == 40 && commit.chars().all(|c| c.is_ascii_hexdigit());
            let tag = commit.strip_prefix('v').is_some_and(|v| v.split('.').count() == 3 && v.split('.').all(|n| n.parse::<u32>().is_ok()));
            assert!(hash || tag, "{label}: commit {commit:?} is neither a full hash nor a release tag");
            let reference = row.get("value").cloned().unwrap_or_else(|| panic!("{label}: no value"));
            // A row without `ours` documents a number with no field of ours to hold it.
            let ours = text("ours")?;
            let (file, field) = ours.split_once(':').unwrap_or_else(|| panic!("{label}: ours = {ours:?}, want FILE:FIELD"));
            Some(Row {
                label,
                file: file.to_owned(),
                field: field.to_owned(),
                reference,
                tol: row.get("tol").and_then(Value::as_float).unwrap_or(1e-9),
                status: text("status").unwrap_or_else(|| "same".to_owned()),
                why: text("why"),
            })
        })
        .collect()
}

fn check(table: &Value, tasks: &Path) -> Vec<String> {
    let mut problems = Vec::new();
    // Each task file read and parsed once, however many rows name it.
    let mut docs = std::collections::BTreeMap::<String, Value>::new();
    for row in rows(table) {
        let doc = docs.entry(row.file.clone()).or_insert_with(|| {
            let path = tasks.join(&row.file);
            let text = std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{}: {}: {e}", row.label, path.display()));
            toml::from_str(&text).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
        });
        let ours = match lookup(doc, &row.field) {
            Ok(v) => v,
            Err(e) => {
                problems.push(format!("{}: {}: {e}", row.label, row.file));
                continue;
            }
        };
        let same = agree(ours, &row.reference, row.tol);
        match row.status.as_str() {
            "same" if !same => {
                problems.push(format!("{}: {}:{} is {ours}, the reference's is {}", row.label, row.file, row.field, row.reference));
            }
            "differs" if same => problems.push(format!(
                "{}: {}:{} now equals the reference's {}: mark the row `same`",
                row.label, row.file, row.field, row.reference
            )),
            "differs" if row.why.as_deref().is_none_or(str::is_empty) => problems.push(format!("{}: a difference must say why", row.label)),
            "same" | "differs" => {}
            other => problems.push(format!("{}: status {other:?}, want same or differs", row.label)),
        }
    }
    problems
}

fn table() -> Value {
    let path = root().join("docs/fidelity.toml");
    toml::from_str(&std::fs::read_to_string(&path).unwrap()).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

#[test]
fn our_task_files_hold_the_reference_numbers() {
    let table = table();
    let problems = check(&table, &root().join("core/sim/tasks"));
    assert!(problems.is_empty(), "docs/fidelity.toml against core/sim/tasks:\n{}", problems.join("\n"));
    assert!(rows(&table).len() >= 40, "the table checks only {} fields", rows(&table).len());
}

/// The check bites: a copy of the task files with one offset, one region and one threshold moved
/// fails on exactly those rows.
#[test]
fn a_drifted_task_file_fails_the_check() {
    let dir = std::env::temp_dir().join(format!("fidelity-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    for entry in std::fs::read_dir(root().join("core/sim/tasks")).unwrap() {
        let entry = entry.unwrap();
        std::fs::copy(entry.path(), dir.join(entry.file_name())).unwrap();
    }
    let edit = |file: &str, from: &str, to: &str| {
        let path = dir.join(file);
        let text = std::fs::read_to_string(&path).unwrap();
        assert!(text.contains(from), "{file}: no {from:?}");
        std::fs::write(&path, text.replacen(from, to, 1)).unwrap();
    };
    edit("threading.toml", "term_offset_range = [5, 10]", "term_offset_range = [10, 20]");
    edit("stack.task.toml", "place.D1 = { x = [-0.2, 0.2]", "place.D1 = { x = [-0.25, 0.2]");
    let problems = check(&table(), &dir);
    std::fs::remove_dir_all(&dir).unwrap();
    assert_eq!(problems.len(), 2, "{problems:#?}");
    assert!(problems[0].contains("threading") || problems[1].contains("threading"), "{problems:#?}");
    assert!(problems.iter().any(|p| p.contains("stack.task.toml:object[cubeA].place.D1.x")), "{problems:#?}");
}

#[test]
fn lookup_follows_keys_indices_and_names() {
    let doc: Value = toml::from_str("[[object]]\nname = \"a\"\nx = [1, 2]\n[[object]]\nname = \"b\"\nx = [3.0, 4.0]\n").unwrap();
    assert!(agree(lookup(&doc, "object[b].x").unwrap(), &toml::from_str::<Value>("v = [3, 4]").unwrap()["v"], 1e-9));
    assert_eq!(lookup(&doc, "object[0].name").unwrap().as_str(), Some("a"));
    assert!(lookup(&doc, "object[c].x").unwrap_err().contains("none named \"c\""));
    assert!(lookup(&doc, "object[2]").unwrap_err().contains("only 2 items"));
    assert!(!agree(&Value::Float(0.1253), &Value::Float(0.11), 1e-6));
}
