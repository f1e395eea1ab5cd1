//! Subtask labels in a LeRobot dataset, as LeRobot's own subtask annotation stores them (what
//! `lerobot` 0.4's `LeRobotDataset.__getitem__` reads): an int64 `subtask_index` per frame and
//! `meta/subtasks.parquet`, a table whose pandas index is the subtask's text and whose
//! `subtask_index` column its number (the layout of `meta/tasks.parquet`).
//!
//! Each frame's subtask comes from the demo's `datagen_info/subtask_term_signals`, as MimicGen
//! segments a demo: subtask `i` ends one step after its signal first turns on (at or after the
//! subtask's start); the last subtask runs to the end.

use std::path::Path;
use std::sync::Arc;

use arrow_array::{Int64Array, RecordBatch, StringArray};
use arrow_schema::{DataType, Field, Schema};
use mimicgen_engine::segment::subtask_end_from_signal;

use crate::tree::Group;

/// One subtask of the exported task, in order.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct SubtaskLabel {
    /// The text LeRobot returns as the frame's `subtask`.
    pub name: String,
    /// The `datagen_info/subtask_term_signals` member that ends it; `None` for the last subtask.
    pub end_signal: Option<String>,
}

/// The subtask of every step of `demo` (`steps` long), by index into `subtasks`.
///
/// A subtask whose signal never turns on runs to the end (the later subtasks get no frames): a
/// failed attempt's labels stop where it stopped.
///
/// # Errors
/// `(field, reason)` when a signal is missing or not `steps` long.
pub(super) fn subtask_of_each_step(demo: &Group, subtasks: &[SubtaskLabel], steps: usize) -> Result<Vec<i64>, (String, String)> {
    let mut labels = Vec::with_capacity(steps);
    let mut start = 0;
    for (index, subtask) in subtasks.iter().enumerate() {
        let end = match &subtask.end_signal {
            None => steps,
            Some(signal) => {
                let field = format!("datagen_info/subtask_term_signals/{signal}");
                let values = demo
                    .group("datagen_info")
                    .and_then(|info| info.group("subtask_term_signals"))
                    .and_then(|signals| signals.dataset(signal))
                    .and_then(|d| d.array.values.to_i64())
                    .ok_or_else(|| (field.clone(), format!("missing: subtask {} ({}) ends on it", index + 1, subtask.name)))?;
                if values.len() != steps {
                    return Err((field, format!("has {} steps, the demo {steps}", values.len())));
                }
                subtask_end_from_signal(&values, start).unwrap_or(steps).min(steps)
            }
        };
        let index = i64::try_from(index).unwrap_or(i64::MAX);
        labels.resize(end.max(start), index);
        start = end.max(start);
        if start >= steps {
            break;
        }
    }
    // Subtasks listed without a last one (every one ending on a signal) leave a tail: it belongs
    // to the last.
    let last = i64::try_from(subtasks.len().saturating_sub(1)).unwrap_or(i64::MAX);
    labels.resize(steps, last);
    Ok(labels)
}

/// A table LeRobot reads with `pandas.read_parquet`: the strings are the index (the parquet
/// column `__index_level_0__`, named in the pandas metadata) and `index_column` numbers them
/// from 0, as `meta/tasks.parquet` and `meta/subtasks.parquet` are.
pub(super) fn indexed_strings(index_column: &str, strings: &[String]) -> Result<RecordBatch, arrow_schema::ArrowError> {
    let pandas = serde_json::json!({
        "index_columns": ["__index_level_0__"],
        "column_indexes": [{"name": null, "field_name": null, "pandas_type": "unicode", "numpy_type": "object", "metadata": {"encoding": "UTF-8"}}],
        "columns": [
            {"name": index_column, "field_name": index_column, "pandas_type": "int64", "numpy_type": "int64", "metadata": null},
            {"name": null, "field_name": "__index_level_0__", "pandas_type": "unicode", "numpy_type": "object", "metadata": null}
        ],
        "creator": {"library": "mimicgen-rs", "version": env!("CARGO_PKG_VERSION")},
        "pandas_version": "2.2.3"
    });
    let schema =
        Schema::new(vec![Field::new(index_column, DataType::Int64, false), Field::new("__index_level_0__", DataType::Utf8, false)])
            .with_metadata(std::collections::HashMap::from([("pandas".to_owned(), pandas.to_string())]));
    let numbers: Vec<i64> = (0..strings.len()).map(|i| i64::try_from(i).unwrap_or(i64::MAX)).collect();
    RecordBatch::try_new(Arc::new(schema), vec![Arc::new(Int64Array::from(numbers)), Arc::new(StringArray::from(strings.to_vec()))])
}

