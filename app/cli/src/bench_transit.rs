//! `mimicgen bench-transit`: interpolated against planned transit on the same attempts, as the
//! rates, obstacle contacts and planning costs BENCHMARKS.md reports.
#![allow(clippy::indexing_slicing, reason = "reading a serde_json::Value by key or index gives Null where it has none; it never panics")]

use std::ops::ControlFlow;
use std::sync::Arc;
use std::time::Instant;

use mimicgen_engine::spec::Transit;
use mimicgen_engine::{Attempt, Generator, SourceDataset};
use mimicgen_pipeline::{Pipeline, RunConfig};
use mimicgen_sim::SimEnv;
use serde_json::json;

use crate::exit::outln;

/// Arguments of `mimicgen bench-transit`.
#[derive(clap::Args, Debug)]
#[command(after_help = "\
Examples:
  mimicgen bench-transit --task stack --variant C0 --attempts 1000
  mimicgen bench-transit --task square --variant C0 --attempts 1000 --sources 1,3,10
  mimicgen bench-transit --task stack --variant D0 --attempts 1000   # no clutter: the cost of planning

Runs the same attempts (same seed, same scenes) with MimicGen's interpolation and with planned
transit, for each number of source demos, and prints a table (and the JSON with --json): the
success rate with its 95 % interval, the attempts in which the robot or what it held touched an
obstacle, planning time per attempt (median and 95th percentile) and its share of the workers'
time, and the attempts that found no path. Nothing is written to disk.")]
pub struct BenchTransitArgs {
    /// Task.
    #[arg(long, default_value = "stack")]
    task: String,
    /// Variant (C0: the cluttered one).
    #[arg(long, default_value = "C0")]
    variant: String,
    /// Attempts per row.
    #[arg(long, default_value_t = 1000)]
    attempts: usize,
    /// Worker threads (default: one per core).
    #[arg(long)]
    workers: Option<usize>,
    /// Numbers of source demos to generate from (the first N of the bundled ones); `all` for all.
    #[arg(long, default_value = "all", value_delimiter = ',')]
    sources: Vec<String>,
    /// Run seed.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Also write the rows as JSON here.
    #[arg(long)]
    json: Option<std::path::PathBuf>,
}

/// One row: a transit mode and a number of sources over the attempts.
struct Row {
    transit: Transit,
    sources: usize,
    attempts: Vec<Attempt>,
    wall_s: f64,
    workers: usize,
}

impl Row {
    #[allow(clippy::cast_precision_loss)] // counts are far below 2^52
    fn to_json(&self) -> serde_json::Value {
        let n = self.attempts.len().max(1) as f64;
        let successes = self.attempts.iter().filter(|a| a.success).count();
        let touched = self.attempts.iter().filter(|a| a.obstacle_contact_steps > 0).count();
        let steps: usize = self.attempts.iter().map(|a| a.obstacle_contact_steps).sum();
        let mut planning: Vec<f64> =
            self.attempts.iter().map(|a| a.plans.iter().filter_map(|p| p.transit).fold(0.0, |s, t| s + t.seconds)).collect();
        planning.sort_by(f64::total_cmp);
        let quantile = |q: f64| {
            #[allow(clippy::cast_possible_truncation, clippy::cast_sign_loss)] // an index into `planning`
            let i = ((planning.len() as f64 - 1.0) * q).round() as usize;
            planning.get(i).copied().unwrap_or(0.0)
        };
        let no_path = self
            .attempts
            .iter()
            .filter(|a| a.failure.as_ref().is_some_and(|f| matches!(f.reason, mimicgen_engine::FailureReason::NoTransitPath { .. })))
            .count();
        let rate = successes as f64 / n;
        // Wilson's 95 % interval.
        let z = 1.96_f64;
        let centre = (rate + z * z / (2.0 * n)) / (1.0 + z * z / n);
        let half = z * (rate * (1.0 - rate) / n + z * z / (4.0 * n * n)).sqrt() / (1.0 + z * z / n);
        json!({
            "transit": self.transit.name(),
            "sources": self.sources,
            "attempts": self.attempts.len(),
            "successes": successes,
            "rate": rate,
            "rate_95": [centre - half, centre + half],
            "obstacle_attempts": touched,
            "obstacle_steps_per_attempt": steps as f64 / n,
            "planning_ms_median": 1000.0 * quantile(0.5),
            "planning_ms_p95": 1000.0 * quantile(0.95),
            "planning_share": planning.iter().fold(0.0, |s, t| s + t) / (self.wall_s * self.workers as f64).max(1e-9),
            "no_path": no_path,
            "wall_s": self.wall_s,
            "workers": self.workers,
        })
    }
}

