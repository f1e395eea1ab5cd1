//! `mimicgen generate`: run the engine on the MuJoCo backend and write robomimic datasets, with
//! a progress bar and the report's summary.

use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};

use anyhow::Context as _;
use indicatif::{ProgressBar, ProgressStyle};
use mimicgen_engine::spec::Transit;
use mimicgen_pipeline::{Event, OffsetRange, Pipeline, RunConfig, Scoped, SpecOverrides};

use crate::exit::outln;

/// Arguments of `mimicgen generate`.
#[derive(clap::Args, Debug)]
#[command(after_help = "\
Examples:
  mimicgen generate                                   # 100 attempts of Stack D0 from the bundled demos
  mimicgen generate --variant D1 --num-demos 1000 --workers 2 --out out/stack_d1.hdf5
  mimicgen generate --task square --variant D2 --num-demos 1000 --out out/square_d2.hdf5
  mimicgen generate --task stack_three --guarantee --num-demos 200 --out out/stack_three.hdf5
  mimicgen generate --source source_D0_prepared.hdf5 --config config_D1.json   # your MimicGen files: Stack D1
  mimicgen generate --num-demos 1000 --out out/big.hdf5 --resume      # continue a killed run exactly
  mimicgen generate --action-noise 0.02 --selection 1:random --offset-range 0:0,10   # spec fields for this run
  mimicgen generate --task square --robot sawyer --out out/square_sawyer.hdf5   # Panda demos, Sawyer data
  mimicgen generate --task two_arm_lift --variant D1 --num-demos 1000 --out out/two_arm_lift_d1.hdf5   # two arms

