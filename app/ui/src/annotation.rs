//! The annotation being edited: per demo, its subtask ends and hand-marked segment starts, with
//! undo and redo. Pure state; the model turns commands into calls here.

use mimicgen_engine::SubtaskMarks;
use mimicgen_engine::segment::{MIN_APPROACH_STEPS, approach_start};

use crate::protocol::DemoView;

/// One demo's marks before a change, kept for undo.
#[derive(Debug, Clone, PartialEq)]
struct Edit {
    demo: String,
    ends: Vec<usize>,
    starts: Option<Vec<Option<usize>>>,
}

/// Subtask ends and segment starts per demo, and whether they changed since opened or saved.
#[derive(Debug, Default)]
pub struct Annotation {
    /// Ends (exclusive, one per subtask but the last) and marked starts, per demo.
    pub marks: SubtaskMarks,
    /// Whether the annotation changed since it was opened or saved.
    pub dirty: bool,
    undo: Vec<Edit>,
    redo: Vec<Edit>,
}

/// A demo's ends as the file has them: its stored signals, else the proposals.
fn opened_ends(d: &DemoView) -> Vec<usize> {
    d.stored_ends.clone().unwrap_or_else(|| d.proposals.iter().map(|p| p.end).collect())
}

impl Annotation {
    /// The annotation the file holds: stored signals (else the proposals) and stored starts.
    #[must_use]
    pub fn opened(demos: &[DemoView]) -> Self {
        let mut annotation = Self::default();
        annotation.add(demos);
        annotation
    }

    /// Adds demos that streamed in after the file opened.
    pub fn add(&mut self, demos: &[DemoView]) {
        for d in demos {
            self.marks.ends.insert(d.name.clone(), opened_ends(d));
            if let Some(starts) = &d.stored_starts {
                self.marks.starts.insert(d.name.clone(), starts.clone());
            }
        }
    }

    /// The ends of `demo`.
    #[must_use]
    pub fn ends(&self, demo: &str) -> Vec<usize> {
        self.marks.ends.get(demo).cloned().unwrap_or_default()
    }

    /// The marked start of each of `demo`'s subtasks (`None` where unmarked).
    #[must_use]
    pub fn starts(&self, demo: &str) -> Vec<Option<usize>> {
        let subtasks = self.marks.ends.get(demo).map_or(0, |e| e.len() + 1);
        let mut starts = self.marks.starts.get(demo).cloned().unwrap_or_default();
        starts.resize(subtasks, None);
        starts
    }

    /// Whether undo has anything to undo.
    #[must_use]
    pub fn can_undo(&self) -> bool {
        !self.undo.is_empty()
    }

    /// Whether redo has anything to redo.
    #[must_use]
    pub fn can_redo(&self) -> bool {
        !self.redo.is_empty()
    }

    /// Replaces `demo`'s marks, keeping the old ones for undo. Starts that no longer lie inside
    /// their subtask are dropped (the engine would refuse them).
    fn change(&mut self, demo: &DemoView, ends: Vec<usize>, starts: &[Option<usize>]) {
        let starts: Vec<Option<usize>> =
            starts.iter().enumerate().map(|(k, s)| s.filter(|&s| start_range(&ends, demo.len, k).contains(&s))).collect();
        let before = self.edit(&demo.name);
        let unmarked = starts.iter().all(Option::is_none);
        if before.ends == ends && before.starts.as_ref().map_or(unmarked, |b| *b == starts) {
            return;
        }
        self.undo.push(before);
        self.redo.clear();
        self.marks.ends.insert(demo.name.clone(), ends);
        // A demo with starts before keeps its entry, so saving writes them as cleared.
        if !unmarked || self.marks.starts.contains_key(&demo.name) {
            self.marks.starts.insert(demo.name.clone(), starts);
        }
        self.dirty = true;
    }

    fn edit(&self, demo: &str) -> Edit {
        Edit { demo: demo.to_owned(), ends: self.ends(demo), starts: self.marks.starts.get(demo).cloned() }
    }

    /// Moves the end of `subtask` in `demo`, keeping every segment at least two steps long so
    /// that each signal is off for at least one step before it turns on (what MimicGen's parser
    /// needs).
    pub fn set_end(&mut self, demo: &DemoView, subtask: usize, end: usize) {
        let mut ends = self.ends(&demo.name);
        let low = subtask.checked_sub(1).and_then(|previous| ends.get(previous)).map_or(2, |&e| e + 2);
        let high = ends.get(subtask + 1).map_or(demo.len.saturating_sub(1), |&e| e.saturating_sub(2));
        let Some(slot) = ends.get_mut(subtask) else { return };
        *slot = end.clamp(low, high.max(low));
        let starts = self.starts(&demo.name);
        self.change(demo, ends, &starts);
    }

    /// Replaces `demo`'s ends (its marked starts kept where they still fit).
    pub fn set_ends(&mut self, demo: &DemoView, ends: Vec<usize>) {
        let starts = self.starts(&demo.name);
        self.change(demo, ends, &starts);
    }

    /// Marks (or with `None` unmarks) where `subtask`'s segment starts in `demo`, clamped into
    /// the subtask's steps.
    pub fn set_start(&mut self, demo: &DemoView, subtask: usize, start: Option<usize>) {
        let ends = self.ends(&demo.name);
        let mut starts = self.starts(&demo.name);
        let range = start_range(&ends, demo.len, subtask);
        let Some(slot) = starts.get_mut(subtask) else { return };
        *slot = start.map(|s| s.clamp(*range.start(), *range.end()));
        self.change(demo, ends, &starts);
    }

