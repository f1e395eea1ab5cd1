//! The generate screen: the run form (what `mimicgen generate` takes, and the command line that
//! makes the same run), then, live: progress with ETA, the generation rate over attempts,
//! attempts and successes per source demo, failures by subtask and reason, the initial scenes from
//! above coloured by outcome, support coverage against uniformly spread scenes with histograms per
//! object coordinate, and the attempt table (filter, sort, re-run one in the preview).
//! Reads the model, returns commands.

use std::collections::BTreeMap;

use egui::{Color32, RichText};
use egui_plot::{Bar, BarChart, Corner, Legend, Line, MarkerShape, Plot, PlotPoints, Points};
use mimicgen_engine::Pose;
use mimicgen_engine::coverage::{Coordinate, Coverage, Dimension, coverage, uniform_support_coverage};
use mimicgen_engine::pose::{Rot, Vec3, pose_from_parts};
use mimicgen_engine::spec::Transit;

use mimicgen_run::{CameraConfig, OffsetRange, Scoped, SpecOverrides};

use crate::model::{AppModel, Command, RunState, SideBySide};
use crate::protocol::{AttemptRow, OpenedRun};
use crate::ui::UiState;

/// Colour of successes in the run's plots.
const SUCCESS: Color32 = Color32::from_rgb(60, 180, 90);
/// Colour of failures in the run's plots.
const FAILURE: Color32 = Color32::from_rgb(220, 70, 70);

/// Which attempts the table lists.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum AttemptFilter {
    /// Every attempt.
    #[default]
    All,
    /// Successes only.
    Successes,
    /// Failures only.
    Failures,
}

/// The camera rows of the run form: on or off, which cameras, their size and depth.
fn cameras(ui: &mut egui::Ui, cameras: &mut Option<CameraConfig>) {
    ui.label("");
    let mut on = cameras.is_some();
    if ui.checkbox(&mut on, "render cameras").on_hover_text("--cameras: images into every kept demo (obs/<camera>_image)").changed() {
        *cameras = on.then(CameraConfig::default);
    }
    ui.end_row();
    let Some(c) = cameras else { return };
    let label = ui.label("Cameras:");
    let mut names = c.names.join(",");
    if ui.add(egui::TextEdit::singleline(&mut names).desired_width(180.0)).labelled_by(label.id).changed() {
        c.names = names.split(',').map(str::trim).filter(|n| !n.is_empty()).map(str::to_owned).collect();
    }
    ui.end_row();
    ui.label("Image size");
    ui.horizontal(|ui| {
        ui.add(egui::DragValue::new(&mut c.height).range(8..=1024)).on_hover_text("--camera-size: height");
        ui.label("x");
        ui.add(egui::DragValue::new(&mut c.width).range(8..=1024)).on_hover_text("--camera-size: width");
        ui.checkbox(&mut c.depth, "depth").on_hover_text("--camera-depth");
    });
    ui.end_row();
}

