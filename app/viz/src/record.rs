//! Source demos, attempts and run statistics as Rerun entities. Labels are kept on every entity
//! (hover or select it to read them) but not drawn in the view, where they piled up.

use std::collections::BTreeMap;

use mimicgen_engine::pose::Pose;
use mimicgen_engine::transform::WaypointKind;
use mimicgen_engine::two_arm::{ArmSubtask, Constraint, TwoArmAttempt, TwoArmSpec};
use mimicgen_engine::{Attempt, RunStats, SourceDemo};
use rerun::{RecordingStream, TimeColumn};

use crate::VizError;

/// Colours of subtask 0, 1, 2, ... (cycled).
const SUBTASK_COLORS: [[u8; 3]; 6] = [[255, 140, 0], [30, 144, 255], [186, 85, 211], [0, 206, 209], [255, 105, 180], [154, 205, 50]];
/// The chosen source segment, as recorded in the source demo.
const SOURCE_COLOR: [u8; 3] = [170, 170, 170];
/// The source segment re-expressed in the new scene.
const TRANSFORMED_COLOR: [u8; 3] = [30, 144, 255];
/// The interpolation segment bridging to it.
const INTERPOLATION_COLOR: [u8; 3] = [255, 215, 0];
/// Planned collision-free transit (`--transit plan`).
const TRANSIT_COLOR: [u8; 3] = [0, 206, 180];
/// The hand riding a mobile base's drive, copied from the source.
const BASE_DRIVE_COLOR: [u8; 3] = [150, 110, 60];
/// Executed path of a successful attempt.
const SUCCESS_COLOR: [u8; 3] = [50, 205, 50];
/// Executed path of a failed attempt.
const FAILURE_COLOR: [u8; 3] = [220, 20, 60];
/// Length of drawn frame axes.
const AXIS_LENGTH_M: f32 = 0.06;

/// Timeline names.
pub mod timelines {
    /// Attempt index in a generation run.
    pub const ATTEMPT: &str = "attempt";
    /// Step within an attempt or demo.
    pub const STEP: &str = "step";
    /// Steps of every attempt (or demo) one after the other, to play a whole run.
    pub const FRAME: &str = "frame";
    /// Demo index in a dataset (`mimicgen view`, and the source demos of a run).
    pub const DEMO: &str = "demo";
}

fn rgb(c: [u8; 3]) -> rerun::Color {
    rerun::Color::from_rgb(c[0], c[1], c[2])
}

/// The colour of subtask `k`.
#[must_use]
pub fn subtask_color(k: usize) -> rerun::Color {
    #[allow(clippy::indexing_slicing, reason = "k % len is below len")]
    rgb(SUBTASK_COLORS[k % SUBTASK_COLORS.len()])
}

#[allow(clippy::cast_possible_truncation)] // Rerun draws in f32
fn point(pose: &Pose) -> [f32; 3] {
    let t = pose.translation.vector;
    [t.x as f32, t.y as f32, t.z as f32]
}

/// Arrows for the x (red), y (green), z (blue) axes of every pose.
#[allow(clippy::cast_possible_truncation)]
fn frame_arrows<'a>(poses: impl IntoIterator<Item = (String, &'a Pose)>) -> rerun::Arrows3D {
    let (mut origins, mut vectors, mut colors, mut labels) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
    for (label, pose) in poses {
        let r = pose.rotation.to_rotation_matrix();
        for (axis, c) in [[255, 0, 0], [0, 200, 0], [0, 100, 255]].into_iter().enumerate() {
            let v = r.matrix().column(axis) * f64::from(AXIS_LENGTH_M);
            origins.push(point(pose));
            vectors.push([v.x as f32, v.y as f32, v.z as f32]);
            colors.push(rgb(c));
            labels.push(if axis == 0 { label.clone() } else { String::new() });
        }
    }
    rerun::Arrows3D::from_vectors(vectors).with_origins(origins).with_colors(colors).with_labels(labels).with_show_labels(false)
}

