//! The 3D view in the browser: the Rerun web viewer (served by the server under `/rerun/`) in the
//! page's `viewer` frame, reading the server's recording stream through the same origin, and one
//! time cursor with the app, as on the desktop. The viewer's page keeps its `WebHandle` as
//! `window._handle`; its methods (`get_active_recording_id`, `get_time_for_timeline`,
//! `set_time_for_timeline`, `set_active_timeline`, `set_playing`) are how the two stay in step:
//! the app's cursor sets the viewer's time on the `step` timeline, and scrubbing the viewer's time
//! panel moves the app's cursor. On the generate screen the run's recording follows its latest
//! attempt, or stays on the attempt selected in the table.

use mimicgen_ui::{AppModel, Screen};
use wasm_bindgen::{JsCast as _, JsValue};

/// The timeline the app's cursor and the viewer's share.
const STEP: &str = "step";
/// A run's recording: the attempt index, and every step of the run one after the other.
const ATTEMPT: &str = "attempt";
const FRAME: &str = "frame";
/// Frames to wait for the viewer to take a time it was given before reading its time again.
const SETTLE_FRAMES: u32 = 30;

/// The frame's state and what the viewer was last told.
#[derive(Default)]
pub struct ViewerFrame {
    /// The viewer page shown in the frame (`None`: hidden).
    shown: Option<String>,
    /// The cursor the viewer was last told, or last told us.
    synced: Option<i64>,
    /// A time given to the viewer that it has not reported back yet, and frames waited for it.
    pending: Option<(i64, u32)>,
    /// What the viewer was last told on the generate screen: stay on this attempt, or follow.
    synced_attempt: Option<Option<u64>>,
}

impl ViewerFrame {
    /// Shows or hides the frame for this frame's model, and keeps the two time cursors in step.
    /// Returns a cursor the viewer moved to, for the app to take.
    pub fn update(&mut self, model: &AppModel, ctx: &mimicgen_ui::egui::Context) -> Option<usize> {
        let wanted = model.viewer.as_ref().and(model.welcome.viewer_url.as_deref()).map(page_url);
        if wanted != self.shown {
            show(wanted.as_deref());
            self.shown = wanted;
            (self.synced, self.pending, self.synced_attempt) = (None, None, None);
        }
        self.shown.as_ref()?;
        // The viewer's time moves without the app hearing of it: look again soon.
        ctx.request_repaint_after(std::time::Duration::from_millis(100));
        let viewer = Handle::find()?;
        let recording = viewer.recording()?;
        match model.screen {
            Screen::Annotate => self.sync_step(&viewer, &recording, model.cursor),
            Screen::Generate => {
                self.sync_attempt(&viewer, &recording, model);
                None
            }
            Screen::Preview => None,
        }
    }

    fn sync_step(&mut self, viewer: &Handle, recording: &str, cursor: usize) -> Option<usize> {
        let time = viewer.time(recording, STEP);
        if let Some((given, waited)) = self.pending {
            // Until the viewer has taken the time it was given, its own is stale.
            if time != Some(given) && waited < SETTLE_FRAMES {
                self.pending = Some((given, waited + 1));
                return None;
            }
            self.pending = None;
        }
        if let Some(t) = time
            && Some(t) != self.synced
            && self.synced.is_some()
        {
            self.synced = Some(t);
            return usize::try_from(t).ok();
        }
        let cursor = i64::try_from(cursor).unwrap_or(i64::MAX);
        if Some(cursor) != self.synced || time.is_none() {
            // Paused, else a live recording's viewer follows its newest data.
            viewer.call("set_playing", &[recording.into(), false.into()]);
            viewer.call("set_time_for_timeline", &[recording.into(), STEP.into(), JsValue::from_f64(cursor as f64)]);
            self.synced = Some(cursor);
            self.pending = Some((cursor, 0));
        }
        None
    }

    fn sync_attempt(&mut self, viewer: &Handle, recording: &str, model: &AppModel) {
        let wanted = model.selected_attempt.filter(|_| model.stay_on_selected);
        if self.synced_attempt == Some(wanted) || !viewer.has_timeline(recording, ATTEMPT) {
            // Told already, or not a run's recording (a tried attempt, a demo): nothing to follow.
            return;
        }
        match wanted {
            Some(index) => {
                viewer.call("set_active_timeline", &[recording.into(), ATTEMPT.into()]);
                viewer.call("set_playing", &[recording.into(), false.into()]);
                viewer.call("set_time_for_timeline", &[recording.into(), ATTEMPT.into(), JsValue::from_f64(index as f64)]);
            }
            None => {
                viewer.call("set_active_timeline", &[recording.into(), FRAME.into()]);
                viewer.call("set_playing", &[recording.into(), true.into()]);
            }
        }
        self.synced_attempt = Some(wanted);
    }
}

/// The viewer's page for the server's recording: `base` (the server's `/rerun/`) with the
/// recording's address on this page's own origin, which the server forwards to its gRPC proxy.
fn page_url(base: &str) -> String {
    let origin = web_sys::window().and_then(|w| w.location().origin().ok()).unwrap_or_default();
    let recording = String::from(js_sys::encode_uri_component(&format!("rerun+{origin}/proxy")));
    format!("{base}?url={recording}&hide_welcome_screen&persist=0")
}

/// Shows the viewer at `url` in the page's `viewer` frame (hides it for `None`).
fn show(url: Option<&str>) {
    let Some(document) = web_sys::window().and_then(|w| w.document()) else { return };
    let Some(frame) = document.get_element_by_id("viewer") else { return };
    let Some(body) = document.body() else { return };
    match url {
        Some(url) => {
            if frame.get_attribute("src").as_deref() != Some(url) {
                let _ = frame.set_attribute("src", url);
            }
            let _ = body.class_list().add_1("with-viewer");
        }
        None => {
            let _ = body.class_list().remove_1("with-viewer");
        }
    }
}

/// The viewer page's `WebHandle`, once its WebAssembly has started.
struct Handle(JsValue);

impl Handle {
    fn find() -> Option<Self> {
        let document = web_sys::window()?.document()?;
        let frame = document.get_element_by_id("viewer")?.dyn_into::<web_sys::HtmlIFrameElement>().ok()?;
        let window = frame.content_window()?;
        let handle = js_sys::Reflect::get(&window, &"_handle".into()).ok()?;
        (!handle.is_undefined() && !handle.is_null()).then_some(Self(handle))
    }

    /// Calls the method `name`; `None` when it is not there or throws.
    fn call(&self, name: &str, args: &[JsValue]) -> Option<JsValue> {
        let method = js_sys::Reflect::get(&self.0, &name.into()).ok()?.dyn_into::<js_sys::Function>().ok()?;
        method.apply(&self.0, &args.iter().collect::<js_sys::Array>()).ok()
    }

    fn recording(&self) -> Option<String> {
        self.call("get_active_recording_id", &[])?.as_string()
    }

    /// The time on `timeline`, when the recording has it.
    #[expect(clippy::cast_possible_truncation, reason = "sequence times are whole numbers")]
    fn time(&self, recording: &str, timeline: &str) -> Option<i64> {
        let t = self.call("get_time_for_timeline", &[recording.into(), timeline.into()])?.as_f64()?;
        t.is_finite().then_some(t.round() as i64)
    }

    fn has_timeline(&self, recording: &str, timeline: &str) -> bool {
        self.call("get_timeline_time_range", &[recording.into(), timeline.into()]).is_some_and(|r| !r.is_undefined() && !r.is_null())
    }
}