The task and variant come from --task/--variant, else from the config's experiment.task.name
(MimicGen's `Stack_D1`), else from the source file's env_args, else stack / D0; inputs that name
different tasks are an error. Successful attempts go to --out (robomimic layout, low-dim
observations); with --keep-failed, failed ones go to <out>_failed.hdf5. A JSON report (rate, per
source demo, failures by subtask and reason, and by subtask and cause: object_moved, arm_lagged,
grasp_slipped, grasp_missed, ran_out_of_steps, success_unmet, simulation) is printed and written
next to the dataset as <out>.json; a quality report (stitch jumps and jerks per subtask, pose
actions against the controller's limits, support coverage of the successes, 3 written demos
replayed from their first state) as <out>_quality.json and in the report; a JSON line per attempt
(sources, cause, a success's figures) as <out>.attempts.jsonl; each failed attempt kept in <out>_failed.hdf5 carries its cause
as the demo attribute mimicgen_failure_cause. An existing output is never replaced without --overwrite. While running, the dataset
is <out>.partial; after a crash or kill, the same command with --resume continues it, and the
finished dataset equals an uninterrupted run's (a run killed after its dataset was finished but
before its report was written gets the report from --resume). Two-arm tasks (two_arm_lift,
two_arm_handover, two_arm_transport: robosuite's own two-arm environments) take --task, --variant, --num-demos,
--guarantee, --max-attempts, --valid-fraction, --seed, --workers, --source, --out, --overwrite and
the --rerun flags so far, and write the dataset and <out>.json. On a terminal, progress is a bar; in a log (a
batch job, stderr redirected) it is a `progress N/TOTAL: ...` line per percent of the run.")]
pub struct GenerateArgs {
    /// Task to generate (see `mimicgen tasks`). Default: what the inputs name, else stack.
    #[arg(long)]
    task: Option<String>,
    /// Task variant: the reset distribution new scenes are drawn from. Default: what the inputs
    /// name, else D0.
    #[arg(long)]
    variant: Option<String>,
    /// The arm to generate with (see `mimicgen tasks`). Default: the source demos' arm. Another
    /// arm than theirs runs in the task's scene composed with it, from the same end-effector
    /// poses (the paper's robot transfer); `env_args` names it for robosuite.
    #[arg(long, ignore_case = true, value_parser = robot_names())]
    robot: Option<String>,
    /// Attempts to make (successes to reach with --guarantee). Default: the spec's num_trials.
    #[arg(long)]
    num_demos: Option<usize>,
    /// Run seed: the same seed gives the same dataset, whatever --workers. Default: the spec's.
    #[arg(long)]
    seed: Option<u64>,
    /// Worker threads, each with its own simulator.
    #[arg(long, default_value_t = default_workers())]
    workers: usize,
    /// Output dataset.
    #[arg(long, default_value = "out/generated.hdf5")]
    out: PathBuf,
    /// Source demos (MimicGen source layout). Default: the task's bundled scripted demos.
    #[arg(long)]
    source: Option<PathBuf>,
    /// Task spec: our TOML or a MimicGen experiment JSON. Default: the task's bundled spec.
    #[arg(long)]
    config: Option<PathBuf>,
    /// Also write failed attempts (to `OUT_failed.hdf5` beside `--out`), up to the spec's max_num_failures.
    #[arg(long)]
    keep_failed: bool,
    /// Keep attempting until --num-demos successes.
    #[arg(long)]
    guarantee: bool,
    /// Hard cap on attempts with --guarantee.
    #[arg(long)]
    max_attempts: Option<usize>,
    /// Put this fraction (0 to 1) of demos, drawn at random with the run seed, in a `mask/valid`
    /// filter key (the rest in `mask/train`).
    #[arg(long)]
    valid_fraction: Option<f64>,
    /// End an attempt as soon as a subtask's segment ends without its signal (the grasp missed),
    /// instead of running the remaining subtasks first. Saves time on failures; an attempt that
    /// would have recovered by luck is lost (see BENCHMARKS.md).
    #[arg(long)]
    early_abort: bool,
    /// Replace existing outputs (dataset, failed attempts, reports, attempt log, an interrupted
    /// run's .partial).
    #[arg(long, conflicts_with = "resume")]
    overwrite: bool,
    /// Continue the interrupted run that left `<out>.partial` (same arguments; --workers may differ).
    #[arg(long)]
    resume: bool,
    /// Make only share PART of COUNT of the attempts (indices = PART modulo COUNT), e.g. on
    /// several machines; `mimicgen merge` joins the shards into the whole run's dataset, reading
    /// the attempt log (OUT.attempts.jsonl) each run writes.
    #[arg(long, value_name = "PART/COUNT")]
    shard: Option<mimicgen_engine::Shard>,
    /// Also write the actions in other forms beside robosuite's delta-pose `actions`: `abs`
    /// writes `actions_abs` (the controller's absolute target: position, axis-angle rotation,
    /// gripper; robomimic's convention, for Diffusion Policy and other absolute-action learners);
    /// `joint` writes `actions_joint` (the arm's joint positions at the next step, then the
    /// gripper). `mimicgen replay --mode actions-abs` and `--mode actions-joint` replay them.
    #[arg(long, value_enum, value_delimiter = ',', value_name = "FORM")]
    actions: Vec<ActionFormArg>,
    /// Spec fields for this run over the spec's.
    #[command(flatten)]
    spec: SpecArgs,
    /// Camera observations rendered into the dataset.
    #[command(flatten)]
    cameras: CameraArgs,
    /// Rerun: where the recording goes and how much 3D scene it holds.
    #[command(flatten)]
    rerun: crate::view::RerunArgs,
}

/// Camera observations, rendered offscreen as robosuite renders them (MuJoCo through EGL; no
/// display or GPU needed) and written under robomimic's keys (`obs/agentview_image`, uint8
/// `(T, H, W, 3)`, one gzip chunk per frame).
#[derive(Debug, Clone, Default, clap::Args)]
#[command(next_help_heading = "Camera observations")]
pub struct CameraArgs {
    /// Render these robosuite cameras into every kept demo; `--cameras` alone means
    /// agentview,robot0_eye_in_hand (robomimic's image datasets). Others: frontview, birdview,
    /// sideview. Rendering costs time (see BENCHMARKS.md); off by default.
    #[arg(long, value_name = "NAMES", num_args = 0..=1, default_missing_value = "agentview,robot0_eye_in_hand")]
    pub cameras: Option<String>,
    /// Image size: `N` for N x N, or `HxW` (height x width).
    #[arg(long, value_name = "N|HxW", default_value = "84", requires = "cameras")]
    pub camera_size: CameraSize,
    /// Also render depth (`<camera>_depth`, float32, robosuite's normalized depth buffer).
    #[arg(long, requires = "cameras")]
    pub camera_depth: bool,
    /// Render without multisampling: about 2x faster on a machine without a GPU, but edges differ
    /// from robosuite's images (see BENCHMARKS.md).
    #[arg(long, requires = "cameras")]
    pub camera_fast: bool,
    /// Mirror the scene in the floor as robosuite does (1 % reflectance): robosuite's pixels to
    /// rounding, about 3x slower without a GPU. Without it the floor differs by a few levels.
    #[arg(long, requires = "cameras")]
    pub camera_reflection: bool,
}

/// An image size on the command line: `84` or `120x160` (height x width).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct CameraSize {
    /// Rows.
    pub height: usize,
    /// Columns.
    pub width: usize,
}

impl Default for CameraSize {
    fn default() -> Self {
        Self { height: 84, width: 84 }
    }
}

impl std::str::FromStr for CameraSize {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        let parse = |v: &str| v.trim().parse::<usize>().ok().filter(|&n| n > 0);
        let size = match s.split_once(['x', 'X']) {
            Some((h, w)) => parse(h).zip(parse(w)).map(|(height, width)| Self { height, width }),
            None => parse(s).map(|n| Self { height: n, width: n }),
        };
        size.ok_or_else(|| format!("{s:?} is not an image size: give N (N x N pixels) or HxW, e.g. 84 or 120x160"))
    }
}

