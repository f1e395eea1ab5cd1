//! Joining the shards of a run (`mimicgen generate --shard i/K`, run anywhere) into the dataset of
//! the whole run: the same demos with the same arrays, the same failed attempts, masks, progress
//! and report counts as one process with the same seed makes.
//!
//! Each shard made the attempts whose index is `i` modulo `K`, and logged every decided attempt
//! (`<out>.attempts.jsonl`). The merge walks the indices in order through the logs, stops where
//! the whole run stops (after `num_trials` attempts; with `guarantee`, at the `num_trials`-th
//! success, which every shard has passed because each ran to its own `num_trials` successes),
//! and copies the kept demos in that order.

use std::path::{Path, PathBuf};

use mimicgen_engine::{RunStats, Shard};
use mimicgen_io::{DatasetWriter, DemoReader, DemoSource as _, ReadOptions, WriterOptions};

use crate::outputs::{
    AttemptRecord, Progress, RunDescription, attempt_log_path, clear_outputs, differing_fields, failed_path, read_attempt_log,
};
use crate::{PROGRESS_ATTR, PipelineError, RUN_ATTR, Report, sibling};

/// One shard's outputs, read and checked.
struct ShardFiles {
    path: PathBuf,
    shard: Shard,
    description: RunDescription,
    report: Report,
    records: Vec<AttemptRecord>,
}

fn read_shard(path: &Path) -> Result<ShardFiles, PipelineError> {
    let file = path.display().to_string();
    if !path.is_file() {
        return Err(PipelineError::input(file, "shard", "no such file (a shard's dataset, as `generate --shard` wrote it)"));
    }
    let report_path = sibling(path, "", "json");
    let text = std::fs::read_to_string(&report_path)
        .map_err(|e| PipelineError::Fs { file: report_path.display().to_string(), reason: format!("the shard's report: {e}") })?;
    let report: Report =
        serde_json::from_str(&text).map_err(|e| PipelineError::input(report_path.display().to_string(), "report", e.to_string()))?;
    let description = mimicgen_io::root_string_attrs(path, &[RUN_ATTR])?
        .into_iter()
        .next()
        .flatten()
        .ok_or_else(|| PipelineError::input(file.clone(), RUN_ATTR, "missing: this dataset was not written by `mimicgen generate`"))?;
    let description: RunDescription =
        serde_json::from_str(&description).map_err(|e| PipelineError::input(file.clone(), RUN_ATTR, e.to_string()))?;
    let Some(shard) = description.shard else {
        return Err(PipelineError::input(file, RUN_ATTR, "is a whole run, not a shard (made without --shard)"));
    };
    if report.cancelled {
        return Err(PipelineError::input(
            report_path.display().to_string(),
            "cancelled",
            "this shard was cancelled before its share was done; run it again, replacing its outputs",
        ));
    }
    let records = read_attempt_log(&attempt_log_path(path))?;
    if let Some(r) = records.iter().find(|r| !shard.contains(r.index)) {
        return Err(PipelineError::input(
            attempt_log_path(path).display().to_string(),
            "index",
            format!("attempt {} is not in shard {shard}", r.index),
        ));
    }
    let sources = report.per_source_demo.len();
    if let Some((r, d)) = records.iter().find_map(|r| r.sources.iter().find(|&&d| d >= sources).map(|&d| (r, d))) {
        return Err(PipelineError::input(
            attempt_log_path(path).display().to_string(),
            "sources",
            format!("attempt {} names source demo {d}, but the run has {sources} (its report's per_source_demo)", r.index),
        ));
    }
    Ok(ShardFiles { path: path.to_path_buf(), shard, description, report, records })
}