/// The run form, "Copy as command", Start and Cancel; and opening a finished run's outputs.
pub fn form(ui: &mut egui::Ui, model: &AppModel, state: &mut UiState, commands: &mut Vec<Command>) {
    let Some(file) = &model.file else {
        ui.label("Open a source file first.");
        return;
    };
    let running = model.run.as_ref().is_some_and(RunState::running);
    let mut f = model.run_form.clone();
    ui.heading("Run");
    ui.add_enabled_ui(!running, |ui| {
        egui::Grid::new("run_form").num_columns(2).show(ui, |ui| {
            ui.label(if f.guarantee { "Successes" } else { "Attempts" });
            ui.add(egui::DragValue::new(&mut f.attempts).range(1..=1_000_000)).on_hover_text("--num-demos");
            ui.end_row();
            ui.label("");
            ui.checkbox(&mut f.guarantee, "until that many successes").on_hover_text("--guarantee");
            ui.end_row();
            ui.label("Seed");
            ui.add(egui::DragValue::new(&mut f.seed)).on_hover_text("--seed: the same seed gives the same dataset");
            ui.end_row();
            ui.label("Workers");
            ui.add(egui::DragValue::new(&mut f.workers).range(1..=model.welcome.cores.max(1)))
                .on_hover_text("--workers: the dataset does not depend on it");
            ui.end_row();
            let label = ui.label("Output:");
            ui.add(egui::TextEdit::singleline(&mut f.out).desired_width(180.0)).labelled_by(label.id);
            ui.end_row();
            ui.label("");
            ui.checkbox(&mut f.keep_failed, "keep failed attempts").on_hover_text("--keep-failed: OUT_failed.hdf5, for the failure views");
            ui.end_row();
            ui.label("");
            ui.checkbox(&mut f.early_abort, "end attempts at a missed subtask").on_hover_text("--early-abort");
            ui.end_row();
            ui.label("");
            ui.checkbox(&mut f.overwrite, "replace existing outputs").on_hover_text("--overwrite");
            ui.end_row();
            ui.label("Variant");
            let variants = &file.variants;
            egui::ComboBox::from_id_salt("variant").selected_text(f.variant.clone().unwrap_or_else(|| "the file's".to_owned())).show_ui(
                ui,
                |ui| {
                    ui.selectable_value(&mut f.variant, None, "the file's");
                    for v in variants {
                        ui.selectable_value(&mut f.variant, Some(v.clone()), v.as_str());
                    }
                },
            );
            ui.end_row();
            let label = ui.label("Robot");
            let robots = &model.welcome.robots;
            egui::ComboBox::from_id_salt("robot")
                .selected_text(f.robot.clone().unwrap_or_else(|| "the sources'".to_owned()))
                .show_ui(ui, |ui| {
                    ui.selectable_value(&mut f.robot, None, "the sources'");
                    for r in robots {
                        ui.selectable_value(&mut f.robot, Some(r.clone()), r.as_str());
                    }
                })
                .response
                .labelled_by(label.id)
                .on_hover_text("--robot: generate with this arm from the same source demos (robot transfer)");
            ui.end_row();
            cameras(ui, &mut f.cameras);
        });
        egui::CollapsingHeader::new("Spec fields")
            .default_open(!f.spec.is_empty())
            .show(ui, |ui| spec_fields(ui, &mut f.spec, file.subtask_objects.len()));
    });
    if f != model.run_form {
        commands.push(Command::SetRunForm(Box::new(f.clone())));
    }
    ui.label(RichText::new(format!("task {} (the source's); source: {}", file.task, file.path.display())).small());
    ui.horizontal(|ui| {
        if ui.add_enabled(!running, egui::Button::new("Start")).clicked() {
            commands.push(Command::StartRun);
        }
        let cancelling = model.run.as_ref().is_some_and(|r| r.cancelling);
        if ui
            .add_enabled(running && !cancelling, egui::Button::new("Cancel"))
            .on_hover_text("Stops after the attempts already decided; the outputs stay valid")
            .clicked()
        {
            commands.push(Command::CancelRun);
        }
        if ui.button("Copy as command").on_hover_text("The mimicgen generate line for the same run").clicked() {
            ui.ctx().copy_text(f.command_line(&file.path));
        }
    });
    ui.label(RichText::new(f.command_line(&file.path)).monospace().small());
    if model.annotation.dirty {
        ui.label(RichText::new("Unsaved subtask ends: a run reads the ends saved in the file.").italics());
    }
    ui.separator();
    ui.heading("Open a run");
    ui.horizontal(|ui| {
        let label = ui.label("Dataset:");
        ui.add(egui::TextEdit::singleline(&mut state.run_path).desired_width(150.0).hint_text("out/generated.hdf5"))
            .labelled_by(label.id)
            .on_hover_text("What mimicgen generate wrote; its _failed.hdf5 and .json report are read too");
        if ui.add_enabled(!running && !state.run_path.trim().is_empty(), egui::Button::new("Open run")).clicked() {
            commands.push(Command::OpenRun(state.run_path.trim().into()));
        }
        if ui
            .add_enabled(!state.run_path.trim().is_empty(), egui::Button::new("Compare"))
            .on_hover_text("Show this run's coverage beside the current one's (D0 against D1, careful against hasty sources)")
            .clicked()
        {
            commands.push(Command::OpenCompare(state.run_path.trim().into()));
        }
    });
    if let Some(other) = &model.compare {
        ui.horizontal(|ui| {
            ui.label(format!("comparing with {}", other.path.display()));
            if ui.small_button("stop").clicked() {
                commands.push(Command::CloseCompare);
            }
        });
    }
}

/// The value of `values` set for exactly `subtask` (the last one).
fn scoped<T: Clone>(values: &[Scoped<T>], subtask: Option<usize>) -> Option<T> {
    values.iter().rev().find(|s| s.subtask == subtask).map(|s| s.value.clone())
}

/// Sets (or with `None`, clears) the value of `values` for exactly `subtask`.
fn set_scoped<T>(values: &mut Vec<Scoped<T>>, subtask: Option<usize>, value: Option<T>) {
    values.retain(|s| s.subtask != subtask);
    values.extend(value.map(|value| Scoped { subtask, value }));
}