/// Runs the benchmark.
///
/// # Errors
/// As `mimicgen generate`.
pub fn run(args: &BenchTransitArgs) -> anyhow::Result<()> {
    let pipeline = Pipeline::prepare(&RunConfig {
        task: Some(args.task.clone()),
        variant: Some(args.variant.clone()),
        num_demos: Some(args.attempts),
        seed: Some(args.seed),
        ..RunConfig::default()
    })?;
    let workers = args.workers.unwrap_or_else(|| std::thread::available_parallelism().map_or(1, std::num::NonZero::get)).max(1);
    let all = pipeline.generator().dataset().demos.len();
    let counts: Vec<usize> = args
        .sources
        .iter()
        .map(|s| if s == "all" { Ok(all) } else { s.parse::<usize>().map(|n| n.clamp(1, all)) })
        .collect::<Result<_, _>>()
        .map_err(|e| anyhow::anyhow!("--sources: {e} (numbers of source demos, or all)"))?;
    let mut rows = Vec::new();
    for &sources in &counts {
        for transit in [Transit::Interpolate, Transit::Plan] {
            let mut spec = pipeline.generator().spec().clone();
            for subtask in &mut spec.subtasks {
                subtask.transit = transit;
            }
            let dataset = SourceDataset {
                demos: pipeline.generator().dataset().demos.iter().take(sources).cloned().collect(),
                env_args: pipeline.generator().dataset().env_args.clone(),
            };
            let generator = Generator::new(spec, dataset)?;
            let mut envs: Vec<SimEnv> =
                (0..workers).map(|_| SimEnv::new(Arc::clone(pipeline.scene()), Arc::clone(pipeline.task()))).collect();
            let bar = indicatif::ProgressBar::new(args.attempts as u64)
                .with_message(format!("{} sources, {}", sources, transit.name()))
                .with_style(
                    indicatif::ProgressStyle::with_template("{msg:>24} {bar:30} {pos}/{len} ({eta})")
                        .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
                );
            let started = Instant::now();
            let mut attempts = Vec::with_capacity(args.attempts);
            mimicgen_engine::run(&generator, &mut envs, |a, _| {
                bar.inc(1);
                attempts.push(a);
                ControlFlow::Continue(())
            })?;
            bar.finish_and_clear();
            let row = Row { transit, sources, attempts, wall_s: started.elapsed().as_secs_f64(), workers };
            let j = row.to_json();
            eprintln!(
                "{} {} {:>2} sources, {:>11}: {:>5.1} % [{:.1}, {:.1}], obstacle touched {:>5.1} %, planning {:.1} ms median, {:.1} ms p95, {:.1} % of worker time, {} without path",
                args.task,
                args.variant,
                sources,
                transit.name(),
                100.0 * j["rate"].as_f64().unwrap_or(0.0),
                100.0 * j["rate_95"][0].as_f64().unwrap_or(0.0),
                100.0 * j["rate_95"][1].as_f64().unwrap_or(0.0),
                100.0 * j["obstacle_attempts"].as_f64().unwrap_or(0.0) / args.attempts.max(1) as f64,
                j["planning_ms_median"].as_f64().unwrap_or(0.0),
                j["planning_ms_p95"].as_f64().unwrap_or(0.0),
                100.0 * j["planning_share"].as_f64().unwrap_or(0.0),
                j["no_path"],
            );
            rows.push(j);
        }
    }
    let out = json!({"task": args.task, "variant": args.variant, "seed": args.seed, "rows": rows});
    if let Some(path) = &args.json {
        std::fs::write(path, serde_json::to_string_pretty(&out)?).map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))?;
    }
    outln!("{}", serde_json::to_string_pretty(&out)?);
    Ok(())
}