/// Checks that `shards` are the shares of one run, all of them, once each.
fn check_set(shards: &[ShardFiles]) -> Result<(), PipelineError> {
    let Some(first) = shards.first() else { return Err(PipelineError::input("", "SHARD", "no shards given")) };
    let count = first.shard.count;
    let whole = |d: &RunDescription| RunDescription { shard: None, ..d.clone() };
    for s in shards {
        if s.shard.count != count {
            return Err(PipelineError::input(
                s.path.display().to_string(),
                "shard",
                format!("is shard {} but {} is shard {}: the shards of one run share K", s.shard, first.path.display(), first.shard),
            ));
        }
        if whole(&s.description) != whole(&first.description) {
            let json = |d: &RunDescription| serde_json::to_value(whole(d)).unwrap_or_default();
            let differing = differing_fields(&json(&s.description), &json(&first.description));
            return Err(PipelineError::input(
                s.path.display().to_string(),
                RUN_ATTR,
                format!("describes another run than {} ({} differ)", first.path.display(), differing.join(", ")),
            ));
        }
    }
    let mut parts: Vec<usize> = shards.iter().map(|s| s.shard.part).collect();
    parts.sort_unstable();
    if let Some(part) = parts.windows(2).find_map(|w| if let &[a, b] = w { (a == b).then_some(a) } else { None }) {
        return Err(PipelineError::input("", "SHARD", format!("shard {part}/{count} is given twice")));
    }
    let missing: Vec<String> = (0..count).filter(|p| !parts.contains(p)).map(|p| format!("{p}/{count}")).collect();
    if !missing.is_empty() {
        return Err(PipelineError::input("", "SHARD", format!("shards {} are missing", missing.join(", "))));
    }
    Ok(())
}

