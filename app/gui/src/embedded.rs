//! The Rerun viewer embedded in the app's window (feature `viewer`): one window, the app's panels
//! beside the 3D view, one time cursor. The backend logs to in-process recording streams whose
//! messages go straight to the viewer (no network); the app's cursor sets the viewer's time on the
//! `step` timeline, and scrubbing the viewer's time panel moves the app's cursor.
//!
//! `re_viewer`'s API changes between Rerun versions; everything that touches it is in this module.

use std::cell::Cell;
use std::rc::Rc;
use std::sync::Arc;

use rerun_viewer::external::re_viewer::external::re_log_channel::{self, DataSourceMessage, LogSource};
use rerun_viewer::external::re_viewer::external::re_log_types::{LogMsg, TimeReal};
use rerun_viewer::external::re_viewer::external::re_viewer_context::TimeControlCommand;
use rerun_viewer::external::re_viewer::{self, SystemCommand, SystemCommandSender as _, ViewerEventKind};

use crate::backend::StreamFactory;
use crate::model::Command;
use crate::protocol::ViewerSink;
use crate::{RunOptions, Window, desktop};

/// The timeline the app's cursor and the viewer's share.
const STEP: &str = "step";
/// A run's recording: the attempt index, and every step of the run one after the other.
const ATTEMPT: &str = "attempt";
const FRAME: &str = "frame";

/// The app and the viewer in one window.
struct Embedded {
    window: Window,
    viewer: re_viewer::App,
    /// Where the viewer's time cursor moved to (on the `step` timeline), not yet taken.
    viewer_time: Rc<Cell<Option<i64>>>,
    /// The cursor the viewer was last told, or last told us.
    synced: Option<usize>,
    /// What the viewer was last told on the generate screen: stay on this attempt, or follow.
    synced_attempt: Option<Option<u64>>,
    /// Whether the 3D view was asked for since it last streamed (not asked again after a failure).
    asked: bool,
    /// Kept alive for the viewer's background tasks.
    _runtime: tokio::runtime::Runtime,
}

impl Embedded {
    /// On the generate screen, the run's recording follows its latest attempt, or stays on the
    /// attempt selected in the table.
    fn sync_attempt(&mut self) {
        let model = &self.window.app.model;
        let wanted = model.selected_attempt.filter(|_| model.stay_on_selected);
        if model.screen != crate::Screen::Generate || model.viewer.is_none() || self.synced_attempt == Some(wanted) {
            return;
        }
        let Some(db) = self.viewer.recording_db() else { return };
        if !db.timelines().keys().any(|t| t.as_str() == ATTEMPT) {
            // Not a run's recording (a tried attempt, a demo): nothing to follow.
            return;
        }
        let time_commands = match wanted {
            Some(index) => vec![
                TimeControlCommand::SetActiveTimeline(ATTEMPT.into()),
                TimeControlCommand::Pause,
                TimeControlCommand::SetTime(TimeReal::from(i64::try_from(index).unwrap_or(i64::MAX))),
            ],
            None => vec![TimeControlCommand::SetActiveTimeline(FRAME.into()), TimeControlCommand::MoveEndAndFollow],
        };
        self.viewer.command_sender.send_system(SystemCommand::TimeControlCommands { store_id: db.store_id().clone(), time_commands });
        self.synced_attempt = Some(wanted);
    }

    fn sync_time(&mut self) {
        self.sync_attempt();
        let model = &self.window.app.model;
        if model.screen != crate::Screen::Annotate || model.viewer.is_none() {
            return;
        }
        if let Some(t) = self.viewer_time.take()
            && let Ok(step) = usize::try_from(t)
            && Some(step) != self.synced
        {
            self.synced = Some(step);
            self.window.app.command(Command::SetCursor(step));
            return;
        }
        let cursor = self.window.app.model.cursor;
        if Some(cursor) != self.synced
            && let Some(db) = self.viewer.recording_db()
        {
            let time = TimeReal::from(i64::try_from(cursor).unwrap_or(i64::MAX));
            self.viewer.command_sender.send_system(SystemCommand::TimeControlCommands {
                store_id: db.store_id().clone(),
                time_commands: vec![TimeControlCommand::SetTime(time)],
            });
            self.synced = Some(cursor);
        }
    }
}

