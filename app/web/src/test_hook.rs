//! What a browser test reads: the UI's widgets from egui's accessibility (AccessKit) output, with
//! their roles, labels and rectangles, so a test finds a button by its label and clicks it with
//! the real pointer; and a few fields of the app's state to wait on. Off unless the page asks for
//! it (`?testhook`): building the tree costs a little every frame.

use std::sync::Mutex;

use mimicgen_ui::egui;
use mimicgen_ui::egui::accesskit;

/// The last frame's widgets, as JSON.
static NODES: Mutex<String> = Mutex::new(String::new());
/// The app's state after the last frame, as JSON.
static STATE: Mutex<String> = Mutex::new(String::new());
/// The app's drawing time per frame (ms) since they were last taken; at most [`MAX_FRAMES`].
static FRAMES: Mutex<Vec<f64>> = Mutex::new(Vec::new());
const MAX_FRAMES: usize = 100_000;

/// Keeps every frame's AccessKit tree.
struct Recorder;

impl egui::Plugin for Recorder {
    fn debug_name(&self) -> &'static str {
        "mimicgen test hook"
    }

    fn output_hook(&mut self, _ctx: &egui::Context, output: &mut egui::FullOutput) {
        let Some(update) = &output.platform_output.accesskit_update else { return };
        // A widget labelled by another (a text field after its label) takes that label's text.
        let labels: std::collections::HashMap<accesskit::NodeId, &str> =
            update.nodes.iter().filter_map(|(id, node)| Some((*id, node.label().or_else(|| node.value())?))).collect();
        let nodes: Vec<serde_json::Value> = update
            .nodes
            .iter()
            .filter_map(|(_, node)| {
                let rect = node.bounds()?;
                let label = node.label().or_else(|| node.labelled_by().iter().find_map(|id| labels.get(id).copied()));
                Some(serde_json::json!({
                    "role": format!("{:?}", node.role()),
                    "label": label.unwrap_or_default(),
                    "value": node.value().unwrap_or_default(),
                    "toggled": node.toggled().map(|t| t == accesskit::Toggled::True),
                    "disabled": node.is_disabled(),
                    "rect": [rect.x0, rect.y0, rect.x1, rect.y1],
                }))
            })
            .collect();
        if let Ok(mut slot) = NODES.lock() {
            *slot = serde_json::Value::Array(nodes).to_string();
        }
    }
}

/// Turns the tree on for `ctx` and keeps it.
pub fn install(ctx: &egui::Context) {
    ctx.enable_accesskit();
    ctx.add_plugin(Recorder);
}

/// The last frame's widgets (empty without the hook).
pub fn nodes() -> String {
    NODES.lock().map(|s| s.clone()).unwrap_or_default()
}

/// The app's state (empty without the hook).
pub fn state() -> String {
    STATE.lock().map(|s| s.clone()).unwrap_or_default()
}

/// Keeps one frame's drawing time.
pub fn frame_time(ms: f64) {
    if let Ok(mut frames) = FRAMES.lock()
        && frames.len() < MAX_FRAMES
    {
        frames.push(ms);
    }
}

/// The frame times kept since the last call, as a JSON array.
pub fn take_frame_times() -> String {
    let frames = FRAMES.lock().map(|mut f| std::mem::take(&mut *f)).unwrap_or_default();
    serde_json::Value::from(frames).to_string()
}

/// Records the model's state after a frame (only when the hook is on).
pub fn record(model: &mimicgen_ui::AppModel) {
    let Ok(mut slot) = STATE.lock() else { return };
    let run = model.run.as_ref().map(|r| {
        serde_json::json!({
            "running": r.running(),
            "out": r.config.out,
            "planned": r.config.num_demos,
            "attempts": r.rows.len(),
            "successes": r.rows.iter().filter(|a| a.success).count(),
            "failed": r.rows.iter().filter(|a| !a.success).map(|a| a.index).collect::<Vec<_>>(),
            "finished": r.report.is_some(),
            "error": r.error,
        })
    });
    let value = serde_json::json!({
        "screen": format!("{:?}", model.screen),
        "file": model.file.as_ref().map(|f| f.path.display().to_string()),
        "demos": model.file.as_ref().map_or(0, |f| f.demos.len()),
        "selected": model.selected,
        "cursor": model.cursor,
        "boundary": model.boundary,
        "ends": model.demo_ends(),
        "arms": model.file.as_ref().map_or(0, |f| f.arms.len()),
        "arm": model.arm,
        "arm_ends": (0..model.file.as_ref().map_or(0, |f| f.arms.len())).map(|k| model.arm_ends(k)).collect::<Vec<_>>(),
        "starts": model.demo_starts(),
        "dirty": model.annotation.dirty,
        "status": model.status,
        "error": model.error,
        "busy": model.busy,
        "in_flight": model.in_flight,
        "viewer": model.viewer,
        "selected_attempt": model.selected_attempt,
        "side_by_side": model.side_by_side.as_ref().map(|p| p.views.is_some()),
        "run": run,
        "root": model.welcome.root.as_ref().map(|r| r.display().to_string()),
        "prepared_from": model.file.as_ref().and_then(|f| f.prepared_from.as_ref()).map(|p| p.display().to_string()),
        "preview": model.preview.view.as_ref().map(|v| serde_json::json!({
            "task": v.task,
            "index": v.index,
            "executed": v.executed.as_ref().map(|e| e.success),
            "arms": v.arms.len(),
            "ties": v.ties.iter().map(|t| if t.coordination { "coordination" } else { "sequential" }).collect::<Vec<_>>(),
        })),
    });
    *slot = value.to_string();
}