/// Subtask ends read from the signals, spec-free, as the engine's segmentation reads them
/// ([`mimicgen_engine::segment::subtask_end_from_signal`] from step 0), sorted. The last subtask
/// runs to the end of the demo.
#[must_use]
pub fn signal_boundaries(signals: &BTreeMap<String, Vec<i64>>) -> Vec<(usize, String)> {
    let mut ends: Vec<(usize, String)> = signals
        .iter()
        .filter_map(|(name, values)| Some((mimicgen_engine::segment::subtask_end_from_signal(values, 0)?, name.clone())))
        .collect();
    ends.sort();
    ends
}

fn step_column(name: &'static str, n: usize, f: impl Fn(usize) -> i64) -> TimeColumn {
    TimeColumn::new_sequence(name, (0..n).map(f))
}

#[allow(clippy::cast_possible_wrap)] // step counts are far below i64::MAX
fn as_i64(v: usize) -> i64 {
    v as i64
}

/// Where camera images go: `cameras/<camera>` (`agentview_image` is logged as `cameras/agentview`).
pub const CAMERAS: &str = "cameras";

/// Logs a demo's RGB camera streams (`<camera>_image`) as images under `cameras/<camera>`, one per
/// step on the `demo`, `step` and `frame` timelines (`frame_offset`: the demo's first frame).
/// Returns the cameras logged.
///
/// # Errors
/// [`VizError::Rerun`] from the stream.
pub fn log_images(
    rec: &RecordingStream,
    images: &BTreeMap<String, mimicgen_engine::image::ImageStream>,
    demo_index: usize,
    frame_offset: usize,
) -> Result<Vec<String>, VizError> {
    let mut cameras = Vec::new();
    for (key, stream) in images {
        let Some(camera) = key.strip_suffix("_image") else { continue };
        let [h, w, 3] = stream.shape else { continue };
        let path = format!("{CAMERAS}/{camera}");
        let resolution = [u32::try_from(w).unwrap_or(u32::MAX), u32::try_from(h).unwrap_or(u32::MAX)];
        rec.set_time_sequence(timelines::DEMO, as_i64(demo_index));
        for t in 0..stream.steps() {
            let Some(frame) = stream.rgb_frame(t) else { break };
            rec.set_time_sequence(timelines::STEP, as_i64(t));
            rec.set_time_sequence(timelines::FRAME, as_i64(frame_offset + t));
            rec.log(path.as_str(), &rerun::Image::from_rgb24(frame.to_vec(), resolution)).map_err(|e| VizError::rerun(&path, &e))?;
        }
        cameras.push(camera.to_owned());
    }
    Ok(cameras)
}

