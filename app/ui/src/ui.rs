//! Drawing: reads the model, returns commands. Nothing here changes state directly.

use egui::{Color32, Key, Modifiers, RichText};
use egui_plot::{Corner, Legend, Line, LineStyle, Plot, PlotPoints, Span, VLine};

use crate::annotation::detected_start;
use crate::model::{AppModel, Command, Screen};
use crate::protocol::DemoView;
use crate::style::subtask_color;

/// UI-only state that is not part of the model (text fields, a drag in progress).
#[derive(Default)]
pub struct UiState {
    /// The "open" path field.
    pub open_path: String,
    /// The "save as" path field.
    pub save_path: String,
    /// A boundary being dragged: (subtask, current x).
    pub drag: Option<(usize, f64)>,
    /// The preview screen's.
    pub preview: crate::preview_ui::PreviewUiState,
    /// The generate screen's.
    pub run: crate::run_ui::RunUiState,
    /// Time of the last playback step (s).
    pub last_tick_s: f64,
    /// The camera images drawn: `(camera, demo, step)` and its texture, one per camera.
    pub camera_textures: Vec<((String, usize, usize), egui::TextureHandle)>,
}

impl std::fmt::Debug for UiState {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("UiState").field("drag", &self.drag).field("camera_textures", &self.camera_textures.len()).finish_non_exhaustive()
    }
}

/// Keyboard shortcuts, read once per frame.
pub fn keys(ctx: &egui::Context, commands: &mut Vec<Command>) {
    if ctx.egui_wants_keyboard_input() {
        return;
    }
    ctx.input_mut(|i| {
        let step = if i.modifiers.shift { 10 } else { 1 };
        if i.key_pressed(Key::ArrowRight) {
            commands.push(Command::StepCursor(step));
        }
        if i.key_pressed(Key::ArrowLeft) {
            commands.push(Command::StepCursor(-step));
        }
        if i.consume_key(Modifiers::COMMAND | Modifiers::SHIFT, Key::Z) || i.consume_key(Modifiers::COMMAND, Key::Y) {
            commands.push(Command::Redo);
        }
        if i.consume_key(Modifiers::COMMAND, Key::Z) {
            commands.push(Command::Undo);
        }
        if i.key_pressed(Key::Space) {
            commands.push(Command::TogglePlay);
        }
        if i.key_pressed(Key::E) {
            commands.push(Command::SetEndAtCursor);
        }
        if i.key_pressed(Key::S) {
            commands.push(Command::SetStartAtCursor);
        }
        for (k, key) in [Key::Num1, Key::Num2, Key::Num3, Key::Num4, Key::Num5].into_iter().enumerate() {
            if i.key_pressed(key) {
                commands.push(Command::SelectBoundary(k));
            }
        }
    });
}

