//! The Doctor panel of the generate screen: `mimicgen doctor` on the run shown. Its settings, its
//! progress, the ranked suggestions and the tested ones with their verdicts, the winner's command
//! line, and a button that puts a tested change into the run form.

use egui::{Color32, RichText};
use mimicgen_run::doctor::Verdict;

use crate::model::{AppModel, Command, DoctorState};

/// The panel, under a header folded until asked for (so that the attempt table stays in sight).
pub fn doctor_panel(ui: &mut egui::Ui, model: &AppModel, commands: &mut Vec<Command>) {
    let finished = model.run.as_ref().is_some_and(|r| r.report.is_some());
    if !finished && !model.doctor.running && model.doctor.diagnosis.is_none() {
        return;
    }
    let shown = model.doctor.shown;
    let header = egui::CollapsingHeader::new("Doctor: what to change").id_salt("doctor").open(Some(shown)).show(ui, |ui| {
        let doctor = &model.doctor;
        ui.label(
            RichText::new(
                "Ranks the changes this run's failure causes point at, then tests the best few against the run's own spec on the same \
                 fresh attempts (the same scenes in every arm), each with its 95 % interval (mimicgen doctor).",
            )
            .weak(),
        );
        settings(ui, doctor, commands);
        if doctor.running {
            let (done, total) = doctor.done_of();
            #[allow(clippy::cast_precision_loss)] // attempt counts
            let fraction = if total > 0 { done as f32 / total as f32 } else { 0.0 };
            let text = if total > 0 { format!("{done} of {total} attempts") } else { "reading the run".to_owned() };
            ui.add(egui::ProgressBar::new(fraction).text(text));
        }
        if let Some(error) = &doctor.error {
            ui.colored_label(Color32::LIGHT_RED, error);
        }
        let suggestions = doctor.diagnosis.as_ref().map_or(&doctor.suggestions, |d| &d.suggestions);
        if suggestions.is_empty() {
            if doctor.diagnosis.is_some() {
                ui.label("No failure cause points at a change: nothing to suggest.");
            }
            return;
        }
        ui.strong("Suggestions, most failures addressed first");
        egui::Grid::new("doctor_suggestions").striped(true).num_columns(4).show(ui, |ui| {
            for (i, s) in suggestions.iter().enumerate() {
                ui.label(format!("{}.", i + 1));
                ui.monospace(s.flags());
                ui.label(&s.what);
                ui.label(format!("{} failures", s.addresses)).on_hover_text(&s.why);
                ui.end_row();
            }
        });
        trials(ui, doctor, commands);
    });
    if header.header_response.clicked() {
        commands.push(Command::ShowDoctor(!shown));
    }
}

fn settings(ui: &mut egui::Ui, doctor: &DoctorState, commands: &mut Vec<Command>) {
    ui.horizontal(|ui| {
        let (mut budget, mut top) = (doctor.budget, doctor.top);
        ui.label("attempts in all");
        let b = ui.add_enabled(!doctor.running, egui::DragValue::new(&mut budget).range(2..=100_000)).on_hover_text("--budget");
        ui.label("changes to test");
        let t = ui.add_enabled(!doctor.running, egui::DragValue::new(&mut top).range(1..=10)).on_hover_text("--top");
        if b.changed() || t.changed() {
            commands.push(Command::SetDoctor { budget, top });
        }
        if doctor.running {
            if ui.button("Stop").clicked() {
                commands.push(Command::CancelDoctor);
            }
        } else if ui.button("Diagnose").on_hover_text("mimicgen doctor on this run").clicked() {
            commands.push(Command::Diagnose);
        }
    });
}