impl CameraArgs {
    /// The pipeline's camera settings (`None` without `--cameras`).
    #[must_use]
    pub fn config(&self) -> Option<mimicgen_sim::camera::CameraConfig> {
        let names: Vec<String> = self.cameras.as_deref()?.split(',').map(str::trim).filter(|n| !n.is_empty()).map(str::to_owned).collect();
        Some(mimicgen_sim::camera::CameraConfig {
            names,
            height: self.camera_size.height,
            width: self.camera_size.width,
            depth: self.camera_depth,
            fast: self.camera_fast,
            reflection: self.camera_reflection,
        })
    }
}

/// Spec fields set on the command line over the task spec's, for every subtask (`VALUE`) or for
/// subtask K only (`K:VALUE`); each flag may be repeated, a later value wins.
#[derive(Debug, Clone, Default, clap::Args)]
#[command(next_help_heading = "Spec fields (each: VALUE for every subtask, or K:VALUE for subtask K)")]
pub struct SpecArgs {
    /// Source selection: random, nearest_neighbor_object or nearest_neighbor_robot_distance
    /// (e.g. `--selection nearest_neighbor_object --selection 1:random`).
    #[arg(long, value_name = "[K:]STRATEGY")]
    selection: Vec<Scoped<String>>,
    /// How many nearest source demos the nearest-neighbour selection draws from.
    #[arg(long, value_name = "[K:]N")]
    nn_k: Vec<Scoped<usize>>,
    /// Standard deviation of the Gaussian noise on each action's six pose dimensions.
    #[arg(long, value_name = "[K:]STD")]
    action_noise: Vec<Scoped<f64>>,
    /// Range of steps added to a subtask's end, drawn per attempt (e.g. `--offset-range 0:10,20`).
    #[arg(long, value_name = "[K:]LO,HI", allow_hyphen_values = true)]
    offset_range: Vec<Scoped<OffsetRange>>,
    /// Intermediate poses of the interpolation segment before each transformed segment.
    #[arg(long, value_name = "[K:]N")]
    interpolation_steps: Vec<Scoped<usize>>,
    /// Steps holding the transformed segment's first pose after interpolating.
    #[arg(long, value_name = "[K:]N")]
    fixed_steps: Vec<Scoped<usize>>,
    /// Choose a source demo at every subtask (true) or once per attempt (false).
    #[arg(long, value_name = "BOOL")]
    select_src_per_subtask: Option<bool>,
    /// How the robot gets to each segment: `interpolate` (MimicGen: a straight bridge) or `plan`
    /// (SkillGen: a collision-free path planned in joint space to where the approach to the
    /// object begins; the source demo's way there is not replayed). E.g. `--transit plan` on a
    /// cluttered variant (`--task stack --variant C0`).
    #[arg(long, value_name = "[K:]interpolate|plan")]
    transit: Vec<Scoped<Transit>>,
    /// With `--transit plan`: the replayed approach begins where the gripper first comes this
    /// near (m) the subtask's object (default 0.1).
    #[arg(long, value_name = "[K:]METRES")]
    approach_m: Vec<Scoped<f64>>,
    /// Source demos no subtask selects, by index as the report counts them (e.g. `--exclude-source
    /// 2,6`: the demos the report lists under never_succeeded; `mimicgen doctor` proposes it).
    #[arg(long, value_name = "I,J,...", value_delimiter = ',')]
    exclude_source: Vec<usize>,
}

