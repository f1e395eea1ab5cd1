//! The preview screen: a new scene from the run's reset distribution, the source demo picked for
//! every subtask (with the selection's ranking), the transformed segments and interpolation
//! bridges seen from above and from the side, the source segments beside them, and the executed
//! path after "try it". Reads the model, returns commands.
#![allow(
    clippy::indexing_slicing,
    reason = "`axes` are the coordinate pairs a view plots, (0, 1) or (0, 2), into 3-vectors and the 3 axis names"
)]

use egui::{Color32, RichText};
use egui_plot::{Arrows, Corner, Legend, Line, LineStyle, MarkerShape, Plot, PlotPoint, PlotPoints, Points, Text};

use crate::model::{AppModel, Command};
use crate::protocol::{ExecutedView, Point, PreviewView};
use crate::style::subtask_color;

/// The preview screen's own state.
#[derive(Debug, Default)]
pub struct PreviewUiState {
    /// An object being dragged in the view from above: (name, current x, y).
    pub object_drag: Option<(String, [f64; 2])>,
}

/// The id of preview plot `name` (`top`, `side`), where egui_plot keeps its transform (tests find
/// screen positions of objects through it).
#[must_use]
pub fn preview_plot_id(name: &str) -> egui::Id {
    egui::Id::new(("preview", name))
}

/// How close (in screen points) a press must be to an object to pick it up.
const PICK_RADIUS_PX: f32 = 12.0;

/// Colour of the executed path (and the objects where it left them): bright on the dark theme.
const EXECUTED: Color32 = Color32::from_rgb(235, 235, 235);
/// Planned collision-free transit (the Rerun stream's colour for it too).
const TRANSIT: Color32 = Color32::from_rgb(0, 206, 180);
/// The hand riding a mobile base's drive (copied from the source).
const BASE_DRIVE: Color32 = Color32::from_rgb(150, 110, 60);
/// Executed path of a two-arm attempt's second arm (the first's is [`EXECUTED`]).
const EXECUTED_SECOND: Color32 = Color32::from_rgb(250, 210, 120);