/// A spec field the run may set: unchecked, the spec's value; checked, `widget` edits it.
fn optional<T: Clone>(
    ui: &mut egui::Ui,
    name: &str,
    flag: &str,
    value: Option<T>,
    default: T,
    widget: impl FnOnce(&mut egui::Ui, &mut T),
) -> Option<T> {
    let mut set = value.is_some();
    ui.checkbox(&mut set, name).on_hover_text(format!("{flag}; unchecked: the spec's value"));
    let mut v = value.unwrap_or(default);
    if set {
        widget(ui, &mut v);
    } else {
        ui.label(RichText::new("spec's").weak());
    }
    ui.end_row();
    set.then_some(v)
}

/// Selection per subtask, then noise, offsets and interpolation for all subtasks (the CLI takes
/// those per subtask too: `--action-noise 1:0.02`).
fn spec_fields(ui: &mut egui::Ui, spec: &mut SpecOverrides, subtasks: usize) {
    const STRATEGIES: [&str; 3] = ["random", "nearest_neighbor_object", "nearest_neighbor_robot_distance"];
    egui::Grid::new("spec_fields").num_columns(2).show(ui, |ui| {
        for k in 0..subtasks {
            let current = scoped(&spec.selection, Some(k));
            ui.label(format!("subtask {k} selection"));
            let mut chosen = current.clone();
            egui::ComboBox::from_id_salt(("selection", k)).selected_text(chosen.clone().unwrap_or_else(|| "spec's".to_owned())).show_ui(
                ui,
                |ui| {
                    ui.selectable_value(&mut chosen, None, "spec's");
                    for s in STRATEGIES {
                        ui.selectable_value(&mut chosen, Some(s.to_owned()), s);
                    }
                },
            );
            ui.end_row();
            if chosen != current {
                set_scoped(&mut spec.selection, Some(k), chosen.clone());
            }
            if chosen.as_deref() != Some("random") {
                let nn_k = optional(ui, &format!("subtask {k} nn_k"), "--nn-k", scoped(&spec.nn_k, Some(k)), 3, |ui, v| {
                    ui.add(egui::DragValue::new(v).range(1..=100));
                });
                set_scoped(&mut spec.nn_k, Some(k), nn_k);
            } else {
                set_scoped(&mut spec.nn_k, Some(k), None);
            }
        }
        let noise = optional(ui, "action noise", "--action-noise", scoped(&spec.action_noise, None), 0.05, |ui, v| {
            ui.add(egui::DragValue::new(v).range(0.0..=1.0).speed(0.005).max_decimals(3));
        });
        set_scoped(&mut spec.action_noise, None, noise);
        let steps = optional(ui, "interpolation steps", "--interpolation-steps", scoped(&spec.interpolation_steps, None), 5, |ui, v| {
            ui.add(egui::DragValue::new(v).range(0..=200));
        });
        set_scoped(&mut spec.interpolation_steps, None, steps);
        let fixed = optional(ui, "fixed steps", "--fixed-steps", scoped(&spec.fixed_steps, None), 0, |ui, v| {
            ui.add(egui::DragValue::new(v).range(0..=200));
        });
        set_scoped(&mut spec.fixed_steps, None, fixed);
        let offsets = optional(ui, "end offset range", "--offset-range", scoped(&spec.offset_range, None), OffsetRange(0, 0), |ui, v| {
            ui.horizontal(|ui| {
                ui.add(egui::DragValue::new(&mut v.0).range(-100..=v.1));
                ui.label("to");
                ui.add(egui::DragValue::new(&mut v.1).range(v.0..=100));
            });
        });
        set_scoped(&mut spec.offset_range, None, offsets);
        let per_subtask = optional(ui, "source per subtask", "--select-src-per-subtask", spec.select_src_per_subtask, true, |ui, v| {
            ui.checkbox(v, "choose at every subtask");
        });
        spec.select_src_per_subtask = per_subtask;
        let transit = optional(ui, "transit", "--transit", scoped(&spec.transit, None), Transit::Plan, |ui, v| {
            ui.horizontal(|ui| {
                ui.selectable_value(v, Transit::Interpolate, "interpolate");
                ui.selectable_value(v, Transit::Plan, "plan").on_hover_text(
                    "a collision-free path to where the approach to the object begins (SkillGen); for cluttered scenes (C0)",
                );
            });
        });
        set_scoped(&mut spec.transit, None, transit);
    });
}