impl SpecArgs {
    /// The spec fields given, as every front end takes them.
    pub fn overrides(&self) -> SpecOverrides {
        SpecOverrides {
            selection: self.selection.clone(),
            nn_k: self.nn_k.clone(),
            action_noise: self.action_noise.clone(),
            offset_range: self.offset_range.clone(),
            interpolation_steps: self.interpolation_steps.clone(),
            fixed_steps: self.fixed_steps.clone(),
            select_src_per_subtask: self.select_src_per_subtask,
            transit: self.transit.clone(),
            approach_m: self.approach_m.clone(),
            exclude_source: self.exclude_source.clone(),
        }
    }
}

/// `--robot`'s values: every arm the simulator has (so `--help` lists them all).
fn robot_names() -> clap::builder::PossibleValuesParser {
    clap::builder::PossibleValuesParser::new(mimicgen_sim::robot::ROBOTS.iter().map(|r| r.name))
}

fn default_workers() -> usize {
    std::thread::available_parallelism().map_or(1, std::num::NonZero::get)
}

impl GenerateArgs {
    /// Whether this run renders images with a worker on every core. Without a GPU, Mesa's
    /// llvmpipe rasterizes on threads of its own, one per core: with every core already running
    /// a worker they only compete, and two workers draw 25 % more frames without them
    /// (BENCHMARKS.md, "Where a frame's time goes").
    pub fn renders_on_every_core(&self) -> bool {
        self.cameras.cameras.is_some() && self.workers >= default_workers()
    }

    fn run_config(&self) -> RunConfig {
        RunConfig {
            task: self.task.clone(),
            variant: self.variant.clone(),
            config: self.config.clone(),
            source: self.source.clone(),
            out: self.out.clone(),
            workers: self.workers,
            num_demos: self.num_demos,
            seed: self.seed,
            keep_failed: self.keep_failed,
            guarantee: self.guarantee,
            max_attempts: self.max_attempts,
            valid_fraction: self.valid_fraction,
            early_abort: self.early_abort,
            overwrite: self.overwrite,
            resume: self.resume,
            spec: self.spec.overrides(),
            shard: self.shard,
            cameras: self.cameras.config(),
            robot: self.robot.clone(),
            actions: self
                .actions
                .iter()
                .map(|a| match a {
                    ActionFormArg::Abs => mimicgen_pipeline::ActionForm::Abs,
                    ActionFormArg::Joint => mimicgen_pipeline::ActionForm::Joint,
                })
                .collect(),
        }
    }
}

/// A form of the actions `--actions` adds.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum ActionFormArg {
    /// `actions_abs`: absolute target position, axis-angle rotation, gripper.
    Abs,
    /// `actions_joint`: the arm's joint positions at the next step, gripper.
    Joint,
}

