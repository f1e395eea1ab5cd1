//! `mimicgen export --lerobot`: a dataset as a LeRobot dataset, with the defaults the CLI, the app
//! and Python share (the task's instruction from `env_args`, robomimic's low-dim state, the
//! ffmpeg `scripts/setup.sh` installs), each frame labelled with its subtask (the run's spec, else
//! the task's bundled one), and a dataset card (`README.md`: the generation settings, the rates
//! and the quality figures of the run's report). The format itself is `mimicgen_io::lerobot`.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use mimicgen_engine::TaskSpec;
use mimicgen_io::lerobot::{DEFAULT_STATE_KEYS, LeRobotOptions, LeRobotSummary, SubtaskLabel};
use mimicgen_io::{DemoReader, DemoSource as _, ReadOptions};
use mimicgen_sim::registry;

use crate::{PipelineError, RUN_ATTR, Report, sibling};

/// What to export; `None` fields take the defaults.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct ExportRequest {
    /// Observation keys concatenated into `observation.state` (default [`DEFAULT_STATE_KEYS`]).
    pub state_keys: Option<Vec<String>>,
    /// The instruction (default: the task's, from the file's `env_args`).
    pub instruction: Option<String>,
    /// The ffmpeg to encode cameras with (default [`LeRobotOptions::default_ffmpeg`]).
    pub ffmpeg: Option<PathBuf>,
    /// Replace an existing output.
    pub overwrite: bool,
}

/// Exports `file` as the LeRobot dataset `out`; `on_episode(done, total)` after each episode.
///
/// Frames carry `subtask_index` when the demos carry their subtask signals
/// (`datagen_info/subtask_term_signals`) and the task's subtasks are known: from the spec the
/// run stored in the file, else the task's bundled spec.
///
/// # Errors
/// [`PipelineError::Io`] for unreadable input, a missing state key, an existing output, or a
/// failed write or encode.
pub fn export(
    file: &Path,
    out: &Path,
    request: &ExportRequest,
    on_episode: impl FnMut(usize, usize),
) -> Result<LeRobotSummary, PipelineError> {
    let reader = DemoReader::open_with(file, ReadOptions::default())?;
    let task = registry::task_from_env_args(reader.env_args_json()).ok();
    let task_name = task.as_ref().map(|(task, _)| task.name().to_owned());
    let instruction =
        request.instruction.clone().unwrap_or_else(|| task_name.as_deref().map_or_else(|| "do the task".to_owned(), registry::instruction));
    let spec = run_spec(file).or_else(|| task_name.as_deref().and_then(|t| crate::bundled::spec(t).ok()));
    let first = reader.demo_names().first().map(|name| reader.load_demo(name)).transpose()?;
    let has_signals = first.is_some_and(|demo| demo.group("datagen_info").and_then(|i| i.group("subtask_term_signals")).is_some());
    let subtasks = spec.as_ref().filter(|_| has_signals).map(subtask_labels).unwrap_or_default();
    let report = read_report(file);
    let options = LeRobotOptions {
        state_keys: request.state_keys.clone().unwrap_or_else(|| DEFAULT_STATE_KEYS.map(str::to_owned).to_vec()),
        fps: 20,
        card: Some(card(&CardFacts {
            file,
            task: task.as_ref().map(|(t, variant)| (t.name(), variant.as_str())),
            instruction: &instruction,
            demos: reader.demo_names().len(),
            spec: spec.as_ref(),
            subtasks: &subtasks,
            report: report.as_ref(),
        })),
        task: instruction,
        robot_type: "panda".to_owned(),
        ffmpeg: request.ffmpeg.clone().unwrap_or_else(LeRobotOptions::default_ffmpeg),
        overwrite: request.overwrite,
        subtasks,
    };
    Ok(mimicgen_io::lerobot::export_lerobot(&reader, out, &options, on_episode)?)
}

/// The spec a run stored in its dataset (`mimicgen generate` writes it as [`RUN_ATTR`]).
fn run_spec(file: &Path) -> Option<TaskSpec> {
    let description = mimicgen_io::root_string_attrs(file, &[RUN_ATTR]).ok()?.into_iter().next().flatten()?;
    let value: serde_json::Value = serde_json::from_str(&description).ok()?;
    serde_json::from_value(value.get("spec")?.clone()).ok()
}

/// The run's report beside the dataset (`<stem>.json`), when it is there and reads as one.
fn read_report(file: &Path) -> Option<Report> {
    serde_json::from_str(&std::fs::read_to_string(sibling(file, "", "json")).ok()?).ok()
}

/// A subtask's text: its object and the event that ends it (`cubeA until grasp`).
fn subtask_labels(spec: &TaskSpec) -> Vec<SubtaskLabel> {
    let last = spec.subtasks.len().saturating_sub(1);
    spec.subtasks
        .iter()
        .enumerate()
        .map(|(i, s)| {
            let object = s.object_ref.as_deref().unwrap_or("world");
            let end_signal = if i == last { None } else { s.term_signal.clone() };
            let until = end_signal.as_deref().unwrap_or("the task succeeds");
            SubtaskLabel { name: format!("{object} until {until}"), end_signal }
        })
        .collect()
}

/// What the dataset card says.
struct CardFacts<'a> {
    file: &'a Path,
    task: Option<(&'a str, &'a str)>,
    instruction: &'a str,
    demos: usize,
    spec: Option<&'a TaskSpec>,
    subtasks: &'a [SubtaskLabel],
    report: Option<&'a Report>,
}