/// The top bar: open, detect, undo/redo, save, and what is going on.
pub fn top_bar(ui: &mut egui::Ui, model: &AppModel, state: &mut UiState, commands: &mut Vec<Command>) {
    // Wraps on narrow windows rather than pushing "Save as" out of sight.
    ui.horizontal_wrapped(|ui| {
        for (screen, name) in [(Screen::Annotate, "Annotate"), (Screen::Preview, "Preview"), (Screen::Generate, "Generate")] {
            if ui.add_enabled(model.file.is_some(), egui::Button::selectable(model.screen == screen, name)).clicked()
                && model.screen != screen
            {
                commands.push(Command::Show(screen));
            }
        }
        ui.separator();
        let label = ui.label("Source demos:");
        ui.add(egui::TextEdit::singleline(&mut state.open_path).desired_width(240.0).hint_text("path/to/source.hdf5"))
            .labelled_by(label.id);
        if ui.button("Open").clicked() && !state.open_path.trim().is_empty() {
            commands.push(Command::Open(state.open_path.trim().into()));
        }
        if ui.button("Browse…").on_hover_text("Pick a file from a folder").clicked() {
            let start =
                model.file.as_ref().and_then(|f| f.prepared_from.as_ref().unwrap_or(&f.path).parent().map(std::path::Path::to_path_buf));
            commands.push(Command::Browse(start.filter(|p| !p.as_os_str().is_empty()).unwrap_or_else(|| ".".into())));
        }
        ui.separator();
        let open = model.file.is_some();
        if ui
            .add_enabled(open, egui::Button::new("Auto-detect all"))
            .on_hover_text("Use the proposed subtask ends for every demo")
            .clicked()
        {
            commands.push(Command::AcceptAllProposals);
        }
        if ui.add_enabled(model.annotation.can_undo(), egui::Button::new("Undo")).clicked() {
            commands.push(Command::Undo);
        }
        if ui.add_enabled(model.annotation.can_redo(), egui::Button::new("Redo")).clicked() {
            commands.push(Command::Redo);
        }
        ui.separator();
        match &model.viewer {
            Some(to) => {
                ui.label("3D: Rerun").on_hover_text(format!("Streaming the shown demo and every tried attempt to {to}"));
            }
            None => {
                if ui
                    .add_enabled(open, egui::Button::new("3D view"))
                    .on_hover_text("Start the Rerun viewer and stream the shown demo (and every attempt you try) to it")
                    .clicked()
                {
                    commands.push(Command::Open3d(crate::protocol::ViewerSink::Spawn));
                }
            }
        }
        ui.separator();
        let label = ui.label("Save to:");
        ui.add(egui::TextEdit::singleline(&mut state.save_path).desired_width(180.0).hint_text("annotated.hdf5")).labelled_by(label.id);
        if ui.add_enabled(open && !state.save_path.trim().is_empty(), egui::Button::new("Save as")).clicked() {
            commands.push(Command::Save(state.save_path.trim().into()));
        }
        let mut replace = model.save_overwrite;
        if ui.checkbox(&mut replace, "replace").on_hover_text("Save over an existing file (never over the open one)").changed() {
            commands.push(Command::SetSaveOverwrite(replace));
        }
    });
    ui.horizontal(|ui| {
        if let Some(busy) = &model.busy {
            match model.progress {
                #[allow(clippy::cast_precision_loss)]
                Some((done, total)) if total > 0 => {
                    ui.add(egui::ProgressBar::new(done as f32 / total as f32).desired_width(160.0).show_percentage());
                }
                _ => {
                    ui.spinner();
                }
            }
            ui.label(busy);
        } else if let Some(error) = &model.error {
            ui.colored_label(Color32::from_rgb(220, 60, 60), format!("Error: {error}"));
        } else {
            ui.label(&model.status);
        }
        if model.annotation.dirty {
            ui.label(RichText::new("unsaved changes").italics());
        }
    });
}

/// The demo list.
pub fn demo_list(ui: &mut egui::Ui, model: &AppModel, commands: &mut Vec<Command>) {
    let Some(file) = &model.file else {
        ui.label("Open a MimicGen source file (or drop one here).");
        return;
    };
    ui.heading(format!("{} demos", file.demos.len()));
    egui::ScrollArea::vertical().show_rows(ui, 18.0, file.demos.len(), |ui, rows| {
        for (i, d) in file.demos.iter().enumerate().skip(rows.start).take(rows.len()) {
            let ends = model.annotation.marks.ends.get(&d.name);
            let edited = ends.is_some_and(|e| d.stored_ends.as_ref() != Some(e));
            let text = format!("{}  {} steps{}", d.name, d.len, if edited { "  (edited)" } else { "" });
            if ui.selectable_label(model.selected == i, text).clicked() {
                commands.push(Command::SelectDemo(i));
            }
        }
    });
}

/// The id of timeline plot `name` (`gripper`, `speed`, `distance`, `signals`), where egui_plot
/// keeps its transform (tests find screen positions of steps through it).
#[must_use]
pub fn timeline_plot_id(name: &str) -> egui::Id {
    egui::Id::new(("timeline", name))
}

fn series(values: impl Iterator<Item = f64>) -> PlotPoints<'static> {
    #[allow(clippy::cast_precision_loss)] // step indices are small
    values.enumerate().map(|(t, v)| [t as f64, v]).collect()
}

