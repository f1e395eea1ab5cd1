//! Plans and tried attempts as the preview screen draws them.

use std::collections::BTreeMap;

use mimicgen_engine::transform::WaypointKind;
use mimicgen_engine::{Attempt, Plan, Pose};
use mimicgen_pipeline::PipelineError;
use mimicgen_pipeline::preview::Previewer;

use mimicgen_ui::protocol::{
    ArmPreview, ExecutedView, ObjectView, Point, PreviewRequest, PreviewView, RankView, Reply, SubtaskDiagnostics, SubtaskPreview,
    TiePreview,
};

pub(crate) fn point(pose: &Pose) -> Point {
    let t = pose.translation.vector;
    [t.x, t.y, t.z]
}

pub(crate) fn objects(poses: &BTreeMap<String, Pose>) -> Vec<ObjectView> {
    poses.iter().map(|(name, p)| ObjectView { name: name.clone(), position: point(p), yaw: p.rotation.euler_angles().2 }).collect()
}

/// Each executed subtask of `attempt` in numbers (see [`SubtaskDiagnostics`]).
pub(crate) fn diagnostics(attempt: &Attempt, subtasks: &[mimicgen_engine::SubtaskSpec]) -> Vec<SubtaskDiagnostics> {
    let t = &attempt.trajectory;
    let mm = |v: mimicgen_engine::pose::Vec3| v.norm() * 1000.0;
    attempt
        .plans
        .iter()
        .enumerate()
        .filter_map(|(k, plan)| {
            let first = plan.first_step;
            let end = attempt.plans.get(k + 1).map_or(t.len(), |p| p.first_step).min(t.len());
            let last = end.checked_sub(1).filter(|&l| l >= first)?;
            let target_error_mm = mm(t.target_poses.get(last)?.translation.vector - t.eef_poses.get(last)?.translation.vector);
            let track = |name: &Option<String>| name.as_ref().and_then(|n| t.object_poses.get(n));
            let moved = |poses: &Vec<Pose>| Some(mm(poses.get(last)?.translation.vector - poses.get(first)?.translation.vector));
            let object_moved_mm = track(&subtasks.get(k)?.object_ref).and_then(moved);
            let held_object_slip_mm = k.checked_sub(1).and_then(|j| track(&subtasks.get(j)?.object_ref)).and_then(|poses| {
                let eef_from_obj = |s: usize| Some(t.eef_poses.get(s)?.inverse() * poses.get(s)?);
                Some(mm(eef_from_obj(last)?.translation.vector - eef_from_obj(first)?.translation.vector))
            });
            Some(SubtaskDiagnostics { subtask: k, steps: (first, end), target_error_mm, object_moved_mm, held_object_slip_mm })
        })
        .collect()
}

/// Turns a plan (and an executed attempt) into what the preview screen draws.
pub(crate) fn preview_view(previewer: &Previewer, plan: &Plan, executed: Option<&Attempt>) -> PreviewView {
    let demos = &previewer.generator().dataset().demos;
    let name = |d: usize| demos.get(d).map_or_else(|| format!("demo {d}"), |demo| demo.name.clone());
    let spec = previewer.generator().spec();
    // Once executed, the segments the attempt really ran: from subtask 1 on, the selection sees
    // where the objects are then, which a plan made before executing cannot know.
    let ran = executed.map_or(&[][..], |a| &a.plans[..]);
    let subtasks = plan
        .subtasks
        .iter()
        .enumerate()
        .map(|(k, s)| ran.get(k).unwrap_or(s))
        .zip(&spec.subtasks)
        .map(|(s, subtask)| {
            let mut ranking: Vec<RankView> = s
                .source_distances
                .iter()
                .flatten()
                .enumerate()
                .map(|(demo, &distance)| RankView { demo, name: name(demo), distance })
                .collect();
            ranking.sort_by(|a, b| a.distance.total_cmp(&b.distance).then(a.demo.cmp(&b.demo)));
            let bridge = s.waypoints.iter().take_while(|(_, k)| *k == WaypointKind::Interpolation).map(|(p, _)| point(p)).collect();
            let transit = s.waypoints.iter().take_while(|(_, k)| *k == WaypointKind::Transit).map(|(p, _)| point(p)).collect();
            let drive = s.waypoints.iter().filter(|(_, k)| *k == WaypointKind::Base).map(|(p, _)| point(p)).collect();
            SubtaskPreview {
                object: subtask.object_ref.clone(),
                src_demo: s.src_demo,
                src_demo_name: name(s.src_demo),
                src_span: s.src_span,
                ranking,
                source_path: s.source_poses.iter().map(point).collect(),
                source_object: s.world_from_obj_src.as_ref().map(point),
                bridge,
                transit,
                drive,
                transformed: s.transformed_poses.iter().map(point).collect(),
            }
        })
        .collect();
    let executed = executed.map(|a| ExecutedView {
        success: a.success,
        failure: a.failure.as_ref().map(|f| format!("subtask {}: {}", f.subtask, f.reason)),
        cause: a.cause.as_ref().map(ToString::to_string),
        path: a.trajectory.eef_poses.iter().map(point).collect(),
        planned: a.plans.iter().flat_map(|p| p.waypoints.iter().map(|(w, _)| point(w))).collect(),
        subtask_of_step: a.trajectory.subtask_labels.clone(),
        sources: a.src_demo_per_subtask.clone(),
        final_objects: objects(&a.trajectory.object_poses.iter().filter_map(|(n, p)| Some((n.clone(), *p.last()?))).collect()),
        diagnostics: diagnostics(a, &spec.subtasks),
    });
    PreviewView {
        task: previewer.pipeline().task().name().to_owned(),
        variant: previewer.pipeline().variant().to_owned(),
        seed: spec.generation.seed,
        index: plan.index,
        eef: point(&plan.world_from_eef),
        objects: objects(&plan.initial_object_poses),
        subtasks,
        executed,
        failure_3d: None,
        arms: Vec::new(),
        ties: Vec::new(),
    }
}