/// Runs `mimicgen generate`: the pipeline, with a progress bar and (optionally) a Rerun recording
/// as consumers of its events.
///
/// # Errors
/// Bad arguments, unreadable inputs, or a failure to write the outputs.
pub fn generate(args: &GenerateArgs) -> anyhow::Result<()> {
    if args.task.as_deref().and_then(mimicgen_sim::two_arm::TwoArmTask::from_name).is_some() {
        return generate_two_arm(args);
    }
    let pipeline = Pipeline::prepare(&args.run_config())?;
    let mut viz = args.rerun.logger("mimicgen", pipeline.scene())?;
    if let Some(v) = viz.as_mut() {
        v.log_demos(pipeline.generator().dataset().demos.iter().enumerate()).context("logging the source demos to Rerun")?;
    }
    let bar = ProgressBar::hidden();
    bar.set_style(
        ProgressStyle::with_template("{spinner} {elapsed_precise} [{bar:30}] {pos}/{len} {msg} ETA {eta}")
            .unwrap_or_else(|_| ProgressStyle::default_bar())
            .progress_chars("=> "),
    );
    let cancel = AtomicBool::new(false);
    let mut viz_error: Option<anyhow::Error> = None;
    let mut guarantee = false;
    let terminal = std::io::IsTerminal::is_terminal(&std::io::stderr());
    let (mut target, mut log_every) = (0, 1);
    let report = pipeline.run(&cancel, |event| match event {
        Event::Started(info) => {
            guarantee = info.guarantee;
            target = info.target;
            log_every = (info.target / 100).max(1);
            bar.set_draw_target(indicatif::ProgressDrawTarget::stderr());
            bar.set_length(info.target as u64);
            eprintln!(
                "generating {} {} {} of {} {} from {} source demos in {} on {} worker(s), seed {}{}",
                if info.guarantee { "until" } else { "with" },
                info.target,
                if info.guarantee { "successes" } else { "attempts" },
                info.task,
                info.variant,
                info.num_sources,
                info.source.display(),
                info.workers,
                info.seed,
                if info.resumed_from > 0 { format!(", resuming at attempt {}", info.resumed_from) } else { String::new() }
            );
        }
        Event::Attempt(a) => {
            if let Some(v) = viz.as_mut()
                && let Err(e) = v.log_attempt(&a.attempt, &a.stats)
            {
                viz_error.get_or_insert_with(|| anyhow::Error::new(e).context("logging to the Rerun recording"));
                cancel.store(true, Ordering::Relaxed);
            }
            let stats = &a.stats;
            let done = if guarantee { stats.successes } else { stats.attempts };
            bar.set_position(done as u64);
            #[allow(clippy::cast_precision_loss)]
            let message = format!(
                "{} ok / {} tried, rate {:.1}%, {:.2} demos/s",
                stats.successes,
                stats.attempts,
                100.0 * stats.rate(),
                stats.successes as f64 / a.elapsed_s.max(1e-9)
            );
            // In a log (a batch job, a pipe) a bar draws nothing: a line per percent of the run.
            if !terminal && (stats.attempts % log_every == 0 || done >= target) {
                eprintln!("progress {done}/{target}: {message}");
            }
            bar.set_message(message);
        }
        Event::Finished(_) => bar.finish_and_clear(),
    })?;
    if let Some(e) = viz_error {
        return Err(e);
    }
    if let Some(v) = viz {
        v.finish().context("flushing the Rerun recording")?;
    }
    outln!("{}", serde_json::to_string_pretty(&report)?);
    // A resumed run's time is this session's, from the attempt it resumed at.
    let session = if report.resumed_from > 0 { format!(" (this session, from attempt {})", report.resumed_from) } else { String::new() };
    eprintln!(
        "{} of {} attempts succeeded ({:.1}%) in {:.1} s{session}; dataset {}, report {}",
        report.successes,
        report.attempts,
        100.0 * report.generation_rate,
        report.wall_time_s,
        report.output,
        pipeline.report_path().display()
    );
    if !report.causes.is_empty() {
        eprintln!("why attempts failed: {}", causes_line(&report.causes));
    }
    if !report.per_object_instance.is_empty() {
        let rates: Vec<String> =
            report.per_object_instance.iter().map(|i| format!("{} {}/{}", i.instance, i.successes, i.attempts)).collect();
        eprintln!("successes per object instance: {}", rates.join(", "));
    }
    if !report.never_succeeded.is_empty() {
        let demos: Vec<String> = report.never_succeeded.iter().map(|d| format!("demo_{d}")).collect();
        eprintln!(
            "source demos in {}+ attempts and never a success: {} (per subtask: the report's per_subtask_source)",
            mimicgen_pipeline::NEVER_SUCCEEDS_MIN_USES,
            demos.join(", ")
        );
    }
    if let Some(q) = &report.quality {
        eprintln!("quality ({}): {}", mimicgen_pipeline::quality_path(&args.out).display(), quality_line(q));
    }
    let t = &report.transit;
    if !t.is_empty() {
        #[allow(clippy::cast_precision_loss)] // counts are far below 2^52
        let mean_ms = 1000.0 * t.planning_s / t.planned.max(1) as f64;
        eprintln!(
            "transit: {} planned ({} found no path), {mean_ms:.1} ms each on average; obstacles touched in {} of {} attempts",
            t.planned, t.no_path, t.obstacle_attempts, report.attempts
        );
    }
    Ok(())
}