/// The boundary editor and the linked timeline plots of the shown demo.
pub fn timeline(ui: &mut egui::Ui, model: &AppModel, state: &mut UiState, commands: &mut Vec<Command>) {
    let Some(demo) = model.demo() else { return };
    let ends = model.demo_ends();
    let file = model.file.as_ref();
    ui.horizontal(|ui| {
        ui.heading(&demo.name);
        ui.label(format!("step {} of {}", model.cursor, demo.len.saturating_sub(1)));
        if ui.button("◀").on_hover_text("Step back (Left arrow; Shift for 10)").clicked() {
            commands.push(Command::StepCursor(-1));
        }
        if ui.button(if model.playing { "Pause" } else { "Play" }).on_hover_text("Space").clicked() {
            commands.push(Command::TogglePlay);
        }
        if ui.button("▶").on_hover_text("Step forward (Right arrow; Shift for 10)").clicked() {
            commands.push(Command::StepCursor(1));
        }
        if ui.button("Use proposals").on_hover_text("Set this demo's ends to the proposals").clicked() {
            commands.push(Command::AcceptProposals);
        }
    });
    if let Some(file) = file.filter(|f| !f.arms.is_empty()) {
        arms_overview(ui, model, file, demo.len, commands);
    }
    let starts = model.demo_starts();
    let mut shown_starts = Vec::new();
    for k in 0..=ends.len() {
        let object = file.and_then(|f| f.subtask_objects.get(k).cloned().flatten());
        let (planned, approach_m) = model.approach(k);
        let detected = detected_start(demo, object.as_deref(), &ends, k, approach_m);
        let marked = starts.get(k).copied().flatten();
        ui.horizontal(|ui| {
            let object = object.as_deref().unwrap_or("no object");
            let Some(&end) = ends.get(k) else {
                ui.label(RichText::new(format!("subtask {k} ({object}) ends with the demo")).color(subtask_color(k)));
                segment_start(ui, k, marked, detected, planned, model.cursor, commands);
                return;
            };
            let signal = file.and_then(|f| f.signal_names.get(k)).map_or("", String::as_str);
            let label = RichText::new(format!("subtask {k} ({object}, {signal}) ends at step {}", end - 1)).color(subtask_color(k));
            if ui.selectable_label(model.boundary == k, label).on_hover_text("Select, then press E to move it to the cursor").clicked() {
                commands.push(Command::SelectBoundary(k));
            }
            if ui.small_button("set at cursor").clicked() {
                commands.push(Command::SelectBoundary(k));
                commands.push(Command::SetEndAtCursor);
            }
            if let Some(p) = demo.proposals.get(k) {
                let text = format!("proposed: step {} (confidence {:.1})", p.end - 1, p.confidence);
                ui.label(text).on_hover_text(&p.reason);
            }
            if let Some(stored) = demo.stored_ends.as_ref().and_then(|s| s.get(k)) {
                ui.label(format!("stored signal: step {}", stored - 1));
            }
            segment_start(ui, k, marked, detected, planned, model.cursor, commands);
        });
        shown_starts.push(match marked {
            Some(marked) => Some((marked, true)),
            None => detected.filter(|_| planned).map(|d| (d, false)),
        });
    }
    cameras(ui, model, state);
    plots(ui, demo, &ends, &shown_starts, model.cursor, state, commands);
}

/// A two-arm file's arms, a row each: its name (click to annotate that arm: the ends and plots
/// below are its own) and a bar of the shown demo with its subtasks' spans, the cursor across both.
fn arms_overview(ui: &mut egui::Ui, model: &AppModel, file: &crate::protocol::LoadedFile, len: usize, commands: &mut Vec<Command>) {
    for (k, arm) in file.arms.iter().enumerate() {
        ui.horizontal(|ui| {
            let label = RichText::new(format!("arm {k} ({})", arm.name)).strong();
            if ui.selectable_label(model.arm == k, label).on_hover_text("Annotate this arm: its ends and plots below").clicked() {
                commands.push(Command::SelectArm(k));
            }
            let (rect, response) = ui.allocate_exact_size(egui::vec2(ui.available_width().max(40.0), 14.0), egui::Sense::hover());
            let painter = ui.painter_at(rect);
            #[allow(clippy::cast_precision_loss)] // step indices are small
            let x = |t: usize| rect.left() + rect.width() * (t as f32 / len.max(1) as f32);
            let ends = model.arm_ends(k);
            let mut start = 0;
            let mut spans = Vec::new();
            for (j, &end) in ends.iter().chain(std::iter::once(&len)).enumerate() {
                let span = egui::Rect::from_min_max(egui::pos2(x(start), rect.top()), egui::pos2(x(end), rect.bottom()));
                painter.rect_filled(span, 0.0, subtask_color(j).gamma_multiply(if model.arm == k { 0.9 } else { 0.5 }));
                let signal = arm.signal_names.get(j).map_or_else(|| "the demo's end".to_owned(), Clone::clone);
                spans.push(format!("subtask {j}: steps {start}..{} (ends on {signal})", end.saturating_sub(1)));
                start = end;
            }
            painter.vline(x(model.cursor), rect.y_range(), egui::Stroke::new(1.5, Color32::WHITE));
            response.on_hover_text(spans.join("\n"));
        });
    }
}

