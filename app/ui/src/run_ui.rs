//! The generate screen's run, live (its form is [`crate::run_form_ui`], its coverage figures
//! [`crate::coverage_ui`]): progress with ETA, the generation rate over attempts,
//! attempts and successes per source demo, failures by subtask and reason and by subtask and
//! cause, the success matrix (subtask by source demo), the initial scenes from
//! above coloured by outcome, support coverage against uniformly spread scenes with histograms per
//! object coordinate, and the attempt table (filter, sort, re-run one in the preview).
//! Reads the model, returns commands.

use std::collections::BTreeMap;

use egui::RichText;
use egui_plot::{Bar, BarChart, Corner, Legend, Line, MarkerShape, Plot, PlotPoints, Points};

use crate::coverage_ui::{CoverageFigures, coverage_view};
use crate::model::{AppModel, Command, RunState, SideBySide};
use crate::protocol::AttemptRow;
use crate::style::{FAILURE, SUCCESS};

/// The success matrix as a heat map: a row per subtask, a column per source demo, each cell its
/// successes of the attempts whose segment came from there, green to red by rate (grey unused);
/// a source demo used often and never in a success is flagged.
fn success_matrix(ui: &mut egui::Ui, model: &AppModel, run: &RunState) {
    // Live runs count as they go; an opened run has the matrix from its report.
    let matrix: Vec<Vec<(usize, usize)>> = match run.stats().filter(|s| !s.per_subtask_source.is_empty()) {
        Some(stats) => stats.per_subtask_source.iter().map(|row| row.iter().map(|d| (d.successes, d.attempts)).collect()).collect(),
        None => run
            .report
            .iter()
            .flat_map(|r| &r.per_subtask_source)
            .map(|row| row.iter().map(|d| (d.successes, d.attempts)).collect())
            .collect(),
    };
    let columns = matrix.iter().map(Vec::len).max().unwrap_or(0);
    if columns == 0 {
        return;
    }
    ui.strong("Successes by subtask and source demo");
    egui::Grid::new("success_matrix").striped(false).num_columns(columns + 1).show(ui, |ui| {
        ui.label("");
        for d in 0..columns {
            ui.label(RichText::new(format!("demo_{d}")).monospace());
        }
        ui.end_row();
        for (subtask, row) in matrix.iter().enumerate() {
            ui.label(model.subtask_name(subtask));
            for d in 0..columns {
                let (successes, attempts) = row.get(d).copied().unwrap_or_default();
                #[allow(clippy::cast_precision_loss)] // counts of attempts
                let rate = if attempts == 0 { None } else { Some(successes as f32 / attempts as f32) };
                let colour = rate.map_or(egui::Color32::GRAY, |r| FAILURE.lerp_to_gamma(SUCCESS, r));
                ui.label(RichText::new(format!("{successes}/{attempts}")).monospace().background_color(colour.gamma_multiply(0.6)));
            }
            ui.end_row();
        }
    });
    // The run's own rule: the live statistics', or the report's list.
    let never: Vec<String> = match run.stats().filter(|s| s.attempts > 0) {
        Some(stats) => stats.never_succeeded(mimicgen_run::NEVER_SUCCEEDS_MIN_USES),
        None => run.report.iter().flat_map(|r| r.never_succeeded.iter().copied()).collect(),
    }
    .into_iter()
    .map(|d| format!("demo_{d}"))
    .collect();
    if !never.is_empty() {
        ui.label(RichText::new(format!("never in a success: {}", never.join(", "))).color(FAILURE));
    }
}