/// Logs one demo (a source demo, or a demo of any dataset) under `root`: the end-effector path
/// coloured by subtask, the subtask ends with the objects' frames there, and each subtask-end
/// signal as a plot under `plots/signals`. `demo_index` is the `demo` timeline value;
/// `frame_offset` the `frame` value of its first step.
///
/// # Errors
/// [`VizError::Rerun`] from the stream.
pub fn log_demo(rec: &RecordingStream, root: &str, demo: &SourceDemo, demo_index: usize, frame_offset: usize) -> Result<(), VizError> {
    let err = |what: &str, e: &dyn std::fmt::Display| VizError::rerun(&format!("{root}/{what}"), e);
    rec.set_time_sequence(timelines::DEMO, as_i64(demo_index));
    rec.set_time_sequence(timelines::STEP, 0);
    rec.set_time_sequence(timelines::FRAME, as_i64(frame_offset));
    rec.log(root, &rerun::Clear::recursive()).map_err(|e| err("clear", &e))?;
    let ends = signal_boundaries(&demo.subtask_term_signals);
    let n = demo.eef_poses.len();
    let mut start = 0;
    let mut cuts: Vec<usize> = ends.iter().map(|(t, _)| *t).filter(|&t| t > 0 && t < n).collect();
    cuts.push(n);
    for (k, &end) in cuts.iter().enumerate() {
        let strip: Vec<[f32; 3]> = demo.eef_poses.get(start.min(n)..(end + 1).min(n)).unwrap_or_default().iter().map(point).collect();
        rec.log(
            format!("{root}/eef_path/subtask_{k}"),
            &rerun::LineStrips3D::new([strip])
                .with_colors([subtask_color(k)])
                .with_labels([format!("{} subtask {k}", demo.name)])
                .with_show_labels(false),
        )
        .map_err(|e| err("eef_path", &e))?;
        start = end;
    }
    let marks: Vec<(usize, String)> = ends.iter().filter(|(t, _)| *t < n).cloned().collect();
    rec.log(
        format!("{root}/subtask_ends"),
        &rerun::Points3D::new(marks.iter().filter_map(|(t, _)| demo.eef_poses.get(*t)).map(point))
            .with_radii([0.008])
            .with_colors(marks.iter().enumerate().map(|(k, _)| subtask_color(k)))
            .with_labels(marks.iter().map(|(t, s)| format!("{s} ends subtask at step {t}")))
            .with_show_labels(false),
    )
    .map_err(|e| err("subtask_ends", &e))?;
    let frames: Vec<(String, &Pose)> = marks
        .iter()
        .flat_map(|(t, s)| demo.object_poses.iter().filter_map(move |(obj, poses)| poses.get(*t).map(|p| (format!("{obj} @ {s}"), p))))
        .collect();
    rec.log(format!("{root}/object_frames_at_ends"), &frame_arrows(frames)).map_err(|e| err("object_frames_at_ends", &e))?;
    let index = || {
        [
            step_column(timelines::STEP, n, as_i64),
            step_column(timelines::DEMO, n, |_| as_i64(demo_index)),
            step_column(timelines::FRAME, n, |t| as_i64(frame_offset + t)),
        ]
    };
    for (name, values) in &demo.subtask_term_signals {
        #[allow(clippy::cast_precision_loss)]
        let scalars = rerun::Scalars::update_fields().with_scalars(values.iter().map(|&v| v as f64)).columns_of_unit_batches();
        let path = format!("plots/signals/{name}");
        rec.send_columns(path.as_str(), index(), scalars.map_err(|e| err(&path, &e))?).map_err(|e| err(&path, &e))?;
    }
    let gripper: Vec<f64> = demo.gripper_actions.iter().map(|row| row.first().copied().unwrap_or_default()).collect();
    let cols = rerun::Scalars::update_fields().with_scalars(gripper).columns_of_unit_batches().map_err(|e| err("gripper", &e))?;
    rec.send_columns("plots/gripper", index(), cols).map_err(|e| err("plots/gripper", &e))?;
    Ok(())
}

/// Logs an attempt's plan under `world/attempt` (replacing what was there): the new scene's object
/// frames and, per subtask, the source, transformed and interpolation segments and the reference
/// object's frames. Sets the `attempt`, `step` (0) and `frame` times.
fn log_plans(
    rec: &RecordingStream,
    index: u64,
    objects: &BTreeMap<String, Pose>,
    plans: &[mimicgen_engine::SubtaskPlan],
    source_names: &[String],
    frame_offset: usize,
) -> Result<(), VizError> {
    begin_attempt(rec, index, objects, frame_offset)?;
    log_subtask_plans(rec, "world/attempt", plans, source_names)
}