/// Joins the shards of one run into `out` (with `<out>_failed.hdf5` where the run keeps failed
/// attempts, and the report `<out>.json`, which it returns). `on_progress(done, total)` follows
/// the copying.
///
/// # Errors
/// [`PipelineError::Input`] naming the file and field: a shard that is missing, given twice,
/// from another run, cancelled, or that lacks an attempt the whole run made; outputs that exist
/// without `overwrite`; read and write errors.
#[allow(
    clippy::indexing_slicing,
    reason = "check_set leaves exactly the parts 0..count, once each; sorted by part, shards[p] is part p, and readers, \
              failed_readers and cursors have one entry per shard, so every `[index % count]` and `[part]` is in bounds"
)]
pub fn merge(
    shard_paths: &[PathBuf],
    out: &Path,
    overwrite: bool,
    mut on_progress: impl FnMut(usize, usize),
) -> Result<Report, PipelineError> {
    let mut shards = shard_paths.iter().map(|p| read_shard(p)).collect::<Result<Vec<_>, _>>()?;
    check_set(&shards)?;
    shards.sort_by_key(|s| s.shard.part);
    let count = shards[0].shard.count;
    let description = RunDescription { shard: None, ..shards[0].description.clone() };
    let settings = &description.spec.generation;
    let cap = settings.attempt_cap();
    // Index order through the logs, cut where the whole run stops.
    let mut cursors = vec![0usize; count];
    let mut order: Vec<&AttemptRecord> = Vec::new();
    let mut successes = 0;
    for index in 0..cap {
        if settings.guarantee && successes >= settings.num_trials {
            break;
        }
        let s = &shards[index % count];
        let record = s.records.get(cursors[index % count]).filter(|r| r.index == index).ok_or_else(|| {
            PipelineError::input(
                attempt_log_path(&s.path).display().to_string(),
                "index",
                format!("attempt {index} is missing: shard {} stopped before the whole run would have", s.shard),
            )
        })?;
        cursors[index % count] += 1;
        successes += usize::from(record.success);
        order.push(record);
    }
    let (failed_out, report_path) = (failed_path(out), sibling(out, "", "json"));
    clear_outputs(out, None, overwrite, false)?;
    let open = |path: &Path| DemoReader::open_with(path, ReadOptions::default());
    let readers = shards.iter().map(|s| open(&s.path)).collect::<Result<Vec<_>, _>>()?;
    let failed_readers = shards
        .iter()
        .map(|s| {
            let failed = failed_path(&s.path);
            if settings.keep_failed && failed.is_file() { open(&failed).map(Some) } else { Ok(None) }
        })
        .collect::<Result<Vec<_>, _>>()?;
    let env_args = readers[0].data_attrs().get("env_args").and_then(mimicgen_io::tree::Array::as_str).map(str::to_owned);
    let options = WriterOptions { env_args, compress_obs: true, valid_fraction: description.valid_fraction, split_seed: settings.seed };
    let mut writer = DatasetWriter::create(out, options.clone())?;
    writer.set_root_attr(RUN_ATTR, &serde_json::to_string(&description).map_err(|e| PipelineError::input("", RUN_ATTR, e.to_string()))?)?;
    let mut failed_writer = if settings.keep_failed {
        Some(DatasetWriter::create(&failed_out, WriterOptions { valid_fraction: None, ..options })?)
    } else {
        None
    };
    let mut stats = RunStats::new(shards[0].report.per_source_demo.len());
    let (mut failures_kept, mut control_steps) = (0, 0);
    for (done, record) in order.iter().enumerate() {
        stats.record_outcome(record.success, &record.sources, record.failure.as_ref(), record.cause.as_ref());
        control_steps += record.steps;
        let part = record.index % count;
        let (target, reader) = if record.success {
            (Some(&mut writer), Some(&readers[part]))
        } else if failures_kept < settings.max_num_failures && failed_writer.is_some() {
            failures_kept += 1;
            (failed_writer.as_mut(), failed_readers[part].as_ref())
        } else {
            (None, None)
        };
        if let Some(target) = target {
            let (Some(reader), Some(name)) = (reader, &record.kept) else {
                return Err(PipelineError::input(
                    shards[part].path.display().to_string(),
                    "kept",
                    format!("attempt {} is kept by the whole run but its shard did not keep it", record.index),
                ));
            };
            target.append_group(&*reader.load_demo(name)?)?;
        }
        on_progress(done + 1, order.len());
    }
    let progress = Progress { next_attempt: order.last().map_or(0, |r| r.index + 1), failures_kept, stats: stats.clone() };
    writer.set_root_attr(PROGRESS_ATTR, &serde_json::to_string(&progress).unwrap_or_default())?;
    let written = writer.finish()?;
    let failed_written = failed_writer.map(DatasetWriter::finish).transpose()?;
    let first = &shards[0].report;
    // The quality report of the joined dataset, from its demos' figures in the shards' logs.
    let (quality, scenes) = crate::outputs::logged_quality(order.iter().copied());
    let dataset_quality = match mimicgen_sim::registry::task(&first.task, &first.variant) {
        Ok(task) => Some(crate::run::dataset_quality(task.as_ref(), &written, quality.summary(), &scenes, true)),
        Err(_) => None,
    };
    if let Some(q) = &dataset_quality {
        crate::outputs::write_quality(out, q)?;
    }
    // The shards ran side by side: the run took as long as the slowest.
    let wall_time_s = shards.iter().map(|s| s.report.wall_time_s).fold(0.0, f64::max);
    let report = Report {
        task: first.task.clone(),
        variant: first.variant.clone(),
        seed: first.seed,
        workers: shards.iter().map(|s| s.report.workers).sum(),
        source: first.source.clone(),
        config: first.config.clone(),
        robot: first.robot.clone(),
        output: written.display().to_string(),
        failed_output: failed_written.map(|p| p.display().to_string()),
        attempts: stats.attempts,
        successes: stats.successes,
        generation_rate: stats.rate(),
        wall_time_s,
        #[allow(clippy::cast_precision_loss)]
        attempts_per_s: if wall_time_s > 0.0 { stats.attempts as f64 / wall_time_s } else { 0.0 },
        control_steps,
        per_source_demo: crate::outputs::per_source_demo(&stats),
        per_subtask_source: crate::outputs::per_subtask_source(&stats),
        never_succeeded: crate::outputs::never_succeeded(&stats),
        per_object_instance: crate::outputs::InstanceTally::of(order.iter().copied()).report(),
        peak_rss_mib: crate::memory::peak_rss_mib(),
        failures: crate::outputs::failures(&stats),
        causes: crate::outputs::causes(&stats),
        cancelled: false,
        resumed_from: 0,
        early_abort: first.early_abort,
        spec_overrides: first.spec_overrides.clone(),
        shard: None,
        quality: dataset_quality,
        transit: mimicgen_engine::generate::TransitTotals::default(),
    };
    std::fs::write(&report_path, serde_json::to_string_pretty(&report).unwrap_or_default())
        .map_err(|e| PipelineError::Fs { file: report_path.display().to_string(), reason: e.to_string() })?;
    Ok(report)
}