/// The generate screen's own state (text fields, table options, figures drawn).
#[derive(Debug, Default)]
pub struct RunUiState {
    /// Which attempts the run's table lists.
    pub attempt_filter: AttemptFilter,
    /// Sort the attempt table by length, longest first (else by index).
    pub longest_first: bool,
    /// The "open a run" path field.
    pub run_path: String,
    /// The coverage figures drawn, until their attempts change.
    pub coverage: Vec<CoverageFigures>,
}

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
pub fn progress(ui: &mut egui::Ui, model: &AppModel, state: &mut RunUiState, commands: &mut Vec<Command>) {
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
    let causes: Vec<(usize, String, usize)> = match run.stats().filter(|s| !s.causes.is_empty()) {
        Some(stats) => stats.causes.iter().map(|c| (c.subtask, c.class.replace('_', " "), c.count)).collect(),
        None => run.report.iter().flat_map(|r| &r.causes).map(|c| (c.subtask, c.cause.replace('_', " "), c.count)).collect(),
    };
    let table = |ui: &mut egui::Ui, title: &str, id: &str, rows: &[(usize, String, usize)]| {
        ui.vertical(|ui| {
            ui.strong(title);
            egui::Grid::new(id).striped(true).num_columns(3).show(ui, |ui| {
                for (subtask, what, count) in rows {
                    ui.label(model.subtask_name(*subtask));
                    ui.label(what);
                    ui.label(format!("{count}"));
                    ui.end_row();
                }
            });
        });
    };
    if !failures.is_empty() {
        table(ui, "Failures by subtask and reason", "failures", &failures);
    }
    // Folded by default, so that the attempt table below stays in sight.
    if !causes.is_empty() || run.stats().is_some_and(|s| !s.per_subtask_source.is_empty()) || run.report.is_some() {
        egui::CollapsingHeader::new("Causes and the success matrix").id_salt("causes_and_matrix").default_open(false).show(ui, |ui| {
            ui.horizontal_top(|ui| {
                if !causes.is_empty() {
                    table(ui, "Failures by subtask and cause", "causes", &causes);
                }
                ui.vertical(|ui| success_matrix(ui, model, run));
            });
        });
    }
    if let Some(report) = &run.report {
        crate::doctor_ui::quality_panel(ui, report);
    }
    crate::doctor_ui::doctor_panel(ui, model, commands);
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
                    plot.points(
                        Points::new(label, points)
                            .shape(shapes.get(k % shapes.len()).copied().unwrap_or(MarkerShape::Circle))
                            .radius(2.5)
                            .color(color),
                    );
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

fn attempt_table(ui: &mut egui::Ui, model: &AppModel, run: &RunState, state: &mut RunUiState, commands: &mut Vec<Command>) {
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
                (Some(reason), Some(k)) => {
                    let cause = row.cause.as_ref().map_or(String::new(), |c| format!(" ({c})"));
                    format!("attempt {}: failed in {}: {reason}{cause}", row.index, model.subtask_name(k))
                }
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
                let one_arm = model.file.as_ref().is_none_or(|f| f.arms.is_empty());
                if one_arm && ui.button("Side by side").on_hover_text("Re-run both and show them next to each other").clicked() {
                    commands.push(Command::SideBySide { failed: row.index, success: Some(near.index) });
                }
                if ui.button("Re-run that one").on_hover_text("Try the nearest success in the preview").clicked() {
                    commands.push(Command::ReRun(near.index));
                }
            });
        }
    }
    egui::ScrollArea::vertical().id_salt("attempts").show_rows(ui, 18.0, rows.len(), |ui, range| {
        for row in rows.get(range).unwrap_or_default() {
            let sources: Vec<String> = row.sources.iter().map(|d| format!("demo_{d}")).collect();
            let text = format!(
                "{:>5}  {:<10} {:>4} steps  sources {}  {}",
                row.index,
                if row.success { "success" } else { "failure" },
                row.steps,
                sources.join(","),
                row.reason
                    .as_ref()
                    .map_or(String::new(), |r| format!("{}: {r}", model.subtask_name(row.failed_subtask.unwrap_or_default())))
            );
            let label = RichText::new(text).monospace().color(if row.success { SUCCESS } else { FAILURE });
            if ui.selectable_label(model.selected_attempt == Some(row.index), label).clicked() {
                commands.push(Command::SelectAttempt(row.index));
            }
        }
    });
}
