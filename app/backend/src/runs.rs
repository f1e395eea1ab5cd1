//! Generation runs for the generate screen: started, reported attempt by attempt, and finished
//! runs read back from their outputs.

use std::path::{Path, PathBuf};
use std::sync::atomic::AtomicBool;

use mimicgen_engine::RunStats;
use mimicgen_io::{
    ATTEMPT_ATTR, CAUSE_ATTR, DemoReader, DemoSource as _, FAILURE_ATTR, INSTANCE_ATTR, ReadOptions, source_demo_from_group,
};
use mimicgen_pipeline::{AttemptEvent, Event, FrontEnd, Outcome, Pipeline, PipelineError, Report, RunConfig, RunInfo, two_arm};
use mimicgen_viz::RunLogger;

use crate::Notify;
use crate::views::objects;
use mimicgen_ui::protocol::{AttemptRow, OpenedRun, Reply, RunUpdate};

/// An attempt event as the attempt table shows it.
pub(crate) fn attempt_row(event: &AttemptEvent) -> AttemptRow {
    let a = &event.attempt;
    AttemptRow {
        index: a.index,
        success: a.success,
        failed_subtask: a.failure.as_ref().map(|f| f.subtask),
        reason: a.failure.as_ref().map(|f| f.reason.to_string()),
        cause: a.cause.as_ref().map(ToString::to_string),
        sources: a.src_demo_per_subtask.clone(),
        steps: a.trajectory.len(),
        outcome: match &event.outcome {
            Outcome::Written { demo } => demo.clone(),
            Outcome::KeptFailed { demo } => format!("{demo} (failed)"),
            Outcome::Discarded => "discarded".to_owned(),
        },
        elapsed_s: event.elapsed_s,
        objects: objects(&a.initial_object_poses),
        instance: event.instance.clone(),
        stats: event.stats.clone(),
    }
}

/// Runs `config` through the pipeline, reporting every event to `notify`; stops when `cancel` is set.
/// With the 3D view open, every attempt is also logged to `logger` as it is decided (a failure
/// to log ends the logging, not the run).
pub(crate) fn run_generation(config: &RunConfig, cancel: &AtomicBool, notify: &Notify, mut logger: Option<RunLogger>) {
    let update = |u: RunUpdate| notify(Reply::Run(u));
    let pipeline = match Pipeline::prepare(config) {
        Ok(p) => p,
        Err(e) => return update(RunUpdate::Failed(e.worded(FrontEnd::App))),
    };
    let result = pipeline.run(cancel, |event| match event {
        Event::Started(info) => update(RunUpdate::Started { info: info.clone(), dimensions: pipeline.task().coverage_dimensions() }),
        Event::Attempt(a) => {
            update(RunUpdate::Attempt(Box::new(attempt_row(a))));
            if let Some(l) = &mut logger
                && l.log_attempt(&a.attempt, &a.stats).is_err()
            {
                logger = None;
            }
        }
        Event::Finished(_) => {}
    });
    if let Some(l) = logger {
        let _ = l.finish();
    }
    match result {
        Ok(report) => update(RunUpdate::Finished(Box::new(report))),
        Err(e) => update(RunUpdate::Failed(e.worded(FrontEnd::App))),
    }
}

/// Reads a finished run's outputs (the dataset `path`, its `_failed.hdf5` and its `.json` report
/// where they exist) and reports them to `notify` as a run would: started, every kept attempt in
/// index order, finished. Attempts that were not kept (failures beyond `max_num_failures`, or all
/// failures without `--keep-failed`) are not in the files; the report still counts them.
///
/// # Errors
/// A file that cannot be read, or demos without `mimicgen_attempt` (not made by `generate`).
pub fn open_run(path: &Path, notify: &Notify) -> Result<(), PipelineError> {
    let run = read_run(path)?;
    let update = |u: RunUpdate| notify(Reply::Run(u));
    update(RunUpdate::Started { info: Box::new(run.info), dimensions: run.dimensions });
    for row in run.rows {
        update(RunUpdate::Attempt(Box::new(row)));
    }
    update(RunUpdate::Finished(Box::new(run.report)));
    Ok(())
}

