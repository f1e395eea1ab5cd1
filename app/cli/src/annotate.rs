//! `mimicgen annotate`: subtask ends for source demos, proposed from the recording or typed by
//! hand, written where MimicGen reads them.

use std::collections::BTreeMap;
use std::path::PathBuf;

use mimicgen_pipeline::annotate;

use crate::exit::outln;

/// Arguments of `mimicgen annotate`.
#[derive(clap::Args, Debug)]
#[command(after_help = "\
Examples:
  mimicgen annotate sources.hdf5 --auto --out annotated.hdf5                 # propose every end
  mimicgen annotate sources.hdf5 --ends demo_0=52 --ends demo_3=60 --auto --out annotated.hdf5
  mimicgen annotate sources.hdf5 --auto                                      # just print the proposals
  mimicgen annotate core/io/tests/data/source_D0_prepared.hdf5 --auto --json  # compare with the stored signals
  mimicgen annotate sources.hdf5 --starts demo_0=1:90 --out marked.hdf5     # where demo_0's place begins

A subtask end is the last step of the subtask, as MimicGen's annotation script marks it: the
subtask's signal is written 0 before that step and 1 from it on, into
data/<demo>/datagen_info/subtask_term_signals/<term_signal of the spec>, replacing the demo's
signals as the reference does. --auto proposes the ends from the gripper commands, the finger
opening and where the gripper is (no privileged signals), each with a confidence and a reason;
a demo given with --ends keeps what you typed. The task and spec come from --task/--config, else
from the file's env_args and the bundled spec. Without --out nothing is written.

--starts marks where a subtask's segment begins (`DEMO=K:STEP,...`, K the subtask): with planned
transit (`generate --transit plan`) that segment is replayed from there and the robot gets there by
a collision-free path; unmarked subtasks start where the gripper first comes `approach_m` near the
object. Starts go in the demo's `mimicgen_subtask_starts` attribute (-1 where unmarked), which the
reference ignores.

A two-arm file (Two Arm Lift, Two Arm Handover) gets each arm's proposals; with --auto --out they
are written as each arm's signals (the app edits them arm by arm).")]
pub struct AnnotateArgs {
    /// Source demos (MimicGen source layout, with datagen_info).
    file: PathBuf,
    /// Propose the ends of every demo not given with --ends.
    #[arg(long)]
    auto: bool,
    /// `DEMO=S1,S2,...`: the last step of each subtask but the final one, for one demo.
    #[arg(long, value_name = "DEMO=STEPS")]
    ends: Vec<String>,
    /// `DEMO=K:STEP,...`: the step where subtask K's segment begins, for one demo (planned
    /// transit replays the segment from there).
    #[arg(long, value_name = "DEMO=K:STEP")]
    starts: Vec<String>,
    /// Task (see `mimicgen tasks`). Default: the file's env_args.
    #[arg(long)]
    task: Option<String>,
    /// Task spec (TOML or MimicGen JSON) whose subtasks and signal names are annotated.
    #[arg(long)]
    config: Option<PathBuf>,
    /// Write the annotated file here (a new file; the input is never changed).
    #[arg(long)]
    out: Option<PathBuf>,
    /// Replace --out if it exists.
    #[arg(long)]
    overwrite: bool,
    /// Print JSON (proposals, stored-signal ends and the distance summary).
    #[arg(long)]
    json: bool,
}

fn parse_ends(specs: &[String]) -> anyhow::Result<BTreeMap<String, Vec<usize>>> {
    let mut out = BTreeMap::new();
    for spec in specs {
        let Some((demo, steps)) = spec.split_once('=') else {
            crate::exit::usage!("--ends {spec:?}: expected DEMO=S1,S2,...");
        };
        let steps: Vec<usize> = steps
            .split(',')
            .map(|s| s.trim().parse::<usize>().map_err(|_| crate::exit::Usage(format!("--ends {spec:?}: {s:?} is not a step"))))
            .collect::<Result<_, _>>()?;
        // MimicGen marks the last step of a subtask; the engine's ends are exclusive.
        out.insert(demo.trim().to_owned(), steps.into_iter().map(|s| s + 1).collect());
    }
    Ok(out)
}

/// `--starts` as a start per subtask (`None` where unmarked) for each demo named.
fn parse_starts(specs: &[String], subtasks: usize) -> anyhow::Result<BTreeMap<String, Vec<Option<usize>>>> {
    let mut out: BTreeMap<String, Vec<Option<usize>>> = BTreeMap::new();
    for spec in specs {
        let Some((demo, marks)) = spec.split_once('=') else {
            crate::exit::usage!("--starts {spec:?}: expected DEMO=K:STEP,...");
        };
        let starts = out.entry(demo.trim().to_owned()).or_insert_with(|| vec![None; subtasks]);
        for mark in marks.split(',') {
            let parsed = mark.split_once(':').and_then(|(k, s)| Some((k.trim().parse::<usize>().ok()?, s.trim().parse::<usize>().ok()?)));
            let Some((k, step)) = parsed else {
                crate::exit::usage!("--starts {spec:?}: {mark:?} is not SUBTASK:STEP");
            };
            let Some(slot) = starts.get_mut(k) else {
                crate::exit::usage!("--starts {spec:?}: subtask {k}, but the task has {subtasks} (0 to {})", subtasks.saturating_sub(1));
            };
            *slot = Some(step);
        }
    }
    Ok(out)
}

