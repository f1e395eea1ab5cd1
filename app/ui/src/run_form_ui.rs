//! The generate screen's run form: what `mimicgen generate` takes (spec fields included), the
//! command line that makes the same run, and opening a finished run. Reads the model, returns
//! commands.

use egui::RichText;
use mimicgen_engine::spec::Transit;

use mimicgen_run::{CameraConfig, OffsetRange, Scoped, SpecOverrides};

use crate::model::{AppModel, Command, RunState};

use crate::run_ui::RunUiState;

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
pub fn form(ui: &mut egui::Ui, model: &AppModel, state: &mut RunUiState, commands: &mut Vec<Command>) {
    let Some(file) = &model.file else {
        ui.label("Open a source file first.");
        return;
    };
    let running = model.run.as_ref().is_some_and(RunState::running);
    let two_arm = file.two_arm_task().is_some();
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
            if !two_arm {
                ui.label("");
                ui.checkbox(&mut f.keep_failed, "keep failed attempts")
                    .on_hover_text("--keep-failed: OUT_failed.hdf5, for the failure views");
                ui.end_row();
                ui.label("");
                ui.checkbox(&mut f.early_abort, "end attempts at a missed subtask").on_hover_text("--early-abort");
                ui.end_row();
            }
            ui.label("");
            if ui.checkbox(&mut f.overwrite, "replace existing outputs").on_hover_text("--overwrite").changed() && f.overwrite {
                f.resume = false;
            }
            ui.end_row();
            if !two_arm {
                ui.label("");
                let resume = ui.checkbox(&mut f.resume, "continue an interrupted run").on_hover_text(
                    "--resume: a run killed before its end left OUT.partial; this continues it, with the arguments it was started with",
                );
                if resume.changed() && f.resume {
                    f.overwrite = false;
                }
                ui.end_row();
            }
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
            if two_arm {
                return;
            }
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
        if two_arm {
            ui.label(RichText::new("Two arms: no failed-attempt file, resume, robot transfer, cameras or spec fields yet.").small());
        } else {
            egui::CollapsingHeader::new("Spec fields")
                .default_open(!f.spec.is_empty())
                .show(ui, |ui| spec_fields(ui, &mut f.spec, file.subtask_objects.len()));
        }
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
            ui.ctx().copy_text(f.command_line(&file.path, file.two_arm_task()));
        }
    });
    ui.label(RichText::new(f.command_line(&file.path, file.two_arm_task())).monospace().small());
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

/// Sets (or with `None`, clears) the value of `values` for exactly `subtask`. A value for every
/// subtask goes first, so that values for one subtask (a doctor's change) still win over it.
fn set_scoped<T>(values: &mut Vec<Scoped<T>>, subtask: Option<usize>, value: Option<T>) {
    values.retain(|s| s.subtask != subtask);
    if let Some(value) = value {
        let at = if subtask.is_none() { 0 } else { values.len() };
        values.insert(at, Scoped { subtask, value });
    }
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_value_for_every_subtask_stays_before_the_values_for_one() {
        // A doctor's change for subtask 1 over the run's noise for all: the form re-sets the value
        // for all every frame, and subtask 1's must still win.
        let mut noise = vec![Scoped::all(0.3), Scoped { subtask: Some(1), value: 0.15 }];
        set_scoped(&mut noise, None, Some(0.3));
        assert_eq!(noise, [Scoped::all(0.3), Scoped { subtask: Some(1), value: 0.15 }]);
        let mut spec = mimicgen_engine::kinematic::pick_place_spec(1, 1);
        SpecOverrides { action_noise: noise.clone(), ..SpecOverrides::default() }.apply(&mut spec).unwrap();
        assert_eq!((spec.subtasks[0].action_noise, spec.subtasks[1].action_noise), (0.3, 0.15));
        set_scoped(&mut noise, Some(1), None);
        assert_eq!(noise, [Scoped::all(0.3)]);
        set_scoped(&mut noise, None, None);
        assert!(noise.is_empty());
    }
}