/// A finished run's outputs read whole (see [`open_run`]).
///
/// # Errors
/// As [`open_run`].
pub fn read_run(path: &Path) -> Result<OpenedRun, PipelineError> {
    let label = path.display().to_string();
    let report_path = mimicgen_pipeline::sibling(path, "", "json");
    let report: Option<Report> = match std::fs::read_to_string(&report_path) {
        Ok(text) => Some(
            serde_json::from_str(&text)
                .map_err(|e| PipelineError::Fs { file: report_path.display().to_string(), reason: format!("not a run report: {e}") })?,
        ),
        Err(_) => None,
    };
    let mut rows: Vec<AttemptRow> = Vec::new();
    let mut env_args = None;
    let failed = mimicgen_pipeline::failed_path(path);
    for (file, success) in [(path.to_path_buf(), true), (failed.clone(), false)] {
        if !success && !file.is_file() {
            continue;
        }
        let reader = DemoReader::open_with(&file, ReadOptions::default())?.without_observations();
        let file_label = file.display().to_string();
        env_args = env_args.or_else(|| reader.env_args_json().map(str::to_owned));
        for name in reader.demo_names() {
            let group = reader.load_demo(name)?;
            let index = group.attrs.get(ATTEMPT_ATTR).and_then(mimicgen_io::tree::Array::as_i64).and_then(|i| u64::try_from(i).ok());
            let index = index.ok_or_else(|| PipelineError::Fs {
                file: file_label.clone(),
                reason: format!("data/{name} has no {ATTEMPT_ATTR} attribute: the file was not written by `mimicgen generate`"),
            })?;
            let demo = source_demo_from_group(&file_label, name, &group)?;
            let sources = group
                .dataset("src_demo_inds")
                .and_then(|d| d.array.values.to_i64())
                .map(|v| v.into_iter().filter_map(|i| usize::try_from(i).ok()).collect())
                .unwrap_or_default();
            // `subtask k: reason`, as the writer puts it.
            let failure = group.attrs.get(FAILURE_ATTR).and_then(mimicgen_io::tree::Array::as_str);
            let parsed = failure.and_then(|f| {
                let (subtask, reason) = f.strip_prefix("subtask ")?.split_once(": ")?;
                Some((subtask.parse::<usize>().ok()?, reason.to_owned()))
            });
            let (failed_subtask, reason) = match parsed {
                Some((k, r)) => (Some(k), Some(r)),
                None => (None, failure.map(str::to_owned)),
            };
            rows.push(AttemptRow {
                index,
                success,
                failed_subtask,
                reason: if success { None } else { Some(reason.unwrap_or_else(|| "not recorded in the file".to_owned())) },
                cause: group
                    .attrs
                    .get(CAUSE_ATTR)
                    .and_then(mimicgen_io::tree::Array::as_str)
                    .and_then(|json| serde_json::from_str::<mimicgen_engine::diagnose::Cause>(json).ok())
                    .map(|c| c.to_string()),
                sources,
                steps: demo.len(),
                outcome: if success { name.clone() } else { format!("{name} (failed)") },
                elapsed_s: 0.0,
                objects: objects(&demo.object_poses.iter().filter_map(|(k, v)| Some((k.clone(), *v.first()?))).collect()),
                instance: group.attrs.get(INSTANCE_ATTR).and_then(mimicgen_io::tree::Array::as_str).map(str::to_owned),
                stats: RunStats::default(),
            });
        }
    }
    rows.sort_by_key(|r| r.index);
    let num_sources = report
        .as_ref()
        .map_or(0, |r| r.per_source_demo.len())
        .max(rows.iter().flat_map(|r| r.sources.iter().map(|d| d + 1)).max().unwrap_or(0));
    let mut stats = RunStats::new(num_sources);
    for row in &mut rows {
        stats.attempts += 1;
        stats.successes += usize::from(row.success);
        let mut used: Vec<usize> = row.sources.clone();
        used.sort_unstable();
        used.dedup();
        for d in used {
            if let Some(u) = stats.per_source_demo.get_mut(d) {
                u.attempts += 1;
                u.successes += usize::from(row.success);
            }
        }
        row.stats = stats.clone();
    }
    let (task, variant) = mimicgen_sim::registry::task_from_env_args(env_args.as_deref())
        .map_err(|e| PipelineError::Fs { file: label.clone(), reason: format!("data attribute env_args: {e}") })?;
    let info = RunInfo {
        task: task.name().to_owned(),
        variant,
        source: report.as_ref().map(|r| PathBuf::from(&r.source)).unwrap_or_default(),
        num_sources,
        workers: report.as_ref().map_or(1, |r| r.workers),
        seed: report.as_ref().map_or(0, |r| r.seed),
        spec_overrides: report.as_ref().map(|r| r.spec_overrides.clone()).unwrap_or_default(),
        target: report.as_ref().map_or(rows.len(), |r| r.attempts),
        guarantee: false,
        resumed_from: 0,
    };
    let kept = rows.len();
    let report = report.unwrap_or_else(|| Report {
        task: task.name().to_owned(),
        variant: String::new(),
        seed: 0,
        workers: 1,
        source: String::new(),
        config: None,
        robot: None,
        output: label.clone(),
        failed_output: failed.is_file().then(|| failed.display().to_string()),
        attempts: kept,
        successes: stats.successes,
        generation_rate: stats.rate(),
        wall_time_s: 0.0,
        attempts_per_s: 0.0,
        control_steps: 0,
        per_source_demo: Vec::new(),
        per_subtask_source: Vec::new(),
        never_succeeded: Vec::new(),
        per_object_instance: Vec::new(),
        peak_rss_mib: None,
        failures: Vec::new(),
        causes: Vec::new(),
        cancelled: false,
        resumed_from: 0,
        early_abort: false,
        spec_overrides: mimicgen_pipeline::SpecOverrides::default(),
        shard: None,
        quality: None,
        transit: mimicgen_engine::generate::TransitTotals::default(),
    });
    Ok(OpenedRun { path: path.to_path_buf(), info, dimensions: task.coverage_dimensions(), rows, report })
}