/// The controls: seed, scene, source per subtask with its ranking, "try it" and its outcome.
pub fn controls(ui: &mut egui::Ui, model: &AppModel, commands: &mut Vec<Command>) {
    let Some(file) = &model.file else {
        ui.label("Open a source file first.");
        return;
    };
    let p = &model.preview;
    ui.heading("Scene");
    egui::Grid::new("scene").num_columns(2).show(ui, |ui| {
        ui.label("Run seed");
        let mut seed = p.seed;
        if ui.add(egui::DragValue::new(&mut seed)).on_hover_text("mimicgen generate --seed").changed() {
            commands.push(Command::SetPreviewSeed(seed));
        }
        ui.end_row();
        ui.label("Attempt");
        let mut index = p.index;
        if ui.add(egui::DragValue::new(&mut index)).on_hover_text("Attempt k of the run: its scene, offsets and noise").changed() {
            commands.push(Command::SetPreviewIndex(index));
        }
        ui.end_row();
    });
    ui.horizontal(|ui| {
        if ui.button("New scene").on_hover_text("The next attempt's scene from the variant's reset distribution").clicked() {
            commands.push(Command::NextScene);
        }
        if !p.moved.is_empty()
            && ui.button("Reset objects").on_hover_text("Put the objects you dragged back where the scene had them").clicked()
        {
            commands.push(Command::ResetObjects);
        }
        if ui.button("Try it").on_hover_text("Execute this attempt in MuJoCo, exactly as generate would").clicked() {
            commands.push(Command::TryIt);
        }
    });
    let Some(view) = &p.view else { return };
    ui.label(format!("{} {}: attempt {} of seed {}", view.task, view.variant, view.index, view.seed));
    if p.moved.is_empty() {
        ui.label(RichText::new("Drag an object in the view from above to move it.").italics());
    } else {
        let moved: Vec<&str> = p.moved.keys().map(String::as_str).collect();
        ui.label(format!("Moved by hand: {}", moved.join(", ")));
    }
    if let Some(e) = &view.executed {
        let (text, color) = if e.success {
            (format!("Tried: success in {} steps", e.path.len()), Color32::from_rgb(30, 140, 60))
        } else {
            (
                format!(
                    "Tried: failed ({}){}",
                    e.failure.as_deref().unwrap_or(""),
                    e.cause.as_ref().map_or(String::new(), |c| format!(": {c}"))
                ),
                Color32::from_rgb(200, 50, 50),
            )
        };
        ui.label(RichText::new(text).color(color).strong());
        diagnostics(ui, "diagnostics", e);
    }
    ui.separator();
    egui::ScrollArea::vertical().show(ui, |ui| {
        for (k, s) in view.subtasks.iter().enumerate() {
            let object = s.object.as_deref().unwrap_or("no object");
            ui.label(RichText::new(format!("Subtask {k} (relative to {object})")).color(subtask_color(k)).strong());
            let forced = p.sources.get(k).copied().flatten();
            let chosen = match forced {
                Some(d) => file.demos.get(d).map_or_else(String::new, |d| d.name.clone()),
                None => format!("selection picks ({})", s.src_demo_name),
            };
            egui::ComboBox::from_id_salt(("source", k)).selected_text(chosen).show_ui(ui, |ui| {
                if ui.selectable_label(forced.is_none(), "selection picks").clicked() {
                    commands.push(Command::SetPreviewSource { subtask: k, demo: None });
                }
                for (d, demo) in file.demos.iter().enumerate() {
                    if ui.selectable_label(forced == Some(d), &demo.name).clicked() {
                        commands.push(Command::SetPreviewSource { subtask: k, demo: Some(d) });
                    }
                }
            });
            ui.label(format!("segment: steps {}..{} of {}", s.src_span.0, s.src_span.1, s.src_demo_name));
            if s.ranking.is_empty() {
                ui.label(RichText::new("no ranking (source kept from the previous subtask, or random selection)").italics());
            } else {
                egui::Grid::new(("ranking", k)).striped(true).num_columns(3).show(ui, |ui| {
                    ui.label("rank");
                    ui.label("demo");
                    ui.label("distance");
                    ui.end_row();
                    for (rank, r) in s.ranking.iter().enumerate().take(10) {
                        let text = |t: String| if r.demo == s.src_demo { RichText::new(t).strong() } else { RichText::new(t) };
                        ui.label(text(format!("{}", rank + 1)));
                        ui.label(text(r.name.clone()));
                        ui.label(text(format!("{:.3}", r.distance)));
                        ui.end_row();
                    }
                });
            }
            ui.add_space(6.0);
        }
    });
}

/// What went wrong in numbers, per subtask of an executed attempt.
pub fn diagnostics(ui: &mut egui::Ui, id: &str, e: &ExecutedView) {
    let opt = |v: Option<f64>| v.map_or_else(|| "-".to_owned(), |v| format!("{v:.1}"));
    egui::Grid::new(id).striped(true).num_columns(5).show(ui, |ui| {
            for head in ["subtask", "steps", "to target (mm)", "object moved (mm)", "held slip (mm)"] {
                ui.label(RichText::new(head).small());
            }
            ui.end_row();
            for d in &e.diagnostics {
                ui.label(format!("{}", d.subtask));
                ui.label(format!("{}..{}", d.steps.0, d.steps.1));
                ui.label(format!("{:.1}", d.target_error_mm));
                ui.label(opt(d.object_moved_mm));
                ui.label(opt(d.held_object_slip_mm));
                ui.end_row();
            }
        })
        .response
        .on_hover_text("At each subtask's end: the distance from the controller's last target to the gripper; how far the subtask's object moved during it (a grasp that pushed the cube); how far the object held from the previous subtask slid in the gripper");
}