/// A tried two-arm attempt as the preview draws it: per arm its path and its subtasks' waypoints,
/// and the ties where both of their subtasks ran; `executed` carries the outcome (and arm 0's
/// path, as a one-arm preview's).
pub(crate) fn two_arm_preview_view(
    task: &str,
    variant: &str,
    spec: &mimicgen_engine::two_arm::TwoArmSpec,
    attempt: &mimicgen_engine::two_arm::TwoArmAttempt,
) -> PreviewView {
    use mimicgen_engine::two_arm::Constraint;
    let arms: Vec<ArmPreview> = attempt
        .arms
        .iter()
        .enumerate()
        .map(|(k, track)| ArmPreview {
            name: spec.arms.get(k).map_or_else(|| format!("arm{k}"), |a| a.name.clone()),
            path: track.eef_poses.iter().map(point).collect(),
            segments: track.plans.iter().map(|p| p.waypoints.iter().map(|(w, _)| point(w)).collect()).collect(),
            sources: track.plans.iter().map(|p| p.src_demo).collect(),
        })
        .collect();
    let plan = |(a, k): (usize, usize)| attempt.arms.get(a).and_then(|t| t.plans.get(k));
    let at = |a: usize, step: usize| {
        attempt.arms.get(a).and_then(|t| t.eef_poses.get(step.min(t.eef_poses.len().saturating_sub(1)))).map(point).unwrap_or_default()
    };
    let ties = spec
        .constraints()
        .into_iter()
        .filter_map(|c| match c {
            Constraint::Coordination(x, y) => {
                let (px, _) = (plan(x)?, plan(y)?);
                let (start, end) = (px.first_step, px.first_step + px.waypoints.len());
                Some(TiePreview {
                    coordination: true,
                    from: x,
                    to: y,
                    from_point: at(x.0, start),
                    to_point: at(y.0, start),
                    steps: (start, end),
                })
            }
            Constraint::Sequential { first, later } => {
                let (pf, pl) = (plan(first)?, plan(later)?);
                let ended = pf.first_step + pf.waypoints.len();
                Some(TiePreview {
                    coordination: false,
                    from: first,
                    to: later,
                    from_point: at(first.0, ended.saturating_sub(1)),
                    to_point: at(later.0, pl.first_step),
                    steps: (ended, pl.first_step),
                })
            }
        })
        .collect();
    let final_objects = objects(&attempt.object_poses.iter().filter_map(|(n, p)| Some((n.clone(), *p.last()?))).collect());
    PreviewView {
        task: task.to_owned(),
        variant: variant.to_owned(),
        seed: spec.generation.seed,
        index: attempt.index,
        eef: arms.first().and_then(|a| a.path.first().copied()).unwrap_or_default(),
        objects: objects(&attempt.initial_object_poses),
        subtasks: Vec::new(),
        executed: Some(ExecutedView {
            success: attempt.success,
            failure: attempt.failure.as_ref().map(ToString::to_string),
            cause: None,
            path: arms.first().map(|a| a.path.clone()).unwrap_or_default(),
            planned: Vec::new(),
            subtask_of_step: attempt.arms.first().map(|t| t.subtask_labels.clone()).unwrap_or_default(),
            sources: arms.first().map(|a| a.sources.clone()).unwrap_or_default(),
            final_objects,
            diagnostics: Vec::new(),
        }),
        failure_3d: None,
        arms,
        ties,
    }
}

pub(crate) fn preview_failed(request: &PreviewRequest, e: &PipelineError) -> Reply {
    Reply::Failed {
        what: format!(
            "{} attempt {} of {}",
            if request.execute { "trying" } else { "previewing" },
            request.index,
            request.source.display()
        ),
        error: e.to_string(),
    }
}