    /// Undoes the last change; returns whether there was one.
    pub fn undo(&mut self) -> bool {
        let Some(edit) = self.undo.pop() else { return false };
        let now = self.restore(edit);
        self.redo.push(now);
        true
    }

    /// Redoes what was undone; returns whether there was anything.
    pub fn redo(&mut self) -> bool {
        let Some(edit) = self.redo.pop() else { return false };
        let now = self.restore(edit);
        self.undo.push(now);
        true
    }

    fn restore(&mut self, edit: Edit) -> Edit {
        let now = self.edit(&edit.demo);
        self.marks.ends.insert(edit.demo.clone(), edit.ends);
        match edit.starts {
            Some(starts) => self.marks.starts.insert(edit.demo, starts),
            None => self.marks.starts.remove(&edit.demo),
        };
        self.dirty = true;
        now
    }
}

/// The steps at which `subtask`'s segment may start: from the previous subtask's end to two
/// steps before its own end (`ends` exclusive, the last subtask ends with the demo's `len`).
#[must_use]
pub fn start_range(ends: &[usize], len: usize, subtask: usize) -> std::ops::RangeInclusive<usize> {
    let first = if subtask == 0 { 0 } else { ends.get(subtask - 1).copied().unwrap_or(len) };
    let end = ends.get(subtask).copied().unwrap_or(len);
    first..=end.saturating_sub(MIN_APPROACH_STEPS).max(first)
}

/// Where the approach detector starts `subtask`'s segment in `demo` (the first step within
/// `approach_m` of the subtask's `object`), or `None` for a subtask without an object.
#[must_use]
pub fn detected_start(demo: &DemoView, object: Option<&str>, ends: &[usize], subtask: usize, approach_m: f64) -> Option<usize> {
    let distances = demo.distances.get(object?)?;
    let range = start_range(ends, demo.len, subtask);
    let end = ends.get(subtask).copied().unwrap_or(demo.len);
    Some(approach_start(*range.start()..end, *range.end(), approach_m, |t| distances.get(t).copied()))
}

#[cfg(test)]
mod tests {
    use std::collections::BTreeMap;

    use super::*;

    fn demo(len: usize) -> DemoView {
        DemoView {
            name: "demo_0".into(),
            len,
            gripper: vec![0.0; len],
            finger_width_m: None,
            eef_speed: vec![0.0; len],
            #[allow(clippy::cast_precision_loss)]
            distances: BTreeMap::from([("cube".to_owned(), (0..len).map(|t| 1.0 - t as f64 / len as f64).collect())]),
            signals: BTreeMap::new(),
            stored_ends: Some(vec![20]),
            stored_starts: None,
            proposals: Vec::new(),
        }
    }

    #[test]
    fn starts_stay_inside_their_subtask_and_undo_with_the_ends() {
        let d = demo(40);
        let mut a = Annotation::opened(std::slice::from_ref(&d));
        assert_eq!(a.starts("demo_0"), vec![None, None]);
        a.set_start(&d, 1, Some(5));
        assert_eq!(a.starts("demo_0"), vec![None, Some(20)], "clamped to the subtask's first step");
        a.set_start(&d, 1, Some(39));
        assert_eq!(a.starts("demo_0"), vec![None, Some(38)], "two steps before the end at most");
        a.set_start(&d, 0, Some(10));
        assert!(a.dirty);
        // Moving the end past a start drops it; undo brings both back.
        a.set_end(&d, 0, 8);
        assert_eq!((a.ends("demo_0"), a.starts("demo_0")), (vec![8], vec![None, Some(38)]));
        assert!(a.undo());
        assert_eq!((a.ends("demo_0"), a.starts("demo_0")), (vec![20], vec![Some(10), Some(38)]));
        assert!(a.undo() && a.undo() && a.undo());
        assert_eq!(a.marks.starts.get("demo_0"), None, "back to unmarked");
        assert!(a.redo());
        assert_eq!(a.starts("demo_0"), vec![None, Some(20)]);
        // Clearing a start the file had keeps the demo's entry, so saving writes it cleared.
        let stored = DemoView { stored_starts: Some(vec![None, Some(30)]), ..d.clone() };
        let mut b = Annotation::opened(std::slice::from_ref(&stored));
        b.set_start(&stored, 1, None);
        assert_eq!(b.marks.starts.get("demo_0"), Some(&vec![None, None]));
    }

    #[test]
    fn the_detected_start_is_where_the_object_comes_within_approach_m() {
        let d = demo(40);
        // Distance 1 - t/40 is within 0.5 from t = 20 on, within 0.25 from t = 30 on.
        assert_eq!(detected_start(&d, Some("cube"), &[20], 1, 0.5), Some(20));
        assert_eq!(detected_start(&d, Some("cube"), &[20], 1, 0.25), Some(30));
        assert_eq!(detected_start(&d, Some("cube"), &[20], 1, 0.01), Some(20), "never near: the subtask's first step");
        assert_eq!(detected_start(&d, Some("cube"), &[10], 0, 0.776), Some(8), "two steps before the end at most");
        assert_eq!(detected_start(&d, None, &[20], 0, 0.5), None, "no object");
    }
}