/// Where subtask `k`'s segment starts: the marked step, or the approach detector's (`detected`),
/// with buttons to mark the cursor's step and to clear a mark. The start matters where transit is
/// `planned`: the robot plans its way to the segment's first pose and the steps before are skipped.
fn segment_start(
    ui: &mut egui::Ui,
    k: usize,
    marked: Option<usize>,
    detected: Option<usize>,
    planned: bool,
    cursor: usize,
    commands: &mut Vec<Command>,
) {
    ui.separator();
    let text = match (marked, detected) {
        (Some(m), _) => format!("segment starts at step {m} (marked)"),
        (None, Some(d)) => format!("segment starts at step {d} (detected)"),
        (None, None) => "segment starts with the subtask".to_owned(),
    };
    let hint = if planned {
        "Transit to this subtask is planned: the steps before its segment's start are not replayed"
    } else {
        "Used when transit to this subtask is planned (--transit plan); with interpolation the segment starts with the subtask"
    };
    ui.label(RichText::new(text).color(subtask_color(k))).on_hover_text(hint);
    if ui
        .small_button("start at cursor")
        .on_hover_text("Mark the cursor's step as this segment's start (S marks it in the subtask under the cursor)")
        .clicked()
    {
        commands.push(Command::SetStart { subtask: k, start: Some(cursor) });
    }
    if marked.is_some() && ui.small_button("clear start").on_hover_text("Let the approach detector decide").clicked() {
        commands.push(Command::SetStart { subtask: k, start: None });
    }
}

/// The shown demo's camera images at the cursor, when its file has camera observations
/// (`generate --cameras`); the images came with the demo from the backend.
fn cameras(ui: &mut egui::Ui, model: &AppModel, state: &mut UiState) {
    let (demo, cameras) = &model.images;
    if *demo != model.selected || cameras.is_empty() {
        return;
    }
    let step = model.cursor;
    state.camera_textures.retain(|((name, _, _), _)| cameras.iter().any(|c| &c.name == name));
    ui.horizontal(|ui| {
        for camera in cameras {
            let Some(frame) = camera.frame(step) else { continue };
            let key = (camera.name.clone(), *demo, step);
            let image = egui::ColorImage::from_rgb([camera.width, camera.height], frame);
            let texture = match state.camera_textures.iter_mut().find(|(k, _)| k.0 == camera.name) {
                Some((k, texture)) => {
                    if *k != key {
                        texture.set(image, egui::TextureOptions::NEAREST);
                        *k = key;
                    }
                    texture.clone()
                }
                None => {
                    let texture = ui.ctx().load_texture(format!("camera {}", camera.name), image, egui::TextureOptions::NEAREST);
                    state.camera_textures.push((key, texture.clone()));
                    texture
                }
            };
            #[allow(clippy::cast_precision_loss)]
            let size = egui::vec2(camera.width as f32, camera.height as f32) * (168.0 / camera.height.max(1) as f32);
            ui.vertical(|ui| {
                ui.add(egui::Image::new(&texture).fit_to_exact_size(size));
                ui.label(RichText::new(format!("{} (step {step})", camera.name)).small());
            });
        }
    });
}