fn xy(points: &[Point], axes: (usize, usize)) -> PlotPoints<'static> {
    points.iter().map(|p| [p[axes.0], p[axes.1]]).collect()
}

/// One view of the scene: `axes` picks the plotted coordinates ((0, 1) from above, (0, 2) from
/// the side). With `drag` (the preview screen's), objects can be dragged in the view from above.
/// Small views leave the legend out (`legend` false).
pub fn view_plot(
    ui: &mut egui::Ui,
    id: &str,
    view: &PreviewView,
    axes: (usize, usize),
    size: egui::Vec2,
    legend: bool,
    drag: Option<(&mut PreviewUiState, &mut Vec<Command>)>,
) {
    let names = ["x (m)", "y (m)", "z (m)"];
    let top = axes == (0, 1) && drag.is_some();
    let dragged = drag.as_ref().and_then(|(state, _)| state.object_drag.clone());
    let mut plot = Plot::new(id);
    if legend {
        plot = plot.legend(Legend::default().position(Corner::LeftBottom).background_alpha(0.6));
    }
    let response = plot
        .id(preview_plot_id(id))
        .allow_drag(!top)
        .width(size.x)
        .height(size.y)
        .data_aspect(1.0)
        .x_axis_label(names[axes.0])
        .y_axis_label(names[axes.1])
        .show(ui, |plot| {
            for (k, s) in view.subtasks.iter().enumerate() {
                let color = subtask_color(k);
                plot.line(
                    Line::new(format!("source segment {k} ({})", s.src_demo_name), xy(&s.source_path, axes))
                        .color(color.gamma_multiply(0.35))
                        .style(LineStyle::dotted_dense()),
                );
                plot.line(Line::new(format!("bridge {k}"), xy(&s.bridge, axes)).color(color).style(LineStyle::dashed_dense()).width(1.5));
                if !s.transit.is_empty() {
                    plot.line(Line::new(format!("planned transit {k}"), xy(&s.transit, axes)).color(TRANSIT).width(2.0));
                }
                if !s.drive.is_empty() {
                    plot.line(
                        Line::new(format!("base drive {k}"), xy(&s.drive, axes))
                            .color(BASE_DRIVE)
                            .width(2.0)
                            .style(LineStyle::dashed_loose()),
                    );
                }
                plot.line(Line::new(format!("transformed {k}"), xy(&s.transformed, axes)).color(color).width(2.5));
                if let Some(o) = s.source_object {
                    plot.points(
                        Points::new(format!("source segment {k} ({})", s.src_demo_name), PlotPoints::new(vec![[o[axes.0], o[axes.1]]]))
                            .shape(MarkerShape::Square)
                            .filled(false)
                            .radius(6.0)
                            .color(color.gamma_multiply(0.5)),
                    );
                }
            }
            for (a, arm) in view.arms.iter().enumerate() {
                for (k, segment) in arm.segments.iter().enumerate() {
                    let style = if a == 0 { LineStyle::Solid } else { LineStyle::dashed_loose() };
                    plot.line(
                        Line::new(format!("{} subtask {k}", arm.name), xy(segment, axes)).color(subtask_color(k)).width(2.5).style(style),
                    );
                }
                let color = if a == 0 { EXECUTED } else { EXECUTED_SECOND };
                plot.line(Line::new(format!("{} executed", arm.name), xy(&arm.path, axes)).color(color).width(1.5));
            }
            for tie in &view.ties {
                let (from, to) = ([tie.from_point[axes.0], tie.from_point[axes.1]], [tie.to_point[axes.0], tie.to_point[axes.1]]);
                let name = |(a, k): (usize, usize)| format!("{} subtask {k}", view.arms.get(a).map_or("arm", |arm| arm.name.as_str()));
                if tie.coordination {
                    let label = format!("coordination: {} with {} (steps {}..{})", name(tie.from), name(tie.to), tie.steps.0, tie.steps.1);
                    plot.line(
                        Line::new(label, PlotPoints::new(vec![from, to])).color(subtask_color(tie.from.1).gamma_multiply(0.4)).width(9.0),
                    );
                } else {
                    let label =
                        format!("sequential: {} after {} (step {} after {})", name(tie.to), name(tie.from), tie.steps.1, tie.steps.0);
                    plot.arrows(Arrows::new(label, PlotPoints::new(vec![from]), PlotPoints::new(vec![to])).color(Color32::LIGHT_RED));
                }
            }
            if let Some(e) = view.executed.as_ref() {
                if view.arms.is_empty() {
                    plot.line(Line::new("executed", xy(&e.path, axes)).color(EXECUTED).width(1.5));
                }
                for o in &e.final_objects {
                    plot.points(
                        Points::new("executed", PlotPoints::new(vec![[o.position[axes.0], o.position[axes.1]]]))
                            .shape(MarkerShape::Diamond)
                            .radius(5.0)
                            .color(EXECUTED),
                    );
                }
            }
            plot.points(
                Points::new("gripper start", PlotPoints::new(vec![[view.eef[axes.0], view.eef[axes.1]]]))
                    .shape(MarkerShape::Circle)
                    .radius(5.0)
                    .color(Color32::GRAY),
            );
            for o in &view.objects {
                let at = match &dragged {
                    Some((name, xy)) if top && *name == o.name => *xy,
                    _ => [o.position[axes.0], o.position[axes.1]],
                };
                plot.points(
                    Points::new("objects", PlotPoints::new(vec![at]))
                        .shape(MarkerShape::Square)
                        .radius(7.0)
                        .color(Color32::from_rgb(120, 90, 60)),
                );
                plot.text(Text::new("objects", PlotPoint::new(at[0], at[1]), format!("  {}", o.name)).anchor(egui::Align2::LEFT_CENTER));
            }
            (plot.response().clone(), plot.pointer_coordinate(), *plot.transform())
        });
    let Some((state, commands)) = drag.filter(|_| top) else { return };
    let (response, pointer, transform) = response.inner;
    if response.drag_stopped() {
        if let Some((name, xy)) = state.object_drag.take() {
            commands.push(Command::MoveObject { name, xy });
        }
        return;
    }
    let Some(pointer) = pointer else { return };
    if response.drag_started() {
        let at = transform.position_from_point(&pointer);
        state.object_drag = view
            .objects
            .iter()
            .map(|o| (o, transform.position_from_point(&PlotPoint::new(o.position[0], o.position[1])).distance(at)))
            .filter(|(_, d)| *d <= PICK_RADIUS_PX)
            .min_by(|a, b| a.1.total_cmp(&b.1))
            .map(|(o, _)| (o.name.clone(), [pointer.x, pointer.y]));
    } else if response.dragged()
        && let Some((_, xy)) = &mut state.object_drag
    {
        *xy = [pointer.x, pointer.y];
    }
}

/// The scene from above (objects can be dragged there) and from the side.
pub fn views(ui: &mut egui::Ui, model: &AppModel, state: &mut PreviewUiState, commands: &mut Vec<Command>) {
    let Some(view) = &model.preview.view else {
        ui.label("Planning the first scene...");
        return;
    };
    ui.label("Solid: transformed segments; dashed: interpolation bridges; teal: planned collision-free transit (--transit plan); dotted: the source segments in their own scene; white: the executed path (after Try it), diamonds where it left the objects.");
    let size = egui::vec2((ui.available_width() - 12.0) / 2.0, ui.available_height() - 8.0);
    ui.horizontal(|ui| {
        ui.vertical(|ui| {
            ui.strong("From above");
            view_plot(ui, "top", view, (0, 1), size - egui::vec2(0.0, 20.0), true, Some((&mut *state, &mut *commands)));
        });
        ui.vertical(|ui| {
            ui.strong("From the side");
            view_plot(ui, "side", view, (0, 2), size - egui::vec2(0.0, 20.0), true, None);
        });
    });
}