/// Starts attempt `index` on the timelines: clears the last attempt's entities and logs the
/// scene's object frames.
fn begin_attempt(rec: &RecordingStream, index: u64, objects: &BTreeMap<String, Pose>, frame_offset: usize) -> Result<(), VizError> {
    let root = "world/attempt";
    let err = |what: &str, e: &dyn std::fmt::Display| VizError::rerun(&format!("{root}/{what}"), e);
    rec.set_time_sequence(timelines::ATTEMPT, i64::try_from(index).unwrap_or(i64::MAX));
    rec.set_time_sequence(timelines::STEP, 0);
    rec.set_time_sequence(timelines::FRAME, as_i64(frame_offset));
    rec.log(root, &rerun::Clear::recursive()).map_err(|e| err("clear", &e))?;
    rec.log(format!("{root}/objects"), &frame_arrows(objects.iter().map(|(name, pose)| (name.clone(), pose))))
        .map_err(|e| err("objects", &e))
}

/// Each subtask's source, transformed, interpolation and transit segments and object frames under
/// `root/subtask_<k>`.
fn log_subtask_plans(
    rec: &RecordingStream,
    root: &str,
    plans: &[mimicgen_engine::SubtaskPlan],
    source_names: &[String],
) -> Result<(), VizError> {
    let err = |what: &str, e: &dyn std::fmt::Display| VizError::rerun(&format!("{root}/{what}"), e);
    let name_of = |d: usize| source_names.get(d).cloned().unwrap_or_else(|| format!("demo {d}"));
    for (s, plan) in plans.iter().enumerate() {
        let sub = format!("{root}/subtask_{s}");
        let strip = |poses: &mut dyn Iterator<Item = &Pose>| -> Vec<[f32; 3]> { poses.map(point).collect() };
        rec.log(
            format!("{sub}/source_segment"),
            &rerun::LineStrips3D::new([strip(&mut plan.source_poses.iter())])
                .with_colors([rgb(SOURCE_COLOR)])
                .with_labels([format!("source {} steps {}..{}", name_of(plan.src_demo), plan.src_span.0, plan.src_span.1)])
                .with_show_labels(false),
        )
        .map_err(|e| err("source_segment", &e))?;
        rec.log(
            format!("{sub}/transformed_segment"),
            &rerun::LineStrips3D::new([strip(&mut plan.transformed_poses.iter())])
                .with_colors([rgb(TRANSFORMED_COLOR)])
                .with_labels([format!("subtask {s} transformed")])
                .with_show_labels(false),
        )
        .map_err(|e| err("transformed_segment", &e))?;
        let first_transformed = plan.waypoints.iter().find(|(_, kind)| *kind == WaypointKind::Transformed).map(|(p, _)| point(p));
        for (kind, name, color, label) in [
            (WaypointKind::Interpolation, "interpolation_segment", INTERPOLATION_COLOR, "interpolation"),
            (WaypointKind::Transit, "transit_segment", TRANSIT_COLOR, "planned transit"),
            (WaypointKind::Base, "base_drive_segment", BASE_DRIVE_COLOR, "base drive (the hand on the base)"),
        ] {
            let mut path: Vec<[f32; 3]> = plan.waypoints.iter().filter(|(_, k)| *k == kind).map(|(p, _)| point(p)).collect();
            if path.is_empty() {
                continue;
            }
            // A bridge ends where the transformed segment begins; a drive ends where it ends.
            if kind != WaypointKind::Base {
                path.extend(first_transformed);
            }
            rec.log(
                format!("{sub}/{name}"),
                &rerun::LineStrips3D::new([path])
                    .with_colors([rgb(color)])
                    .with_labels([format!("subtask {s} {label}")])
                    .with_show_labels(false),
            )
            .map_err(|e| err(name, &e))?;
        }
        let mut frames = Vec::new();
        if let Some(p) = &plan.world_from_obj_new {
            frames.push((format!("subtask {s} object (new scene)"), p));
        }
        if let Some(p) = &plan.world_from_obj_src {
            frames.push((format!("subtask {s} object (in {})", name_of(plan.src_demo)), p));
        }
        rec.log(format!("{sub}/object_frames"), &frame_arrows(frames)).map_err(|e| err("object_frames", &e))?;
    }
    Ok(())
}