/// `starts`: per subtask, where its segment starts, and whether that was marked by hand (else
/// detected; only shown for subtasks whose transit is planned).
fn plots(
    ui: &mut egui::Ui,
    demo: &DemoView,
    ends: &[usize],
    starts: &[Option<(usize, bool)>],
    cursor: usize,
    state: &mut UiState,
    commands: &mut Vec<Command>,
) {
    #[allow(clippy::cast_precision_loss)]
    let x = |t: usize| t as f64;
    let n = demo.len;
    let height = ((ui.available_height() - 20.0) / 4.0).max(60.0);
    let mut draw = |ui: &mut egui::Ui, id: &str, lines: Vec<Line<'static>>| {
        let response = Plot::new(id)
            .id(timeline_plot_id(id))
            .height(height)
            .legend(Legend::default().position(Corner::LeftTop))
            .y_axis_min_width(36.0)
            .link_axis("timeline", [true, false])
            .link_cursor("timeline", [true, false])
            .allow_drag(false)
            .allow_boxed_zoom(false)
            .allow_scroll(false)
            .show_x(true)
            .show(ui, |plot| {
                let mut start = 0;
                for (k, &end) in ends.iter().chain(std::iter::once(&n)).enumerate() {
                    plot.span(Span::new(format!("subtask {k}"), x(start)..=x(end)).fill(subtask_color(k).gamma_multiply(0.08)));
                    start = end;
                }
                for line in lines {
                    plot.line(line);
                }
                for (k, &end) in ends.iter().enumerate() {
                    let at = match state.drag {
                        Some((b, pos)) if b == k => pos,
                        _ => x(end - 1),
                    };
                    plot.vline(VLine::new("", at).color(subtask_color(k)).width(2.0));
                }
                for (k, start) in starts.iter().enumerate() {
                    let Some((t, marked)) = *start else { continue };
                    let style = if marked { LineStyle::dashed_dense() } else { LineStyle::dotted_loose() };
                    plot.vline(VLine::new("", x(t)).color(subtask_color(k)).width(if marked { 2.0 } else { 1.0 }).style(style));
                }
                plot.vline(VLine::new("", x(cursor)).color(Color32::GRAY));
                (plot.response().clone(), plot.pointer_coordinate())
            });
        let (response, pointer) = response.inner;
        // A release ends the drag wherever the pointer is (even outside the plot, or gone).
        if response.drag_stopped() {
            if let Some((k, pos)) = state.drag.take() {
                #[allow(clippy::cast_possible_truncation, clippy::cast_sign_loss)]
                commands.push(Command::SetEnd { subtask: k, end: pos as usize + 1 });
            }
            return;
        }
        let Some(pointer) = pointer else { return };
        let step = pointer.x.round().max(0.0);
        if response.drag_started() {
            let nearest = ends
                .iter()
                .enumerate()
                .map(|(k, &e)| (k, (x(e - 1) - pointer.x).abs()))
                .filter(|(_, d)| *d <= 3.0)
                .min_by(|a, b| a.1.total_cmp(&b.1));
            state.drag = nearest.map(|(k, _)| (k, step));
        } else if response.dragged() {
            if let Some((k, _)) = state.drag {
                state.drag = Some((k, step));
            }
        } else if response.clicked() {
            #[allow(clippy::cast_possible_truncation, clippy::cast_sign_loss)]
            commands.push(Command::SetCursor(step as usize));
        }
    };
    let mut gripper = vec![Line::new("gripper command", series(demo.gripper.iter().copied()))];
    if let Some(w) = &demo.finger_width_m {
        gripper.push(Line::new("finger opening (x 10 cm)", series(w.iter().map(|v| v * 10.0))));
    }
    draw(ui, "gripper", gripper);
    draw(ui, "speed", vec![Line::new("end-effector speed (m/s)", series(demo.eef_speed.iter().copied()))]);
    draw(
        ui,
        "distance",
        demo.distances.iter().map(|(name, d)| Line::new(format!("gripper to {name} (m)"), series(d.iter().copied()))).collect(),
    );
    #[allow(clippy::cast_precision_loss)]
    let signals = demo
        .signals
        .iter()
        .enumerate()
        .map(|(k, (name, s))| Line::new(format!("signal {name}"), series(s.iter().map(move |&v| v as f64 + 0.02 * k as f64))))
        .collect();
    draw(ui, "signals", signals);
}

/// The file browser (while one is open): the folder's subfolders and HDF5 files; a click goes into
/// a folder or opens a file. The listing comes from the backend, so no frame reads the disk.
pub fn file_browser(ctx: &egui::Context, model: &AppModel, commands: &mut Vec<Command>) {
    let Some(listing) = &model.browser else { return };
    let mut open = true;
    egui::Window::new("Open a file").open(&mut open).default_size([520.0, 420.0]).collapsible(false).show(ctx, |ui| {
        ui.label(RichText::new(listing.dir.display().to_string()).monospace());
        egui::ScrollArea::vertical().max_height(360.0).show(ui, |ui| {
            if let Some(parent) = &listing.parent
                && ui.selectable_label(false, "⬆ ..").clicked()
            {
                commands.push(Command::Browse(parent.clone()));
            }
            for dir in &listing.dirs {
                let name = dir.file_name().map_or_else(String::new, |n| n.to_string_lossy().into_owned());
                if ui.selectable_label(false, format!("📁 {name}")).clicked() {
                    commands.push(Command::Browse(dir.clone()));
                }
            }
            for (file, bytes) in &listing.files {
                let name = file.file_name().map_or_else(String::new, |n| n.to_string_lossy().into_owned());
                #[allow(clippy::cast_precision_loss)]
                let size = *bytes as f64 / 1e6;
                if ui.selectable_label(false, format!("{name}  ({size:.1} MB)")).clicked() {
                    commands.push(Command::Open(file.clone()));
                }
            }
            if listing.dirs.is_empty() && listing.files.is_empty() {
                ui.label("No folders or HDF5 files here.");
            }
        });
    });
    if !open {
        commands.push(Command::CloseBrowser);
    }
}