/// Target, done and ETA of a run.
fn progress_line(run: &RunState) -> (f32, String) {
    let guarantee = run.config.guarantee;
    let target = run.info.as_ref().map_or(run.config.num_demos.unwrap_or(1), |i| i.target).max(1);
    let (attempts, successes) = run.stats().map_or((0, 0), |s| (s.attempts, s.successes));
    let done = if guarantee { successes } else { attempts };
    let elapsed = run.rows.last().map_or(0.0, |r| r.elapsed_s);
    #[allow(clippy::cast_precision_loss)]
    let eta = if done > 0 && done < target { elapsed / done as f64 * (target - done) as f64 } else { 0.0 };
    #[allow(clippy::cast_precision_loss)]
    let rate = if attempts > 0 { 100.0 * successes as f64 / attempts as f64 } else { 0.0 };
    let state = match (&run.report, &run.error) {
        (Some(r), _) if r.cancelled => "cancelled".to_owned(),
        (Some(_), _) => "done".to_owned(),
        (None, Some(_)) => "stopped on an error".to_owned(),
        (None, None) if run.cancelling => "cancelling".to_owned(),
        (None, None) => format!("ETA {eta:.0} s"),
    };
    #[allow(clippy::cast_precision_loss)]
    let fraction = (done as f32 / target as f32).min(1.0);
    (fraction, format!("{attempts} attempts, {successes} successes ({rate:.1} %) in {elapsed:.1} s; {state}"))
}

/// Live progress, charts and the attempt table of the last run.
pub fn progress(ui: &mut egui::Ui, model: &AppModel, state: &mut UiState, commands: &mut Vec<Command>) {
    let Some(run) = &model.run else {
        ui.label(
            "Fill in the run on the left and press Start. The run goes on in the background; every attempt shows up here as it is decided.",
        );
        return;
    };
    let (fraction, text) = progress_line(run);
    ui.add(egui::ProgressBar::new(fraction).text(text));
    if let Some(report) = &run.report {
        ui.label(format!(
            "dataset {}{}",
            report.output,
            report.failed_output.as_ref().map_or(String::new(), |f| format!(", failed attempts {f}"))
        ));
    }
    if let Some(pair) = &model.side_by_side {
        side_by_side(ui, run, pair, model.viewer.is_some(), commands);
        ui.separator();
        attempt_table(ui, model, run, state, commands);
        return;
    }
    let height = 190.0;
    let width = (ui.available_width() - 16.0) / 3.0;
    ui.horizontal(|ui| {
        rate_plot(ui, run, egui::vec2(width, height));
        source_plot(ui, run, egui::vec2(width, height));
        scene_plot(ui, run, egui::vec2(width, height));
    });
    // Live runs count failures as they go; an opened run has them from its report.
    let failures: Vec<(usize, String, usize)> = match run.stats().filter(|s| !s.failures.is_empty()) {
        Some(stats) => stats.failures.iter().map(|f| (f.subtask, f.reason.to_string(), f.count)).collect(),
        None => run.report.iter().flat_map(|r| &r.failures).map(|f| (f.subtask, f.reason.clone(), f.count)).collect(),
    };
    if !failures.is_empty() {
        ui.strong("Failures by subtask and reason");
        egui::Grid::new("failures").striped(true).num_columns(3).show(ui, |ui| {
            for (subtask, reason, count) in &failures {
                ui.label(format!("subtask {subtask}"));
                ui.label(reason);
                ui.label(format!("{count}"));
                ui.end_row();
            }
        });
    }
    let instances = instance_rates(&run.rows);
    if !instances.is_empty() {
        ui.strong("Success by object instance");
        egui::Grid::new("instances").striped(true).num_columns(3).show(ui, |ui| {
            for (label, successes, attempts) in &instances {
                ui.label(label);
                ui.label(format!("{successes} of {attempts}"));
                #[allow(clippy::cast_precision_loss)] // counts of attempts
                ui.label(format!("{:.1} %", 100.0 * *successes as f64 / *attempts as f64));
                ui.end_row();
            }
        });
    }
    if let Some(report) = run.report.as_ref().filter(|r| r.attempts > run.rows.len()) {
        ui.label(RichText::new(format!(
            "{} of {} attempts are in the files: failures not kept (beyond max_num_failures, or without --keep-failed) are only counted",
            run.rows.len(),
            report.attempts
        ))
        .italics());
    }
    coverage_view(ui, run, model.compare.as_ref(), &mut state.coverage);
    ui.separator();
    attempt_table(ui, model, run, state, commands);
}

/// Per object instance (object transfer runs: which mug each episode drew), its successes and
/// attempts among `rows`, by label; empty when no row names an instance.
#[must_use]
pub fn instance_rates(rows: &[AttemptRow]) -> Vec<(String, usize, usize)> {
    let mut counts: BTreeMap<&str, (usize, usize)> = BTreeMap::new();
    for row in rows {
        if let Some(label) = &row.instance {
            let entry = counts.entry(label).or_default();
            entry.0 += usize::from(row.success);
            entry.1 += 1;
        }
    }
    counts.into_iter().map(|(label, (ok, tried))| (label.to_owned(), ok, tried)).collect()
}