/// Logs a planned, not executed, attempt ([`mimicgen_engine::Plan`]) as [`log_attempt`] logs the
/// plan part of an executed one, with an outcome line saying it is a plan.
///
/// # Errors
/// [`VizError::Rerun`] from the stream.
pub fn log_plan(rec: &RecordingStream, plan: &mimicgen_engine::Plan, source_names: &[String], frame_offset: usize) -> Result<(), VizError> {
    log_plans(rec, plan.index, &plan.initial_object_poses, &plan.subtasks, source_names, frame_offset)?;
    let name_of = |d: usize| source_names.get(d).cloned().unwrap_or_else(|| format!("demo {d}"));
    let sources = plan.subtasks.iter().map(|s| name_of(s.src_demo)).collect::<Vec<_>>().join(", ");
    let text = format!("attempt {}: planned, not executed (sources {sources})", plan.index);
    rec.log("outcome", &rerun::TextLog::new(text).with_level(rerun::TextLogLevel::INFO)).map_err(|e| VizError::rerun("outcome", &e))
}

/// Logs one attempt under `world/attempt` (replaced by the next) and its executed path under
/// `world/history/attempt_<k>` (kept, to compare many): the new scene's object frames, per
/// subtask the chosen source segment, the transformed segment, the interpolation segment and the
/// reference object's frames, the executed path, the gripper command and the outcome.
/// `frame_offset` is the `frame` value of its first step.
///
/// # Errors
/// [`VizError::Rerun`] from the stream.
pub fn log_attempt(rec: &RecordingStream, attempt: &Attempt, source_names: &[String], frame_offset: usize) -> Result<(), VizError> {
    let root = "world/attempt";
    let err = |what: &str, e: &dyn std::fmt::Display| VizError::rerun(&format!("{root}/{what}"), e);
    log_plans(rec, attempt.index, &attempt.initial_object_poses, &attempt.plans, source_names, frame_offset)?;
    let k = i64::try_from(attempt.index).unwrap_or(i64::MAX);
    let name_of = |d: usize| source_names.get(d).cloned().unwrap_or_else(|| format!("demo {d}"));
    let traj = &attempt.trajectory;
    let executed: Vec<[f32; 3]> = traj.eef_poses.iter().map(point).collect();
    let outcome_color = rgb(if attempt.success { SUCCESS_COLOR } else { FAILURE_COLOR });
    let sources = attempt.src_demo_per_subtask.iter().map(|&d| name_of(d)).collect::<Vec<_>>().join(", ");
    let outcome = match &attempt.failure {
        None if attempt.success => format!("attempt {}: success (sources {sources})", attempt.index),
        None => format!("attempt {}: failed (sources {sources})", attempt.index),
        Some(f) => {
            let cause = attempt.cause.as_ref().map_or(String::new(), |c| format!("; {c}"));
            format!("attempt {}: FAILED in subtask {}: {}{cause} (sources {sources})", attempt.index, f.subtask, f.reason)
        }
    };
    rec.log(
        format!("{root}/executed_path"),
        &rerun::LineStrips3D::new([executed.clone()]).with_colors([outcome_color]).with_labels([outcome.clone()]).with_show_labels(false),
    )
    .map_err(|e| err("executed_path", &e))?;
    rec.log(
        format!("world/history/attempt_{:05}", attempt.index),
        &rerun::LineStrips3D::new([executed.clone()]).with_colors([outcome_color]).with_radii([rerun::Radius::new_ui_points(0.5)]),
    )
    .map_err(|e| err("history", &e))?;
    let level = if attempt.success { rerun::TextLogLevel::INFO } else { rerun::TextLogLevel::WARN };
    rec.log("outcome", &rerun::TextLog::new(outcome).with_level(level)).map_err(|e| err("outcome", &e))?;
    rec.log("plots/attempt/success", &rerun::Scalars::single(f64::from(u8::from(attempt.success)))).map_err(|e| err("success", &e))?;
    let n = traj.len();
    if n > 0 {
        let index = || {
            [
                step_column(timelines::STEP, n, as_i64),
                step_column(timelines::ATTEMPT, n, |_| k),
                step_column(timelines::FRAME, n, |t| as_i64(frame_offset + t)),
            ]
        };
        let cols = rerun::Points3D::update_fields()
            .with_positions(executed)
            .with_colors(std::iter::repeat_n(outcome_color, n))
            .with_radii(std::iter::repeat_n(0.012_f32, n))
            .columns_of_unit_batches()
            .map_err(|e| err("eef", &e))?;
        rec.send_columns(format!("{root}/eef"), index(), cols).map_err(|e| err("eef", &e))?;
        let gripper: Vec<f64> = traj.gripper_actions.iter().map(|row| row.first().copied().unwrap_or_default()).collect();
        let cols = rerun::Scalars::update_fields().with_scalars(gripper).columns_of_unit_batches().map_err(|e| err("gripper", &e))?;
        rec.send_columns("plots/gripper", index(), cols).map_err(|e| err("plots/gripper", &e))?;
        #[allow(clippy::cast_precision_loss)]
        let subtasks = traj.subtask_labels.iter().map(|&s| s as f64);
        let cols = rerun::Scalars::update_fields().with_scalars(subtasks).columns_of_unit_batches().map_err(|e| err("subtask", &e))?;
        rec.send_columns("plots/subtask", index(), cols).map_err(|e| err("plots/subtask", &e))?;
        for (name, values) in &traj.subtask_term_signals {
            #[allow(clippy::cast_precision_loss)]
            let cols = rerun::Scalars::update_fields()
                .with_scalars(values.iter().map(|&v| v as f64))
                .columns_of_unit_batches()
                .map_err(|e| err(name, &e))?;
            rec.send_columns(format!("plots/signals/{name}"), index(), cols).map_err(|e| err(name, &e))?;
        }
    }
    Ok(())
}