/// A report's failure causes in a line, by subtask, most frequent first:
/// `subtask 1: grasp missed 30, object moved 3; subtask 2: success unmet 7`.
fn causes_line(causes: &[mimicgen_pipeline::CauseReport]) -> String {
    let mut by_subtask: std::collections::BTreeMap<usize, Vec<(usize, String)>> = std::collections::BTreeMap::new();
    for c in causes {
        by_subtask.entry(c.subtask).or_default().push((c.count, c.cause.replace('_', " ")));
    }
    by_subtask
        .into_iter()
        .map(|(subtask, mut counts)| {
            counts.sort_by(|a, b| b.0.cmp(&a.0).then_with(|| a.1.cmp(&b.1)));
            let counts: Vec<String> = counts.into_iter().map(|(n, cause)| format!("{cause} {n}")).collect();
            format!("subtask {subtask}: {}", counts.join(", "))
        })
        .collect::<Vec<_>>()
        .join("; ")
}

/// A dataset's quality report in a line: the largest stitch jump and where, the pose actions at
/// their limits, coverage, the replay sample.
fn quality_line(q: &mimicgen_pipeline::DatasetQuality) -> String {
    let mut parts = Vec::new();
    if let Some(s) = q.quality.stitches.iter().max_by(|a, b| a.jump_m_max.total_cmp(&b.jump_m_max)) {
        let at = match s.at {
            mimicgen_engine::quality::StitchAt::InterpolationStart => "interpolation start",
            mimicgen_engine::quality::StitchAt::InterpolationEnd => "interpolation end",
        };
        parts.push(format!(
            "largest stitch jump {:.1} cm (subtask {} {at}; p95 {:.1} cm, steps there p95 {:.1} cm)",
            100.0 * s.jump_m_max,
            s.subtask,
            100.0 * s.jump_m_p95,
            100.0 * s.step_m_p95
        ));
    }
    let a = &q.quality.actions;
    if a.steps > 0 {
        #[allow(clippy::cast_precision_loss)] // step counts
        let share = 100.0 * a.saturated_steps as f64 / a.steps as f64;
        parts.push(format!("pose actions at their limit in {share:.1} % of steps"));
    }
    if let Some(c) = &q.coverage {
        parts.push(format!(
            "support coverage {:.1} % (as many uniform scenes: {:.1} %)",
            100.0 * c.support_coverage,
            100.0 * c.uniform_support_coverage
        ));
    }
    match &q.replay {
        Some(r) if r.error.is_some() => {
            parts.push(format!("the written demos could not be replayed: {}", r.error.as_deref().unwrap_or_default()));
        }
        Some(r) => parts.push(format!("{} of {} demos replay to success", r.succeeded, r.demos.len())),
        None => {}
    }
    parts.join("; ")
}

