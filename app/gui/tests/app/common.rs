//! What every click-through needs: files to open, the app in a harness, and waiting on its
//! backend.
#![allow(dead_code, reason = "each test module uses some of these")]

use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use egui_kittest::Harness;
use mimicgen_gui::MimicgenApp;

pub fn fixture() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../core/io/tests/data/source_D0_prepared.hdf5")
}

/// A bundled source file (`core/sim/data/<name>`).
pub fn bundled(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../core/sim/data").join(name)
}

pub fn harness(file: Option<PathBuf>) -> Harness<'static, MimicgenApp> {
    let app = mimicgen_gui::desktop(|| {}, file, None, None);
    Harness::builder().with_size(egui::vec2(1280.0, 800.0)).build_ui_state(|ui, app: &mut MimicgenApp| app.show(ui), app)
}

/// Steps frames until the backend has answered (the UI never blocks on it). The deadline only
/// turns a hung backend into a failure; a slow machine just takes longer.
pub fn settle(h: &mut Harness<'static, MimicgenApp>) {
    let deadline = Instant::now() + Duration::from_secs(600);
    loop {
        h.step();
        if h.state().model.in_flight == 0 {
            break;
        }
        assert!(Instant::now() < deadline, "the backend did not answer");
        std::thread::sleep(Duration::from_millis(10));
    }
    h.run_steps(2);
}

/// Presses at `from`, moves to `to` over a few frames and releases there, as a hand drags.
pub fn drag(h: &mut Harness<'static, MimicgenApp>, from: egui::Pos2, to: egui::Pos2) {
    h.hover_at(from);
    h.step();
    h.drag_at(from);
    h.step();
    for i in 1..=8 {
        h.hover_at(from + (to - from) * (i as f32 / 8.0));
        h.step();
    }
    // egui_plot reports the pointer of the frame before: hold still one frame before releasing.
    h.step();
    h.drop_at(to);
}

/// Waits (stepping frames) until the app's run has ended.
pub fn until_run_ends(h: &mut Harness<'static, MimicgenApp>) {
    let deadline = Instant::now() + Duration::from_secs(900);
    while h.state().model.run.as_ref().is_some_and(mimicgen_gui::model::RunState::running) {
        h.step();
        assert!(Instant::now() < deadline, "the run did not end");
        std::thread::sleep(Duration::from_millis(20));
    }
    h.run_steps(2);
}