/// Runs `mimicgen annotate`.
///
/// # Errors
/// Unreadable input, bad --ends, or a failure to write.
pub fn run(args: &AnnotateArgs) -> anyhow::Result<()> {
    if !args.auto && args.ends.is_empty() && args.starts.is_empty() {
        crate::exit::usage!("nothing to do: pass --auto, --ends DEMO=S1,S2,... or --starts DEMO=K:STEP (see --help)");
    }
    if let Some(out) = &args.out {
        crate::check_output(out, Some(&args.file), args.overwrite)?;
    }
    let two_arm = match args.task.as_deref() {
        Some(name) => mimicgen_sim::two_arm::TwoArmTask::from_name(name),
        // Only the file's attributes are read here (a large one-arm file is read once, below).
        None => mimicgen_io::DemoReader::open_with(&args.file, mimicgen_io::ReadOptions::default()).ok().and_then(|reader| {
            use mimicgen_io::DemoSource as _;
            reader.env_args_json().and_then(mimicgen_sim::two_arm::TwoArmTask::from_env_args)
        }),
    };
    if let Some(task) = two_arm {
        return run_two_arm(args, task);
    }
    let mut ends = parse_ends(&args.ends)?;
    let found = annotate::propose(&args.file, args.task.as_deref(), args.config.as_deref())?;
    for demo in &found.demos {
        let typed = ends.get(&demo.demo).cloned();
        if typed.is_none() && args.auto {
            ends.insert(demo.demo.clone(), demo.proposals.iter().map(|p| p.end).collect());
        }
        if !args.json {
            outln!("{} ({} steps){}", demo.demo, demo.len, if typed.is_some() { ": ends typed with --ends" } else { "" });
            print_proposals(demo, "  ")?;
        }
    }
    let mut distances = found.distances();
    distances.sort_unstable();
    #[allow(clippy::cast_precision_loss)]
    let summary = (!distances.is_empty()).then(|| {
        let at = |q: f64| distances.get(((distances.len() - 1) as f64 * q).round() as usize).copied().unwrap_or_default();
        serde_json::json!({
            "boundaries": distances.len(),
            "median_steps": at(0.5),
            "p90_steps": at(0.9),
            "worst_steps": distances.last().copied().unwrap_or_default(),
            "within_5_steps": distances.iter().filter(|&&d| d <= 5).count() as f64 / distances.len() as f64,
        })
    });
    if args.json {
        outln!("{}", serde_json::to_string_pretty(&serde_json::json!({"demos": found.demos, "distance_to_stored_signals": summary}))?);
    } else if let Some(s) = &summary {
        outln!(
            "against the stored signals: {} boundaries, median {} steps off, 90th percentile {}, worst {}, {:.0} % within 5 steps",
            s["boundaries"],
            s["median_steps"],
            s["p90_steps"],
            s["worst_steps"],
            100.0 * s["within_5_steps"].as_f64().unwrap_or_default()
        );
    }
    let starts = parse_starts(&args.starts, found.spec.subtasks.len())?;
    if let Some(out) = &args.out {
        annotate::write_annotations(&args.file, out, &found.spec, &ends, &starts)?;
        eprintln!("wrote {} with the subtask ends of {} demo(s) and the segment starts of {}", out.display(), ends.len(), starts.len());
    }
    Ok(())
}

/// `mimicgen annotate` of a two-arm file: each arm's proposals (and stored ends), and with
/// `--auto --out` every arm's proposals written as its signals.
fn run_two_arm(args: &AnnotateArgs, task: mimicgen_sim::two_arm::TwoArmTask) -> anyhow::Result<()> {
    if !args.ends.is_empty() || !args.starts.is_empty() || args.config.is_some() {
        crate::exit::usage!(
            "{}: a two-arm file ({}): --ends, --starts and --config are one-arm only so far; --auto proposes each arm's ends (the app edits them arm by arm)",
            args.file.display(),
            task.name()
        );
    }
    let (arms, _) = annotate::propose_two_arm(&args.file, task)?;
    let mut report = Vec::new();
    for arm in &arms {
        if !args.json {
            outln!("arm {}:", arm.name);
        }
        for (_, demo) in &arm.demos {
            if !args.json {
                outln!("  {} ({} steps)", demo.demo, demo.len);
                print_proposals(demo, "    ")?;
            }
            report.push(serde_json::json!({"arm": arm.name, "demo": demo.demo, "proposals": demo.proposals.iter().map(|p| p.end).collect::<Vec<_>>(), "stored": demo.signal_ends}));
        }
    }
    if args.json {
        outln!("{}", serde_json::to_string_pretty(&report)?);
    }
    if let Some(out) = &args.out {
        if !args.auto {
            crate::exit::usage!("--out needs --auto for a two-arm file (the proposals are what is written)");
        }
        let ends: Vec<annotate::ArmEnds> = arms
            .iter()
            .map(|arm| {
                let last = arm.spec.subtasks.len().saturating_sub(1);
                let names = arm.spec.subtasks.iter().take(last).map(|s| s.term_signal.clone().unwrap_or_default()).collect();
                (names, arm.demos.iter().map(|(_, d)| (d.demo.clone(), d.proposals.iter().map(|p| p.end).collect())).collect())
            })
            .collect();
        annotate::write_arm_signals(&args.file, out, &ends)?;
        eprintln!("wrote both arms' proposed ends to {}", out.display());
    }
    Ok(())
}

/// One line per proposed subtask end of `demo` (with the stored signal's end), indented by
/// `indent`.
fn print_proposals(demo: &annotate::DemoAnnotation, indent: &str) -> anyhow::Result<()> {
    for (i, p) in demo.proposals.iter().enumerate() {
        let stored = demo.signal_ends.as_ref().and_then(|e| e.get(i));
        outln!(
            "{indent}subtask {} ends at step {} (confidence {:.1}){}: {}",
            p.subtask,
            p.end - 1,
            p.confidence,
            stored.map_or_else(String::new, |&e| format!(", stored signal: step {}", e - 1)),
            p.reason
        );
    }
    Ok(())
}