/// `mimicgen generate` for a two-arm task: the flags the two-arm run takes, the others refused.
/// A two-arm task's run (`TwoArmRun::from_config` refuses by name the flags it lacks).
fn generate_two_arm(args: &GenerateArgs) -> anyhow::Result<()> {
    let run = mimicgen_pipeline::two_arm::TwoArmRun::from_config(&args.run_config())?;
    crate::check_output(&args.out, args.source.as_deref(), args.overwrite)?;
    crate::two_arm::generate(&run, &args.rerun)
}

#[cfg(test)]
mod tests {
    use clap::{CommandFactory as _, Parser as _};
    use mimicgen_pipeline::CameraConfig;

    use super::*;

    #[derive(clap::Parser)]
    struct Generate {
        #[command(flatten)]
        args: GenerateArgs,
    }

    #[derive(clap::Parser)]
    struct Rerun {
        #[command(flatten)]
        args: crate::view::RerunArgs,
    }

    #[test]
    fn causes_read_by_subtask_most_frequent_first() {
        let cause = |subtask, cause: &str, count| mimicgen_pipeline::CauseReport { subtask, cause: cause.to_owned(), count };
        let line = causes_line(&[cause(2, "success_unmet", 7), cause(1, "object_moved", 3), cause(1, "grasp_missed", 30)]);
        assert_eq!(line, "subtask 1: grasp missed 30, object moved 3; subtask 2: success unmet 7");
    }

    /// A run with every field away from its default.
    fn every_field() -> RunConfig {
        RunConfig {
            task: Some("square".into()),
            variant: Some("D1".into()),
            config: Some("my spec.toml".into()),
            source: Some("sources.hdf5".into()),
            out: "runs/out.hdf5".into(),
            workers: 3,
            num_demos: Some(7),
            seed: Some(9),
            keep_failed: true,
            guarantee: true,
            max_attempts: Some(70),
            valid_fraction: Some(0.25),
            early_abort: true,
            overwrite: true,
            resume: false,
            spec: SpecOverrides {
                action_noise: vec![Scoped::all(0.02)],
                nn_k: vec![Scoped { subtask: Some(1), value: 4 }],
                exclude_source: vec![2, 6],
                ..SpecOverrides::default()
            },
            shard: Some(mimicgen_engine::Shard { part: 1, count: 4 }),
            cameras: Some(CameraConfig {
                names: vec!["agentview".into()],
                height: 120,
                width: 160,
                depth: true,
                fast: true,
                reflection: true,
            }),
            robot: Some("ur5e".into()),
            actions: vec![mimicgen_pipeline::ActionForm::Abs],
        }
    }

    #[test]
    fn the_cli_and_the_run_description_have_the_same_fields() {
        // Written as flags and parsed back, a run is the same run (`--resume` conflicts with
        // `--overwrite`, so it is checked on its own).
        for config in [every_field(), RunConfig { resume: true, overwrite: false, ..every_field() }] {
            let args = config.to_args();
            let parsed = Generate::try_parse_from(std::iter::once("generate".to_owned()).chain(args.clone()))
                .unwrap_or_else(|e| panic!("{args:?}: {e}"));
            assert_eq!(parsed.args.run_config(), config, "{args:?}");
        }
        // Every flag of `generate` but Rerun's is a field of the run description.
        let rerun: Vec<String> = Rerun::command().get_arguments().filter_map(|a| a.get_long().map(str::to_owned)).collect();
        let written = [every_field().to_args(), RunConfig { resume: true, ..RunConfig::default() }.to_args()].concat();
        for arg in Generate::command().get_arguments() {
            let Some(long) = arg.get_long() else { continue };
            if rerun.iter().any(|r| r == long) {
                continue;
            }
            let flag = format!("--{long}");
            let covered = written.contains(&flag) || SpecOverrides::FIELDS.iter().any(|f| f.replace('_', "-") == long);
            assert!(covered, "{flag} is not a field of RunConfig (or RunConfig::to_args does not write it)");
        }
    }

    #[test]
    fn robot_help_lists_every_arm() {
        let help = Generate::command().render_long_help().to_string();
        for robot in mimicgen_sim::robot::ROBOTS {
            assert!(help.contains(robot.name), "--robot's help lacks {}", robot.name);
        }
    }
}