impl eframe::App for Embedded {
    fn ui(&mut self, ui: &mut egui::Ui, frame: &mut eframe::Frame) {
        let ctx = ui.ctx().clone();
        let model = &self.window.app.model;
        if model.viewer.is_some() {
            // Streaming. Opening another file drops the stream, and the view is asked for again.
            self.asked = false;
        } else if model.file.is_some() && model.in_flight == 0 && !self.asked {
            self.asked = true;
            self.window.app.command(Command::Open3d(ViewerSink::Embedded));
        }
        let viewer = &mut self.viewer;
        self.window.app.show_with(ui, Some(|ui: &mut egui::Ui| viewer.ui(ui, frame)));
        self.sync_time();
        self.window.script(&ctx);
    }

    fn logic(&mut self, ctx: &egui::Context, frame: &mut eframe::Frame) {
        self.viewer.logic(ctx, frame);
    }

    fn save(&mut self, storage: &mut dyn eframe::Storage) {
        self.viewer.save(storage);
    }
}

/// Recording streams that feed the viewer through `tx`.
fn streams(tx: re_log_channel::LogSender) -> StreamFactory {
    Arc::new(move || {
        let rec = rerun_viewer::RecordingStreamBuilder::new("mimicgen").buffered().map_err(|e| e.to_string())?;
        let tx = tx.clone();
        rec.set_sink(Box::new(rerun_viewer::sink::CallbackSink::new(move |msgs: &[LogMsg]| {
            for msg in msgs {
                let _ = tx.send(DataSourceMessage::LogMsg(msg.clone()));
            }
        })));
        Ok(rec)
    })
}

/// Opens the window with the viewer embedded and runs until it is closed.
///
/// # Errors
/// eframe's error when no window can be opened, or the viewer's when its renderer cannot start.
pub fn run(options: RunOptions) -> Result<(), eframe::Error> {
    let main_thread = re_viewer::MainThreadToken::i_promise_i_am_on_the_main_thread();
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(1)
        .enable_all()
        .build()
        .map_err(|e| eframe::Error::AppCreation(Box::new(e)))?;
    let mut native = re_viewer::native::eframe_options(None);
    native.viewport = native.viewport.with_app_id("mimicgen").with_inner_size([1600.0, 1000.0]).with_drag_and_drop(true);
    let viewer_time: Rc<Cell<Option<i64>>> = Rc::new(Cell::new(None));
    let on_time = Rc::clone(&viewer_time);
    let startup = re_viewer::StartupOptions {
        on_event: Some(Rc::new(move |event: re_viewer::ViewerEvent| match event.kind {
            ViewerEventKind::TimeUpdate { time } => on_time.set(Some(time.floor().as_i64())),
            ViewerEventKind::TimelineChange { timeline_name, time } if timeline_name.as_str() == STEP => {
                on_time.set(Some(time.floor().as_i64()));
            }
            _ => {}
        })),
        ..re_viewer::StartupOptions::default()
    };
    eframe::run_native(
        "mimicgen",
        native,
        Box::new(move |cc| {
            re_viewer::customize_eframe_and_setup_renderer(cc).map_err(|e| Box::new(e) as Box<dyn std::error::Error + Send + Sync>)?;
            let handle = re_viewer::AsyncRuntimeHandle::new_native(runtime.handle().clone());
            let mut viewer = re_viewer::App::new(
                main_thread,
                re_viewer::build_info(),
                re_viewer::AppEnvironment::Custom("mimicgen app".to_owned()),
                startup,
                cc,
                None,
                handle,
            );
            let (tx, rx) = re_log_channel::log_channel(LogSource::Sdk);
            viewer.add_log_receiver(rx);
            let ctx = cc.egui_ctx.clone();
            let app = desktop(move || ctx.request_repaint(), options.file.clone(), Some(streams(tx)), options.vet.clone());
            let window = Window::new(app, &options);
            Ok(Box::new(Embedded { window, viewer, viewer_time, synced: None, synced_attempt: None, asked: false, _runtime: runtime }))
        }),
    )
}
