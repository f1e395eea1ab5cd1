//! Where in a spec's text a field is: the line of a field named in an error, and TOML errors as
//! `file:line` and the dotted field.

use crate::EngineError;

/// The 1-based line of field `field` (`subtask[1].object_ref`, as errors name fields) in a spec's
/// text: our TOML (`[[subtask]]` tables) or a MimicGen experiment JSON (`"subtask_2": {...}`).
/// `None` when the text does not spell it out on a line of its own.
#[must_use]
pub fn field_line(text: &str, field: &str) -> Option<usize> {
    let (index, key) = field.strip_prefix("subtask[")?.split_once("].")?;
    let index: usize = index.parse().ok()?;
    let lines = text.lines().enumerate();
    if text.trim_start().starts_with('{') {
        let table = format!("\"subtask_{}\"", index + 1);
        let quoted = format!("\"{key}\"");
        let mut inside = false;
        for (n, line) in lines {
            if line.contains("\"subtask_") {
                inside = line.contains(&table);
            }
            if inside && line.contains(&quoted) {
                return Some(n + 1);
            }
        }
        return None;
    }
    let mut table: Option<usize> = None;
    let mut subtasks = 0;
    for (n, line) in lines {
        let line = line.trim();
        if line.starts_with('[') {
            table = (line.trim_start_matches('[').trim_end_matches(']').trim() == "subtask" && line.starts_with("[[")).then_some(subtasks);
            subtasks += usize::from(table.is_some());
        } else if table == Some(index) && line.split_once('=').is_some_and(|(k, _)| k.trim().trim_matches('"') == key) {
            return Some(n + 1);
        }
    }
    None
}

/// A TOML error as `file:line`, the dotted field (`subtask[1].object_ref`) and the message.
pub(crate) fn toml_error(text: &str, origin: &str, e: &toml::de::Error) -> EngineError {
    let Some(span) = e.span() else {
        return EngineError::Config { file: origin.to_owned(), field: String::new(), reason: e.message().to_owned() };
    };
    let start = span.start.min(text.len());
    let line = text[..start].matches('\n').count() + 1;
    let lines: Vec<&str> = text.lines().take(line).collect();
    let key = lines.last().and_then(|l| l.split_once('=')).map(|(k, _)| k.trim().trim_matches('"').to_owned());
    // The table the line sits in, with its index when it is an array of tables, and the index
    // of each array of tables it is nested in (`arm[1].subtask[0]`: counted within its arm).
    let mut table: Option<String> = None;
    let mut counts: std::collections::BTreeMap<String, usize> = std::collections::BTreeMap::new();
    let render = |segments: &[&str], counts: &std::collections::BTreeMap<String, usize>| {
        let mut path = String::new();
        for s in segments {
            if !path.is_empty() {
                path.push('.');
            }
            path.push_str(s.trim());
            if let Some(&n) = counts.get(&path) {
                path = format!("{path}[{}]", n.saturating_sub(1));
            }
        }
        path
    };
    for l in &lines {
        let l = l.trim();
        if let Some(name) = l.strip_prefix("[[").and_then(|r| r.strip_suffix("]]")) {
            let segments: Vec<&str> = name.split('.').collect();
            let (last, parents) = segments.split_last().unwrap_or((&"", &[]));
            let parent = render(parents, &counts);
            let key = if parent.is_empty() { last.trim().to_owned() } else { format!("{parent}.{}", last.trim()) };
            let n = counts.entry(key.clone()).or_insert(0);
            table = Some(format!("{key}[{n}]"));
            *n += 1;
        } else if let Some(name) = l.strip_prefix('[').and_then(|r| r.strip_suffix(']')) {
            table = Some(render(&name.split('.').collect::<Vec<_>>(), &counts));
        }
    }
    let field = match (table, key) {
        (Some(t), Some(k)) => format!("{t}.{k}"),
        (Some(t), None) => t,
        (None, Some(k)) => k,
        (None, None) => String::new(),
    };
    EngineError::Config { file: format!("{origin}:{line}"), field, reason: e.message().trim().to_owned() }
}