/// A failed attempt and a successful one, re-run, side by side: outcome, sources, what went wrong
/// in numbers, and both from above and from the side (from above only when `compact`: beside the
/// 3D view, which shows them whole).
fn side_by_side(ui: &mut egui::Ui, run: &RunState, pair: &SideBySide, compact: bool, commands: &mut Vec<Command>) {
    ui.horizontal(|ui| {
        ui.strong(format!("Attempt {} beside attempt {}", pair.indices[0], pair.indices[1]));
        if ui.button("Back to the charts").clicked() {
            commands.push(Command::CloseSideBySide);
        }
    });
    let Some(views) = &pair.views else {
        ui.label("Re-running both attempts...");
        return;
    };
    ui.label(
        RichText::new(
            "Solid: transformed segments (colour per subtask); dashed: interpolation bridges; teal: planned transit; dotted: the source segments in their own scene; white: the executed path, diamonds where it left the objects; brown squares: the objects at the start.",
        )
        .small(),
    );
    let width = (ui.available_width() - 16.0) / 2.0;
    let height = if compact { 150.0 } else { ((ui.available_height() - 260.0) / 2.0).clamp(120.0, 320.0) };
    ui.horizontal_top(|ui| {
        for (k, view) in views.iter().enumerate() {
            ui.vertical(|ui| {
                ui.set_width(width);
                let row = run.rows.iter().find(|r| r.index == view.index);
                if let Some(e) = &view.executed {
                    let text = if e.success {
                        format!("attempt {}: success in {} steps", view.index, e.path.len())
                    } else {
                        format!("attempt {}: failed ({})", view.index, e.failure.as_deref().unwrap_or(""))
                    };
                    ui.label(RichText::new(text).color(if e.success { SUCCESS } else { FAILURE }).strong());
                    if row.is_some_and(|r| r.success != e.success) {
                        ui.label(RichText::new("the re-run's outcome differs from the run's").color(FAILURE));
                    }
                    let sources: Vec<String> = e.sources.iter().map(|d| format!("demo_{d}")).collect();
                    ui.label(format!("sources: {}", sources.join(",")));
                    crate::preview_ui::diagnostics(ui, &format!("pair_diagnostics_{k}"), e);
                }
                crate::preview_ui::view_plot(ui, &format!("pair{k}_top"), view, (0, 1), egui::vec2(width, height), false, None);
                if !compact {
                    crate::preview_ui::view_plot(ui, &format!("pair{k}_side"), view, (0, 2), egui::vec2(width, height), false, None);
                }
            });
        }
    });
}

/// Bins per coordinate of the support coverage (the paper's appendix uses 3).
const SUPPORT_BINS: usize = 3;
/// Bins per coordinate of the histograms.
const HISTOGRAM_BINS: usize = 10;

/// The initial scenes of `rows` as object poses (for the engine's coverage analysis).
fn scenes<'a>(rows: impl Iterator<Item = &'a AttemptRow>) -> Vec<BTreeMap<String, Pose>> {
    rows.map(|r| {
        r.objects
            .iter()
            .map(|o| {
                (
                    o.name.clone(),
                    pose_from_parts(Vec3::new(o.position[0], o.position[1], o.position[2]), Rot::from_axis_angle(&Vec3::z_axis(), o.yaw)),
                )
            })
            .collect()
    })
    .collect()
}

/// Support coverage of the run's initial scenes (all, successes, failures) against uniformly
/// spread scenes, and per-coordinate histograms over the reset region, successes and failures
/// stacked: the numbers `mimicgen coverage` prints, from the same function. With a run to compare
/// with, its numbers and histograms follow on a second row.
fn coverage_view(ui: &mut egui::Ui, run: &RunState, compare: Option<&OpenedRun>, cache: &mut Vec<CoverageFigures>) {
    if run.dimensions.is_empty() || run.rows.is_empty() {
        return;
    }
    let mut blocks = vec![("this run".to_owned(), run.rows.as_slice(), run.dimensions.as_slice())];
    if let Some(other) = compare {
        let name = other.path.file_name().map_or_else(String::new, |n| n.to_string_lossy().into_owned());
        blocks.push((format!("{name} ({} {})", other.info.task, other.info.variant), &other.rows, &other.dimensions));
    }
    // The figures are computed when a block's rows change (a run's attempt arrives), not every
    // frame: with thousands of attempts the binning costs more than drawing.
    cache.retain(|c| blocks.iter().any(|(title, rows, _)| c.title == *title && c.key == CoverageFigures::key_of(rows)));
    for (title, rows, dimensions) in &blocks {
        if !cache.iter().any(|c| c.title == *title) {
            cache.push(CoverageFigures::compute(title, rows, dimensions));
        }
    }
    egui::CollapsingHeader::new("Coverage of the initial scenes").default_open(true).show(ui, |ui| {
        for (title, rows, _) in &blocks {
            if let Some(figures) = cache.iter().find(|c| c.title == *title) {
                coverage_block(ui, figures, rows);
            }
        }
    });
}