/// Logs the run statistics after an attempt (on the `attempt` timeline): attempts, successes,
/// generation rate, and per source demo the attempts and successes that used it.
///
/// # Errors
/// [`VizError::Rerun`] from the stream.
#[allow(clippy::cast_precision_loss)] // counts are far below 2^52
pub fn log_stats(rec: &RecordingStream, stats: &RunStats, source_names: &[String]) -> Result<(), VizError> {
    let err = |what: &str, e: &dyn std::fmt::Display| VizError::rerun(what, e);
    rec.log("stats/attempts", &rerun::Scalars::single(stats.attempts as f64)).map_err(|e| err("stats/attempts", &e))?;
    rec.log("stats/successes", &rerun::Scalars::single(stats.successes as f64)).map_err(|e| err("stats/successes", &e))?;
    rec.log("stats/generation_rate", &rerun::Scalars::single(stats.rate())).map_err(|e| err("stats/generation_rate", &e))?;
    for (d, used) in stats.per_source_demo.iter().enumerate() {
        let name = source_names.get(d).cloned().unwrap_or_else(|| format!("demo_{d}"));
        let path = format!("stats/per_source_demo/{name}");
        rec.log(format!("{path}/attempts"), &rerun::Scalars::single(used.attempts as f64)).map_err(|e| err(&path, &e))?;
        rec.log(format!("{path}/successes"), &rerun::Scalars::single(used.successes as f64)).map_err(|e| err(&path, &e))?;
    }
    Ok(())
}