#[allow(clippy::cast_precision_loss)] // attempt counts
fn trials(ui: &mut egui::Ui, doctor: &DoctorState, commands: &mut Vec<Command>) {
    let Some(d) = &doctor.diagnosis else { return };
    let rate = |n: usize| 100.0 * n as f64 / d.attempts.max(1) as f64;
    ui.strong(format!(
        "Tested on attempts {}..{} (seed {}): the run's spec {:.1} %",
        d.first_attempt,
        d.first_attempt + d.attempts,
        d.seed,
        rate(d.base_successes)
    ));
    egui::Grid::new("doctor_trials").striped(true).num_columns(6).show(ui, |ui| {
        for (i, t) in d.trials.iter().enumerate() {
            let p = &t.paired;
            ui.monospace(t.suggestion.flags());
            ui.label(format!("{:.1} %", rate(p.changed_successes)));
            ui.label(p.interval());
            ui.label(format!("gained {}, lost {}", p.gained, p.lost));
            let colour = match t.verdict {
                Verdict::Helps => Color32::LIGHT_GREEN,
                Verdict::Hurts => Color32::LIGHT_RED,
                Verdict::Unproven => ui.visuals().weak_text_color(),
            };
            ui.colored_label(colour, t.verdict.words());
            if ui.small_button("use").on_hover_text("put this change into the run form").clicked() {
                commands.push(Command::UseSuggestion(i));
            }
            ui.end_row();
        }
    });
    match d.best() {
        Some(best) => {
            ui.label(format!("Best: {} ({:+.1} points). The run again with it:", best.suggestion.what, 100.0 * best.paired.difference));
            let mut line = best.command.clone();
            ui.add(egui::TextEdit::singleline(&mut line).code_editor().desired_width(f32::INFINITY));
        }
        None => {
            ui.label(format!("No change was shown to help on {} attempts; more attempts narrow the intervals.", d.attempts));
        }
    }
}

/// The run's quality report (folded): stitches per subtask, the pose actions against their
/// limits, coverage, the replay sample.
pub fn quality_panel(ui: &mut egui::Ui, report: &mimicgen_run::Report) {
    let Some(q) = &report.quality else { return };
    egui::CollapsingHeader::new("Quality of the dataset").id_salt("quality").default_open(false).show(ui, |ui| {
        ui.label(RichText::new(format!("also in {}", mimicgen_run::quality_path(std::path::Path::new(&report.output)).display())).weak());
        egui::Grid::new("quality_stitches").striped(true).num_columns(6).show(ui, |ui| {
            for h in ["stitch", "count", "jump max / p95 (cm)", "turn max / p95 (deg)", "jerk max / p95 (m/s³)", "steps p95 (cm)"] {
                ui.strong(h);
            }
            ui.end_row();
            for s in &q.quality.stitches {
                let at = match s.at {
                    mimicgen_engine::quality::StitchAt::InterpolationStart => "interpolation start",
                    mimicgen_engine::quality::StitchAt::InterpolationEnd => "interpolation end",
                };
                ui.label(format!("subtask {} {at}", s.subtask));
                ui.label(format!("{}", s.count));
                ui.label(format!("{:.1} / {:.1}", 100.0 * s.jump_m_max, 100.0 * s.jump_m_p95));
                ui.label(format!("{:.1} / {:.1}", s.jump_deg_max, s.jump_deg_p95));
                ui.label(format!("{:.0} / {:.0}", s.jerk_max, s.jerk_p95));
                ui.label(format!("{:.1}", 100.0 * s.step_m_p95));
                ui.end_row();
            }
        });
        let a = &q.quality.actions;
        #[allow(clippy::cast_precision_loss)] // step counts
        let share = 100.0 * a.saturated_steps as f64 / a.steps.max(1) as f64;
        let dims: Vec<String> = a.max_abs.iter().zip(&a.p95_abs).map(|(m, p)| format!("{m:.2}/{p:.2}")).collect();
        ui.label(format!(
            "pose actions at their limit (|a| = 1) in {share:.1} % of {} steps; |a| max/p95 per dimension: {}",
            a.steps,
            dims.join(", ")
        ));
        if let Some(c) = &q.coverage {
            ui.label(format!(
                "support coverage of the successes: {:.1} % ({} scenes, {} bins per coordinate; as many uniform scenes: {:.1} %)",
                100.0 * c.support_coverage,
                c.scenes,
                c.bins,
                100.0 * c.uniform_support_coverage
            ));
        }
        if let Some(error) = q.replay.as_ref().and_then(|r| r.error.as_ref()) {
            ui.colored_label(Color32::LIGHT_RED, format!("the written demos could not be replayed: {error}"));
        } else if let Some(r) = &q.replay {
            ui.label(format!(
                "{} of {} written demos replay to success from their first state ({})",
                r.succeeded,
                r.demos.len(),
                r.demos.join(", ")
            ));
        }
    });
}