/// Runs `config` as a two-arm run (its source is a two-arm file), reporting to `notify` as
/// [`run_generation`] does, its subtasks numbered through both arms (arm 0's, then arm 1's); the
/// report is also written as `<out>.json`, as `mimicgen generate` writes it.
pub(crate) fn run_two_arm_generation(config: &RunConfig, cancel: &AtomicBool, notify: &Notify) {
    let update = |u: RunUpdate| notify(Reply::Run(u));
    let result = two_arm::TwoArmRun::from_config(config).and_then(|run| {
        let started = std::time::Instant::now();
        two_arm::run_and_report(&run, cancel, &mut |event| match event {
            two_arm::TwoArmEvent::Started { source_names, .. } => {
                update(RunUpdate::Started { info: Box::new(run.info(source_names.len())), dimensions: Vec::new() });
            }
            two_arm::TwoArmEvent::Attempt { attempt, stats, written, subtask_counts, .. } => {
                // Each subtask's source by its number (arm 1's after all of arm 0's).
                let mut sources = Vec::new();
                for (k, demo) in attempt.flat_sources(subtask_counts) {
                    if k == sources.len() {
                        sources.push(demo);
                    }
                }
                let failure = attempt.flat_failure(subtask_counts);
                let row = AttemptRow {
                    index: attempt.index,
                    success: attempt.success,
                    failed_subtask: failure.as_ref().map(|f| f.subtask),
                    // The arm is in the subtask's number (the UI names it).
                    reason: failure.map(|f| f.reason.to_string()),
                    cause: None,
                    sources,
                    steps: attempt.actions.len(),
                    outcome: written.map_or_else(|| "discarded".to_owned(), str::to_owned),
                    elapsed_s: started.elapsed().as_secs_f64(),
                    objects: objects(&attempt.initial_object_poses),
                    instance: None,
                    stats: stats.clone(),
                };
                update(RunUpdate::Attempt(Box::new(row)));
            }
        })
    });
    match result {
        Ok((_, report)) => update(RunUpdate::Finished(Box::new(report))),
        Err(e) => update(RunUpdate::Failed(e.worded(FrontEnd::App))),
    }
}