/// Where the subtask table goes in the dataset.
pub(super) fn table_path(meta: &Path) -> std::path::PathBuf {
    meta.join("subtasks.parquet")
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]

    use super::*;
    use crate::tree::{Array, Dataset, Node, Values};

    fn demo_with(signals: &[(&str, Vec<i64>)]) -> Group {
        let mut group = Group::default();
        for (name, values) in signals {
            group.members.insert(
                (*name).to_owned(),
                Node::Dataset(Dataset::new(Array { shape: vec![values.len()], values: Values::I64(values.clone()) })),
            );
        }
        let mut info = Group::default();
        info.members.insert("subtask_term_signals".into(), Node::Group(group));
        let mut demo = Group::default();
        demo.members.insert("datagen_info".into(), Node::Group(info));
        demo
    }

    fn label(name: &str, signal: Option<&str>) -> SubtaskLabel {
        SubtaskLabel { name: name.into(), end_signal: signal.map(str::to_owned) }
    }

    #[test]
    fn a_subtask_ends_one_step_after_its_signal_turns_on() {
        let demo = demo_with(&[("grasp", vec![0, 0, 0, 1, 1, 0, 0])]);
        let labels = subtask_of_each_step(&demo, &[label("grasp", Some("grasp")), label("place", None)], 7).unwrap();
        assert_eq!(labels, [0, 0, 0, 0, 1, 1, 1]);
    }

    #[test]
    fn later_signals_count_only_from_their_subtask_start() {
        // "b" is on from the start and turns on again at step 4; "a" turns on at step 2.
        let demo = demo_with(&[("a", vec![0, 0, 1, 1, 0, 0, 0, 0]), ("b", vec![1, 0, 0, 0, 1, 1, 1, 1])]);
        let labels =
            subtask_of_each_step(&demo, &[label("first", Some("a")), label("second", Some("b")), label("third", None)], 8).unwrap();
        assert_eq!(labels, [0, 0, 0, 1, 1, 2, 2, 2]);
    }

    #[test]
    fn a_signal_that_never_turns_on_keeps_its_subtask_to_the_end() {
        let demo = demo_with(&[("grasp", vec![0; 5])]);
        let labels = subtask_of_each_step(&demo, &[label("grasp", Some("grasp")), label("place", None)], 5).unwrap();
        assert_eq!(labels, [0; 5]);
    }

    #[test]
    fn a_missing_or_short_signal_is_named() {
        let demo = demo_with(&[("grasp", vec![0, 1])]);
        let (field, reason) = subtask_of_each_step(&demo, &[label("lift", Some("lift")), label("place", None)], 2).unwrap_err();
        assert_eq!(field, "datagen_info/subtask_term_signals/lift");
        assert!(reason.contains("missing") && reason.contains("lift"), "{reason}");
        let (field, reason) = subtask_of_each_step(&demo, &[label("grasp", Some("grasp")), label("place", None)], 3).unwrap_err();
        assert_eq!(field, "datagen_info/subtask_term_signals/grasp");
        assert!(reason.contains("2 steps"), "{reason}");
    }
}