/// A coverage block's numbers and histograms, kept until its rows change.
#[derive(Debug, Clone)]
pub struct CoverageFigures {
    title: String,
    /// What the rows were: how many, how many succeeded, the last attempt's index, the first
    /// scene's first coordinate (another run with as many rows differs there).
    key: (usize, usize, Option<u64>, Option<u64>),
    /// The line of support coverages (`None`: too few scenes to bin).
    summary: Option<String>,
    /// Per-coordinate histograms of the successes and of the failures.
    histograms: Option<(Coverage, Coverage)>,
}

impl CoverageFigures {
    fn key_of(rows: &[AttemptRow]) -> (usize, usize, Option<u64>, Option<u64>) {
        let first = rows.first().and_then(|r| r.objects.first()).map(|o| o.position[0].to_bits());
        (rows.len(), rows.iter().filter(|r| r.success).count(), rows.last().map(|r| r.index), first)
    }

    fn compute(title: &str, rows: &[AttemptRow], dimensions: &[Dimension]) -> Self {
        let all = scenes(rows.iter());
        let good = scenes(rows.iter().filter(|r| r.success));
        let bad = scenes(rows.iter().filter(|r| !r.success));
        let support = |s: &[BTreeMap<String, Pose>]| coverage(s, dimensions, SUPPORT_BINS).ok();
        let summary = match (support(&all), support(&good), support(&bad)) {
            (Some(c_all), Some(c_good), Some(c_bad)) => {
                let uniform = uniform_support_coverage(c_all.joint_bins_total, all.len());
                #[allow(clippy::cast_precision_loss)]
                let rate = 100.0 * good.len() as f64 / all.len().max(1) as f64;
                Some(format!(
                    "{title}: {} scenes, {} successes ({rate:.1} % of the attempts kept); support coverage ({SUPPORT_BINS} bins per coordinate, {} joint bins): all {:.1} % (uniformly spread scenes: {:.1} %), successes {:.1} %, failures {:.1} %",
                    all.len(),
                    good.len(),
                    c_all.joint_bins_total,
                    100.0 * c_all.support_coverage(),
                    100.0 * uniform,
                    100.0 * c_good.support_coverage(),
                    100.0 * c_bad.support_coverage(),
                ))
            }
            _ => None,
        };
        let histograms = coverage(&good, dimensions, HISTOGRAM_BINS).ok().zip(coverage(&bad, dimensions, HISTOGRAM_BINS).ok());
        Self { title: title.to_owned(), key: Self::key_of(rows), summary, histograms }
    }
}

fn coverage_block(ui: &mut egui::Ui, figures: &CoverageFigures, rows: &[AttemptRow]) {
    let (Some(summary), Some((h_good, h_bad))) = (&figures.summary, &figures.histograms) else { return };
    let title = figures.title.as_str();
    ui.label(summary);
    let mut charts = vec![source_demo_chart(title, rows)];
    for (k, dim) in h_good.dimensions.iter().enumerate() {
        #[allow(clippy::cast_precision_loss)]
        let width = (dim.high - dim.low) / HISTOGRAM_BINS as f64;
        #[allow(clippy::cast_precision_loss)]
        let bars = |h: &[usize]| -> Vec<Bar> {
            h.iter().enumerate().map(|(b, &n)| Bar::new(dim.low + (b as f64 + 0.5) * width, n as f64).width(width * 0.9)).collect()
        };
        let succeeded = BarChart::new("successes", bars(&h_good.histograms[k])).color(SUCCESS);
        let failed = BarChart::new("failures", bars(&h_bad.histograms[k])).color(FAILURE).stack_on(&[&succeeded]);
        let coordinate = match dim.coordinate {
            Coordinate::X => "x (m)",
            Coordinate::Y => "y (m)",
            Coordinate::Yaw => "yaw (rad)",
        };
        charts.push(SmallBars {
            id: Plot::new(("coverage", title, k)),
            x_label: format!("{} {coordinate}", dim.object),
            succeeded,
            failed,
        });
    }
    // Rows of as many charts as fit the width (a browser beside the 3D view is narrow): a chart
    // reaching past the edge would widen everything drawn after it.
    let spacing = ui.spacing().item_spacing.x;
    let available = ui.available_width();
    #[allow(clippy::cast_possible_truncation, clippy::cast_sign_loss, clippy::cast_precision_loss)]
    let per_row = (((available + spacing) / (SMALL_BARS_MIN_WIDTH + spacing)).floor().max(1.0) as usize).min(charts.len());
    #[allow(clippy::cast_precision_loss)]
    let width = ((available + spacing) / per_row as f32 - spacing).clamp(SMALL_BARS_MIN_WIDTH.min(available), SMALL_BARS_MAX_WIDTH);
    let mut charts = charts.into_iter().peekable();
    while charts.peek().is_some() {
        ui.horizontal(|ui| {
            for chart in charts.by_ref().take(per_row) {
                chart.show(ui, width);
            }
        });
    }
}