/// Logs a two-arm attempt ([`TwoArmAttempt`]) under `world/attempt/<arm>` per arm (`arms` names
/// them: each arm's subtask segments as [`log_attempt`] draws one arm's, its executed path and end
/// effector per step) and its ties: a coordinated pair as a band, `plots/ties/coordination_<i>`, 1
/// on the steps the two run together, and a line between the two hands where they start; a
/// sequential tie as a text line at the step the later subtask starts and an arrow from where the
/// first one's arm ended it to where the later one's arm starts. Per arm, `plots/<arm>/gripper`,
/// `plots/<arm>/subtask` and `plots/<arm>/holding` (1 while it holds, waiting or done).
///
/// # Errors
/// [`VizError::Rerun`] from the stream.
#[allow(clippy::too_many_lines)] // one attempt: per arm, then the ties, then the outcome
pub fn log_two_arm_attempt(
    rec: &RecordingStream,
    attempt: &TwoArmAttempt,
    spec: &TwoArmSpec,
    source_names: &[String],
    frame_offset: usize,
) -> Result<(), VizError> {
    let err = |what: &str, e: &dyn std::fmt::Display| VizError::rerun(what, e);
    begin_attempt(rec, attempt.index, &attempt.initial_object_poses, frame_offset)?;
    let k = i64::try_from(attempt.index).unwrap_or(i64::MAX);
    let n = attempt.actions.len();
    let index = || {
        [
            step_column(timelines::STEP, n, as_i64),
            step_column(timelines::ATTEMPT, n, |_| k),
            step_column(timelines::FRAME, n, |t| as_i64(frame_offset + t)),
        ]
    };
    let outcome_color = rgb(if attempt.success { SUCCESS_COLOR } else { FAILURE_COLOR });
    let arm_name = |a: usize| spec.arms.get(a).map_or_else(|| format!("arm{a}"), |arm| arm.name.clone());
    for (a, track) in attempt.arms.iter().enumerate() {
        let name = arm_name(a);
        let root = format!("world/attempt/{name}");
        log_subtask_plans(rec, &root, &track.plans, source_names)?;
        let executed: Vec<[f32; 3]> = track.eef_poses.iter().map(point).collect();
        rec.log(
            format!("{root}/executed_path"),
            &rerun::LineStrips3D::new([executed.clone()])
                .with_colors([outcome_color])
                .with_labels([format!("{name} executed")])
                .with_show_labels(false),
        )
        .map_err(|e| err(&format!("{root}/executed_path"), &e))?;
        if n == 0 || executed.len() != n {
            continue;
        }
        let cols = rerun::Points3D::update_fields()
            .with_positions(executed)
            .with_colors(track.subtask_labels.iter().map(|&s| subtask_color(s)))
            .with_radii(std::iter::repeat_n(0.012_f32, n))
            .columns_of_unit_batches()
            .map_err(|e| err(&root, &e))?;
        rec.send_columns(format!("{root}/eef"), index(), cols).map_err(|e| err(&format!("{root}/eef"), &e))?;
        #[allow(clippy::cast_precision_loss)]
        let series: [(&str, Vec<f64>); 3] = [
            ("gripper", track.gripper_actions.iter().map(|row| row.first().copied().unwrap_or_default()).collect()),
            ("subtask", track.subtask_labels.iter().map(|&s| s as f64).collect()),
            ("holding", track.holding.iter().map(|&h| f64::from(u8::from(h))).collect()),
        ];
        for (what, values) in series {
            let path = format!("plots/{name}/{what}");
            let cols = rerun::Scalars::update_fields().with_scalars(values).columns_of_unit_batches().map_err(|e| err(&path, &e))?;
            rec.send_columns(path.clone(), index(), cols).map_err(|e| err(&path, &e))?;
        }
    }
    for (signal, values) in &attempt.subtask_term_signals {
        let path = format!("plots/signals/{signal}");
        #[allow(clippy::cast_precision_loss)]
        let cols = rerun::Scalars::update_fields()
            .with_scalars(values.iter().map(|&v| v as f64))
            .columns_of_unit_batches()
            .map_err(|e| err(&path, &e))?;
        rec.send_columns(path.clone(), index(), cols).map_err(|e| err(&path, &e))?;
    }
    // The ties, where both of their subtasks ran.
    let plan = |(a, s): ArmSubtask| attempt.arms.get(a).and_then(|t| t.plans.get(s));
    let eef_at = |a: usize, step: usize| attempt.arms.get(a).and_then(|t| t.eef_poses.get(step.min(n.saturating_sub(1)))).map(point);
    let mut coordination = 0;
    for constraint in spec.constraints() {
        match constraint {
            Constraint::Coordination(x, y) => {
                let i = coordination;
                coordination += 1;
                let (Some(px), Some(py)) = (plan(x), plan(y)) else { continue };
                let (start, end) = (px.first_step, px.first_step + px.waypoints.len());
                let path = format!("plots/ties/coordination_{i}");
                let band = (0..n).map(|t| f64::from(u8::from((start..end).contains(&t))));
                let cols = rerun::Scalars::update_fields().with_scalars(band).columns_of_unit_batches().map_err(|e| err(&path, &e))?;
                rec.send_columns(path.clone(), index(), cols).map_err(|e| err(&path, &e))?;
                if let (Some(hx), Some(hy)) = (eef_at(x.0, start), eef_at(y.0, py.first_step)) {
                    let label = format!(
                        "coordination: {} subtask {} with {} subtask {} (steps {start}..{end})",
                        arm_name(x.0),
                        x.1,
                        arm_name(y.0),
                        y.1
                    );
                    rec.log(
                        format!("world/attempt/ties/coordination_{i}"),
                        &rerun::LineStrips3D::new([[hx, hy]])
                            .with_colors([subtask_color(x.1)])
                            .with_labels([label])
                            .with_show_labels(false),
                    )
                    .map_err(|e| err("world/attempt/ties", &e))?;
                }
            }
            Constraint::Sequential { first, later } => {
                let (Some(pf), Some(pl)) = (plan(first), plan(later)) else { continue };
                let ended = pf.first_step + pf.waypoints.len();
                let label = format!(
                    "sequential: {} subtask {} starts at step {} after {} subtask {} ended at step {ended}",
                    arm_name(later.0),
                    later.1,
                    pl.first_step,
                    arm_name(first.0),
                    first.1
                );
                rec.set_time_sequence(timelines::STEP, as_i64(pl.first_step));
                rec.set_time_sequence(timelines::FRAME, as_i64(frame_offset + pl.first_step));
                rec.log("ties", &rerun::TextLog::new(label.clone()).with_level(rerun::TextLogLevel::INFO)).map_err(|e| err("ties", &e))?;
                if let (Some(from), Some(to)) = (eef_at(first.0, ended.saturating_sub(1)), eef_at(later.0, pl.first_step)) {
                    let vector = [to[0] - from[0], to[1] - from[1], to[2] - from[2]];
                    rec.log(
                        format!("world/attempt/ties/sequential_{}_{}_{}_{}", first.0, first.1, later.0, later.1),
                        &rerun::Arrows3D::from_vectors([vector]).with_origins([from]).with_labels([label]).with_show_labels(false),
                    )
                    .map_err(|e| err("world/attempt/ties", &e))?;
                }
                rec.set_time_sequence(timelines::STEP, 0);
                rec.set_time_sequence(timelines::FRAME, as_i64(frame_offset));
            }
        }
    }
    let outcome = match &attempt.failure {
        None if attempt.success => format!("attempt {}: success", attempt.index),
        None => format!("attempt {}: failed", attempt.index),
        Some(f) => format!("attempt {}: FAILED: {f}", attempt.index),
    };
    let level = if attempt.success { rerun::TextLogLevel::INFO } else { rerun::TextLogLevel::WARN };
    rec.log("outcome", &rerun::TextLog::new(outcome).with_level(level)).map_err(|e| err("outcome", &e))?;
    rec.log("plots/attempt/success", &rerun::Scalars::single(f64::from(u8::from(attempt.success)))).map_err(|e| err("success", &e))?;
    Ok(())
}
