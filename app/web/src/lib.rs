//! The inspection app in a browser: the UI of `mimicgen-ui` compiled to
//! `wasm32-unknown-unknown`, run by eframe's web runner on the page `mimicgen serve` hosts, and
//! talking to the server's backend over a WebSocket (JSON `ClientMessage`s and
//! `ServerMessage`s, from `mimicgen_ui::protocol`). The Rerun web viewer sits beside the canvas in the page.
//!
//! What it does not do: read files or simulate (the server does, natively). On any other target
//! than wasm32 this crate is empty, so `cargo build --workspace` does not need the wasm target.
//!
//! Built by `scripts/build_web.sh` (cargo for wasm32, then `wasm-bindgen --target web`); the page
//! calls `start` once the module has loaded:
//!
//! ```js
//! import init, { start } from "./mimicgen_web.js";
//! await init();
//! start("app");
//! ```
#![cfg(target_arch = "wasm32")]

mod socket;
mod test_hook;
mod viewer;

use mimicgen_ui::model::Command;
use mimicgen_ui::protocol::{ClientMessage, ServerMessage};
use mimicgen_ui::{MimicgenApp, egui};
use wasm_bindgen::JsCast as _;
use wasm_bindgen::prelude::*;

/// The app on the page: the UI, and the 3D view's frame beside it.
struct WebApp {
    app: MimicgenApp,
    /// The 3D view beside the canvas.
    viewer: viewer::ViewerFrame,
    /// Whether a browser test reads the app's state.
    test_hook: bool,
}

impl eframe::App for WebApp {
    fn ui(&mut self, ui: &mut egui::Ui, _frame: &mut eframe::Frame) {
        let started = self.test_hook.then(now_ms);
        self.app.show(ui);
        if let (Some(started), Some(ended)) = (started, self.test_hook.then(now_ms)) {
            test_hook::frame_time(ended - started);
        }
        // The 3D view is the Rerun web viewer in the page's own frame (egui cannot host it).
        if let Some(step) = self.viewer.update(&self.app.model, ui.ctx()) {
            self.app.command(Command::SetCursor(step));
        }
        if self.test_hook {
            test_hook::record(&self.app.model);
        }
    }
}

/// A panic stops the app: say so on the page and in the console, with where it happened.
fn on_panic(info: &std::panic::PanicHookInfo<'_>) {
    let message = format!("mimicgen crashed: {info}. Reload the page; the server and its run go on.");
    web_sys::console::error_1(&message.as_str().into());
    let Some(document) = web_sys::window().and_then(|w| w.document()) else { return };
    let Some(body) = document.body() else { return };
    if let Ok(note) = document.create_element("div") {
        note.set_id("crashed");
        note.set_text_content(Some(&message));
        let _ = note.set_attribute("role", "alert");
        let _ = body.append_child(&note);
    }
}

/// The page's clock, in milliseconds (sub-millisecond where the browser allows).
fn now_ms() -> f64 {
    web_sys::window().and_then(|w| w.performance()).map_or_else(js_sys::Date::now, |p| p.now())
}

/// The page's query parameter `name`, if it has one.
fn query(name: &str) -> Option<String> {
    let search = web_sys::window()?.location().search().ok()?;
    web_sys::UrlSearchParams::new_with_str(&search).ok()?.get(name)
}

/// Starts the app on the canvas with id `canvas_id`, connected to the server that served the page
/// (the page's `token` query parameter, if any, goes with every request). With `testhook` in the
/// page's query, the UI's accessibility tree is kept for [`test_nodes`].
#[wasm_bindgen]
pub fn start(canvas_id: &str) -> Result<(), JsValue> {
    let document = web_sys::window().and_then(|w| w.document()).ok_or("no document")?;
    let canvas = document
        .get_element_by_id(canvas_id)
        .ok_or_else(|| format!("no element {canvas_id:?}"))?
        .dyn_into::<web_sys::HtmlCanvasElement>()
        .map_err(|_| format!("{canvas_id:?} is not a canvas"))?;
    let test_hook = query("testhook").is_some();
    std::panic::set_hook(Box::new(on_panic));
    let runner = eframe::WebRunner::new();
    wasm_bindgen_futures::spawn_local(async move {
        let started = runner
            .start(
                canvas,
                eframe::WebOptions::default(),
                Box::new(move |cc| {
                    if test_hook {
                        test_hook::install(&cc.egui_ctx);
                    }
                    let socket = socket::Socket::connect(query("token").as_deref(), cc.egui_ctx.clone());
                    Ok(Box::new(WebApp {
                        app: MimicgenApp::new(Box::new(socket), None),
                        viewer: viewer::ViewerFrame::default(),
                        test_hook,
                    }))
                }),
            )
            .await;
        if let Err(e) = started {
            web_sys::console::error_2(&"mimicgen: the app could not start:".into(), &e);
        }
    });
    Ok(())
}

/// The UI's widgets as the last frame drew them, as JSON (`[{"role", "label", "value", "rect":
/// [x0, y0, x1, y1], "toggled"}]`, in CSS pixels of the canvas): what a browser test clicks.
/// Empty unless the page was opened with `testhook`.
#[wasm_bindgen]
pub fn test_nodes() -> String {
    test_hook::nodes()
}

/// The app's state in a few fields, as JSON, for a browser test to wait on.
#[wasm_bindgen]
pub fn test_state() -> String {
    test_hook::state()
}

/// The milliseconds the app's own drawing took (`show`: layout and plots, not the GPU) in each
/// frame since the last call, as JSON (`[ms, ...]`), for `tests/web/bench.mjs`. Empty unless
/// the page was opened with `testhook`.
#[wasm_bindgen]
pub fn test_frames() -> String {
    test_hook::take_frame_times()
}

/// The wire format, in one place (the server has the other end).
fn encode(message: &ClientMessage) -> Option<String> {
    serde_json::to_string(message).ok()
}

fn decode(text: &str) -> Result<ServerMessage, String> {
    serde_json::from_str(text).map_err(|e| e.to_string())
}