/// The dataset card: Hugging Face's front matter (so the Hub lists it under robotics and LeRobot),
/// then the generation settings, rates and quality figures, and how to load it.
fn card(facts: &CardFacts<'_>) -> String {
    let (task, variant) = facts.task.unwrap_or(("unknown task", ""));
    let file_name = facts.file.file_name().map_or_else(|| facts.file.display().to_string(), |n| n.to_string_lossy().into_owned());
    let mut s = String::new();
    let _ = writeln!(s, "---\ntask_categories:\n- robotics\ntags:\n- LeRobot\n- mimicgen-rs\n- MimicGen\n- {task}");
    let _ = writeln!(s, "configs:\n- config_name: default\n  data_files: data/*/*.parquet\n---\n");
    let _ = writeln!(s, "# {task} {variant}: {} demos generated by mimicgen-rs\n", facts.demos);
    let _ = writeln!(s, "Instruction (every frame's `task`): \"{}\".\n", facts.instruction);
    let _ = writeln!(
        s,
        "Exported by mimicgen-rs {} from `{file_name}`, a robomimic dataset generated with MimicGen's method \
         (Mandlekar et al., CoRL 2023): source demos split into object-centric subtask segments, each \
         transformed to the new scene's object pose, executed as delta-pose actions, kept when the task succeeds.\n",
        env!("CARGO_PKG_VERSION")
    );
    if let Some(r) = facts.report {
        let _ = writeln!(s, "## Generation\n\n| setting | value |\n|---|---|");
        let _ = writeln!(s, "| task, variant | {} {} |", r.task, r.variant);
        let _ = writeln!(s, "| arm | {} |", r.robot.as_deref().unwrap_or("Panda (the source demos')"));
        let source = Path::new(&r.source).file_name().map_or_else(|| r.source.clone(), |n| n.to_string_lossy().into_owned());
        let _ = writeln!(s, "| source demos | `{source}` |");
        let _ = writeln!(
            s,
            "| spec | {} |",
            r.config.as_deref().map_or_else(|| "the task's bundled spec (the paper's settings)".to_owned(), |c| format!("`{c}`"))
        );
        let _ = writeln!(s, "| seed | {} |", r.seed);
        let _ = writeln!(s, "\n## Rates\n\n| attempts | successes | generation rate |\n|---|---|---|");
        let _ = writeln!(s, "| {} | {} | {:.1} % |", r.attempts, r.successes, 100.0 * r.generation_rate);
        if !r.causes.is_empty() {
            let _ = writeln!(s, "\nFailures by subtask and cause:\n\n| subtask | cause | attempts |\n|---|---|---|");
            for c in &r.causes {
                let _ = writeln!(s, "| {} | {} | {} |", c.subtask + 1, c.cause, c.count);
            }
        }
        if let Some(q) = &r.quality {
            let a = &q.quality.actions;
            let _ = writeln!(s, "\n## Quality\n\nOver the {} successful attempts of the run:\n", q.quality.attempts);
            let _ = writeln!(s, "- pose actions at the controller's limit: {} of {} steps", a.saturated_steps, a.steps);
            for st in &q.quality.stitches {
                let at = match st.at {
                    mimicgen_engine::quality::StitchAt::InterpolationStart => "where its bridge starts",
                    mimicgen_engine::quality::StitchAt::InterpolationEnd => "where its transformed segment starts",
                };
                let _ = writeln!(
                    s,
                    "- subtask {} {at}: commanded jump p95 {:.1} mm (max {:.1} mm), {:.1} deg (max {:.1} deg)",
                    st.subtask + 1,
                    1000.0 * st.jump_m_p95,
                    1000.0 * st.jump_m_max,
                    st.jump_deg_p95,
                    st.jump_deg_max
                );
            }
            if let Some(c) = &q.coverage {
                let _ = writeln!(
                    s,
                    "- support coverage of the initial object poses: {:.1} % ({:.1} % for as many uniform scenes; {} bins per coordinate)",
                    100.0 * c.support_coverage,
                    100.0 * c.uniform_support_coverage,
                    c.bins
                );
            }
            if let Some(replay) = &q.replay {
                let _ = writeln!(
                    s,
                    "- replayed from their first state with their actions: {} of {} succeed again",
                    replay.succeeded,
                    replay.demos.len()
                );
            }
        }
    }
    if let Some(spec) = facts.spec {
        let _ = writeln!(
            s,
            "\n## Subtasks\n\n| subtask_index | text | object | selection | action noise | interpolation steps |\n|---|---|---|---|---|---|"
        );
        for (i, st) in spec.subtasks.iter().enumerate() {
            let text = facts.subtasks.get(i).map_or("(not labelled)", |l| l.name.as_str());
            let _ = writeln!(
                s,
                "| {i} | {text} | {} | {} | {} | {} |",
                st.object_ref.as_deref().unwrap_or("world"),
                st.selection.name(),
                st.action_noise,
                st.num_interpolation_steps
            );
        }
    }
    let _ = writeln!(
        s,
        "\n## Load it\n\n```python\nfrom lerobot.datasets.lerobot_dataset import LeRobotDataset\n\n\
         dataset = LeRobotDataset(\"REPO_ID\", root=\"PATH/TO/THIS/FOLDER\")\nframe = dataset[0]\n\
         print(frame[\"task\"], frame.get(\"subtask\"), frame[\"observation.state\"].shape, frame[\"action\"].shape)\n```"
    );
    s
}