/// The narrowest and widest a coverage chart is drawn.
const SMALL_BARS_MIN_WIDTH: f32 = 110.0;
const SMALL_BARS_MAX_WIDTH: f32 = 240.0;

/// Which source demos the kept attempts used (any subtask), successes and failures stacked: the
/// paper notes successes can come very unevenly from the sources.
fn source_demo_chart(title: &str, rows: &[AttemptRow]) -> SmallBars<'static> {
    let demos = rows.iter().flat_map(|r| r.sources.iter().copied()).max().map_or(0, |d| d + 1);
    let (mut good, mut bad) = (vec![0usize; demos], vec![0usize; demos]);
    for r in rows {
        let mut used = r.sources.clone();
        used.sort_unstable();
        used.dedup();
        for d in used {
            if r.success {
                good[d] += 1;
            } else {
                bad[d] += 1;
            }
        }
    }
    #[allow(clippy::cast_precision_loss)]
    let bars =
        |counts: &[usize]| -> Vec<Bar> { counts.iter().enumerate().map(|(d, &n)| Bar::new(d as f64, n as f64).width(0.7)).collect() };
    let succeeded = BarChart::new("successes", bars(&good)).color(SUCCESS);
    let failed = BarChart::new("failures", bars(&bad)).color(FAILURE).stack_on(&[&succeeded]);
    SmallBars { id: Plot::new(("sources", title)), x_label: "source demo".to_owned(), succeeded, failed }
}

/// One of the coverage row's small charts: successes and failures stacked, fixed in place.
struct SmallBars<'a> {
    id: Plot<'a>,
    x_label: String,
    succeeded: BarChart,
    failed: BarChart,
}

impl SmallBars<'_> {
    fn show(self, ui: &mut egui::Ui, width: f32) {
        let Self { id, x_label, succeeded, failed } = self;
        id.width(width).height(110.0).x_axis_label(x_label).show_axes([true, false]).allow_drag(false).allow_scroll(false).show(
            ui,
            |plot| {
                plot.bar_chart(succeeded);
                plot.bar_chart(failed);
            },
        );
    }
}

fn rate_plot(ui: &mut egui::Ui, run: &RunState, size: egui::Vec2) {
    let mut successes = 0usize;
    #[allow(clippy::cast_precision_loss)]
    let rate: PlotPoints<'static> = run
        .rows
        .iter()
        .enumerate()
        .map(|(i, r)| {
            successes += usize::from(r.success);
            [(i + 1) as f64, 100.0 * successes as f64 / (i + 1) as f64]
        })
        .collect();
    Plot::new("run_rate")
        .width(size.x)
        .height(size.y)
        .include_y(0.0)
        .include_y(100.0)
        .x_axis_label("attempts")
        .y_axis_label("generation rate (%)")
        .legend(Legend::default().position(Corner::LeftBottom))
        .show(ui, |plot| plot.line(Line::new("rate so far", rate).color(SUCCESS)));
}

fn source_plot(ui: &mut egui::Ui, run: &RunState, size: egui::Vec2) {
    let Some(stats) = run.stats() else { return };
    #[allow(clippy::cast_precision_loss)]
    let bars = |f: &dyn Fn(&mimicgen_engine::generate::DemoUse) -> usize| -> Vec<Bar> {
        stats.per_source_demo.iter().enumerate().map(|(d, u)| Bar::new(d as f64, f(u) as f64).width(0.7)).collect()
    };
    let succeeded = BarChart::new("successes", bars(&|u| u.successes)).color(SUCCESS);
    let failed = BarChart::new("failures", bars(&|u| u.attempts - u.successes)).color(FAILURE).stack_on(&[&succeeded]);
    Plot::new("run_sources")
        .width(size.x)
        .height(size.y)
        .x_axis_label("source demo")
        .y_axis_label("segments used (all subtasks)")
        .legend(Legend::default().position(Corner::LeftTop))
        .show(ui, |plot| {
            plot.bar_chart(succeeded);
            plot.bar_chart(failed);
        });
}

