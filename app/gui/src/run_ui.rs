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
use mimicgen_engine::coverage::{Coordinate, Dimension, coverage, uniform_support_coverage};
use mimicgen_engine::pose::{Rot, Vec3, pose_from_parts};

use crate::model::{AppModel, Command, RunState};
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
            let cores = std::thread::available_parallelism().map_or(1, std::num::NonZero::get);
            ui.add(egui::DragValue::new(&mut f.workers).range(1..=cores.max(1)))
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
        });
    });
    if f != model.run_form {
        commands.push(Command::SetRunForm(f.clone()));
    }
    ui.label(RichText::new(format!("source: {}", file.path.display())).small());
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
    if model.dirty {
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
    if let Some(report) = run.report.as_ref().filter(|r| r.attempts > run.rows.len()) {
        ui.label(RichText::new(format!(
            "{} of {} attempts are in the files: failures not kept (beyond max_num_failures, or without --keep-failed) are only counted",
            run.rows.len(),
            report.attempts
        ))
        .italics());
    }
    coverage_view(ui, run, model.compare.as_ref());
    ui.separator();
    attempt_table(ui, run, state, commands);
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
fn coverage_view(ui: &mut egui::Ui, run: &RunState, compare: Option<&OpenedRun>) {
    if run.dimensions.is_empty() || run.rows.is_empty() {
        return;
    }
    egui::CollapsingHeader::new("Coverage of the initial scenes").default_open(true).show(ui, |ui| {
        coverage_block(ui, "this run", &run.rows, &run.dimensions);
        if let Some(other) = compare {
            let name = other.path.file_name().map_or_else(String::new, |n| n.to_string_lossy().into_owned());
            coverage_block(ui, &format!("{name} ({} {})", other.info.task, other.info.variant), &other.rows, &other.dimensions);
        }
    });
}

fn coverage_block(ui: &mut egui::Ui, title: &str, rows: &[AttemptRow], dimensions: &[Dimension]) {
    let all = scenes(rows.iter());
    let good = scenes(rows.iter().filter(|r| r.success));
    let bad = scenes(rows.iter().filter(|r| !r.success));
    let support = |s: &[BTreeMap<String, Pose>]| coverage(s, dimensions, SUPPORT_BINS).ok();
    let (Some(c_all), Some(c_good), Some(c_bad)) = (support(&all), support(&good), support(&bad)) else { return };
    let uniform = uniform_support_coverage(c_all.joint_bins_total, all.len());
    ui.label(format!(
        "{title}: {} scenes; support coverage ({SUPPORT_BINS} bins per coordinate, {} joint bins): all {:.1} % (uniformly spread scenes: {:.1} %), successes {:.1} %, failures {:.1} %",
        all.len(),
        c_all.joint_bins_total,
        100.0 * c_all.support_coverage(),
        100.0 * uniform,
        100.0 * c_good.support_coverage(),
        100.0 * c_bad.support_coverage()
    ));
    let (Ok(h_good), Ok(h_bad)) = (coverage(&good, dimensions, HISTOGRAM_BINS), coverage(&bad, dimensions, HISTOGRAM_BINS)) else { return };
    ui.horizontal_wrapped(|ui| {
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
            Plot::new(("coverage", title, k))
                .width(200.0)
                .height(110.0)
                .x_axis_label(format!("{} {coordinate}", dim.object))
                .show_axes([true, false])
                .allow_drag(false)
                .allow_scroll(false)
                .show(ui, |plot| {
                    plot.bar_chart(succeeded);
                    plot.bar_chart(failed);
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

/// The successful attempt whose initial objects are nearest `failed`'s (mean distance per object,
/// cm), preferring those that used the same source demo for the subtask that failed.
pub fn nearest_success<'a>(rows: &'a [AttemptRow], failed: &AttemptRow) -> Option<(&'a AttemptRow, f64)> {
    let distance = |r: &AttemptRow| {
        let pairs: Vec<f64> = failed
            .objects
            .iter()
            .filter_map(|o| {
                let p = r.objects.iter().find(|q| q.name == o.name)?;
                Some(((o.position[0] - p.position[0]).powi(2) + (o.position[1] - p.position[1]).powi(2)).sqrt())
            })
            .collect();
        #[allow(clippy::cast_precision_loss)]
        let mean = pairs.iter().sum::<f64>() / pairs.len().max(1) as f64;
        100.0 * mean
    };
    let source = failed.failed_subtask.and_then(|k| failed.sources.get(k).map(|d| (k, *d)));
    let same_source = |r: &&AttemptRow| source.is_none_or(|(k, d)| r.sources.get(k) == Some(&d));
    let candidates = |filter: &dyn Fn(&&AttemptRow) -> bool| {
        rows.iter().filter(|r| r.success).filter(|r| filter(r)).map(|r| (r, distance(r))).min_by(|a, b| a.1.total_cmp(&b.1))
    };
    candidates(&same_source).or_else(|| candidates(&|_| true))
}

fn attempt_table(ui: &mut egui::Ui, run: &RunState, state: &mut UiState, commands: &mut Vec<Command>) {
    ui.horizontal(|ui| {
        ui.strong("Attempts");
        for (filter, name) in [(AttemptFilter::All, "all"), (AttemptFilter::Successes, "successes"), (AttemptFilter::Failures, "failures")]
        {
            ui.radio_value(&mut state.attempt_filter, filter, name);
        }
        ui.checkbox(&mut state.longest_first, "longest first");
    });
    let mut rows: Vec<&AttemptRow> = run.rows.iter().filter(|r| matches(state.attempt_filter, r)).collect();
    if state.longest_first {
        rows.sort_by(|a, b| b.steps.cmp(&a.steps).then(a.index.cmp(&b.index)));
    }
    if let Some(row) = state.selected_attempt.and_then(|i| run.rows.iter().find(|r| r.index == i)) {
        ui.horizontal(|ui| {
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
            && let Some((near, cm)) = nearest_success(&run.rows, row)
        {
            ui.horizontal(|ui| {
                let same = row
                    .failed_subtask
                    .and_then(|k| row.sources.get(k))
                    .map_or_else(String::new, |d| format!(" from the same source demo_{d}"));
                ui.label(format!("nearest success{same}: attempt {} (objects {cm:.1} cm away on average)", near.index));
                if ui.button("Re-run that one").on_hover_text("Try the nearest success in the preview, to compare").clicked() {
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
            if ui.selectable_label(state.selected_attempt == Some(row.index), label).clicked() {
                state.selected_attempt = Some(row.index);
            }
        }
    });
}