fn scene_plot(ui: &mut egui::Ui, run: &RunState, size: egui::Vec2) {
    let shapes = [MarkerShape::Circle, MarkerShape::Square, MarkerShape::Diamond, MarkerShape::Up];
    Plot::new("run_scenes")
        .width(size.x)
        .height(size.y)
        .data_aspect(1.0)
        .x_axis_label("x (m)")
        .y_axis_label("y (m)")
        .legend(Legend::default().position(Corner::LeftTop))
        .show(ui, |plot| {
            let names: Vec<String> = run.rows.first().map(|r| r.objects.iter().map(|o| o.name.clone()).collect()).unwrap_or_default();
            for (k, name) in names.iter().enumerate() {
                for (success, color) in [(true, SUCCESS), (false, FAILURE)] {
                    let points: PlotPoints<'static> = run
                        .rows
                        .iter()
                        .filter(|r| r.success == success)
                        .filter_map(|r| r.objects.iter().find(|o| &o.name == name).map(|o| [o.position[0], o.position[1]]))
                        .collect();
                    let label = format!("{name} ({})", if success { "success" } else { "failure" });
                    plot.points(Points::new(label, points).shape(shapes[k % shapes.len()]).radius(2.5).color(color));
                }
            }
        });
}

fn matches(filter: AttemptFilter, row: &AttemptRow) -> bool {
    match filter {
        AttemptFilter::All => true,
        AttemptFilter::Successes => row.success,
        AttemptFilter::Failures => !row.success,
    }
}

fn attempt_table(ui: &mut egui::Ui, model: &AppModel, run: &RunState, state: &mut UiState, commands: &mut Vec<Command>) {
    ui.horizontal(|ui| {
        ui.strong("Attempts");
        for (filter, name) in [(AttemptFilter::All, "all"), (AttemptFilter::Successes, "successes"), (AttemptFilter::Failures, "failures")]
        {
            ui.radio_value(&mut state.attempt_filter, filter, name);
        }
        ui.checkbox(&mut state.longest_first, "longest first");
        if model.viewer.is_some() {
            ui.separator();
            let mut follow = !model.stay_on_selected;
            if ui
                .add_enabled(model.selected_attempt.is_some(), egui::Checkbox::new(&mut follow, "3D: follow the latest attempt"))
                .on_hover_text("Unchecked, the 3D view stays on the attempt selected in the table")
                .changed()
            {
                commands.push(Command::FollowLatest(follow));
            }
        }
    });
    let mut rows: Vec<&AttemptRow> = run.rows.iter().filter(|r| matches(state.attempt_filter, r)).collect();
    if state.longest_first {
        rows.sort_by(|a, b| b.steps.cmp(&a.steps).then(a.index.cmp(&b.index)));
    }
    if let Some(row) = model.selected_attempt.and_then(|i| run.rows.iter().find(|r| r.index == i)) {
        // Wrapped: in a narrow window (a browser beside the 3D view) the buttons stay in sight.
        ui.horizontal_wrapped(|ui| {
            let what = match (&row.reason, row.failed_subtask) {
                (Some(reason), Some(k)) => format!("attempt {}: failed in subtask {k}: {reason}", row.index),
                _ => format!("attempt {}: success, written as {}", row.index, row.outcome),
            };
            ui.label(RichText::new(what).color(if row.success { SUCCESS } else { FAILURE }));
            if ui.button("Re-run in preview").on_hover_text("Plan and try this attempt again (same seed and index)").clicked() {
                commands.push(Command::ReRun(row.index));
            }
        });
        if !row.success
            && let Some((near, cm)) = crate::model::nearest_success(&run.rows, row)
        {
            ui.horizontal_wrapped(|ui| {
                let same = row
                    .failed_subtask
                    .and_then(|k| row.sources.get(k))
                    .map_or_else(String::new, |d| format!(" from the same source demo_{d}"));
                ui.label(format!("nearest success{same}: attempt {} (objects {cm:.1} cm away on average)", near.index));
                if ui.button("Side by side").on_hover_text("Re-run both and show them next to each other").clicked() {
                    commands.push(Command::SideBySide { failed: row.index, success: Some(near.index) });
                }
                if ui.button("Re-run that one").on_hover_text("Try the nearest success in the preview").clicked() {
                    commands.push(Command::ReRun(near.index));
                }
            });
        }
    }
    egui::ScrollArea::vertical().id_salt("attempts").show_rows(ui, 18.0, rows.len(), |ui, range| {
        for row in &rows[range] {
            let sources: Vec<String> = row.sources.iter().map(|d| format!("demo_{d}")).collect();
            let text = format!(
                "{:>5}  {:<10} {:>4} steps  sources {}  {}",
                row.index,
                if row.success { "success" } else { "failure" },
                row.steps,
                sources.join(","),
                row.reason.as_ref().map_or(String::new(), |r| format!("subtask {}: {r}", row.failed_subtask.unwrap_or_default()))
            );
            let label = RichText::new(text).monospace().color(if row.success { SUCCESS } else { FAILURE });
            if ui.selectable_label(model.selected_attempt == Some(row.index), label).clicked() {
                commands.push(Command::SelectAttempt(row.index));
            }
        }
    });
}
