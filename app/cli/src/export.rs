//! `mimicgen export`: a dataset to MCAP (Foxglove) or to a LeRobot dataset.

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use mimicgen_io::{DemoReader, DemoSource as _, ReadOptions};

use crate::check_output;
use crate::exit::outln;

/// `mimicgen export`'s arguments.
#[derive(Debug, clap::Args)]
pub struct ExportArgs {
    /// The dataset.
    pub file: PathBuf,
    /// Output MCAP file.
    #[arg(long, required_unless_present = "lerobot")]
    pub mcap: Option<PathBuf>,
    /// Output LeRobot dataset directory (format v3.0).
    #[arg(long)]
    pub lerobot: Option<PathBuf>,
    /// LeRobot: observation keys concatenated into `observation.state`, in order.
    #[arg(long, value_delimiter = ',', default_value = "robot0_eef_pos,robot0_eef_quat,robot0_gripper_qpos,object")]
    pub state_keys: Vec<String>,
    /// LeRobot: the task instruction of every frame. Default: the task's, from env_args.
    #[arg(long)]
    pub instruction: Option<String>,
    /// LeRobot: the ffmpeg that encodes camera streams. Default: $MIMICGEN_FFMPEG, else the
    /// one scripts/setup.sh unpacked into the cache, else `ffmpeg` on the PATH.
    #[arg(long)]
    pub ffmpeg: Option<PathBuf>,
    /// Replace an existing output (the MCAP file, the LeRobot directory).
    #[arg(long)]
    pub overwrite: bool,
    /// LeRobot: then upload the dataset to the Hugging Face Hub as the dataset repository REPO
    /// (`user/name`), as LeRobot's own push_to_hub does: huggingface_hub's
    /// `HfApi().create_repo(REPO, repo_type="dataset", exist_ok=True)`, `upload_folder(...)` of
    /// the directory, and `create_tag(REPO, tag="v3.0")`, the version tag LeRobot's loader asks
    /// for. Runs $MIMICGEN_PYTHON (else python3), which needs huggingface_hub and a token
    /// (`hf auth login`). `file:///some/dir` copies the files into that directory instead, as
    /// the repository would hold them (no network needed).
    #[arg(long, requires = "lerobot", value_name = "REPO")]
    pub push: Option<String>,
}

/// What `--push` runs in Python for a Hub repository: LeRobot's push_to_hub, in three calls.
const PUSH_SCRIPT: &str = r#"
import sys
from huggingface_hub import HfApi
repo, folder, tag = sys.argv[1:4]
api = HfApi()
api.create_repo(repo, repo_type="dataset", exist_ok=True)
api.upload_folder(repo_id=repo, folder_path=folder, repo_type="dataset")
api.create_tag(repo, tag=tag, repo_type="dataset", exist_ok=True)
print(f"https://huggingface.co/datasets/{repo} (tag {tag})")
"#;

/// Refuses a `--push` target that cannot take the dataset, before anything is exported.
fn check_push_target(repo: &str) -> anyhow::Result<()> {
    if let Some(local) = repo.strip_prefix("file://") {
        let local = Path::new(local);
        if local.exists() && std::fs::read_dir(local).map(|mut d| d.next().is_some()).unwrap_or(true) {
            anyhow::bail!("--push {repo}: {} is not empty; push into a new or empty directory", local.display());
        }
    } else if repo.split('/').count() != 2 || repo.split('/').any(str::is_empty) {
        anyhow::bail!("--push {repo}: a Hub dataset repository is `user/name` (or file:///dir for a local copy)");
    }
    Ok(())
}

/// Uploads the LeRobot dataset `dir` to `repo` (see [`ExportArgs::push`], checked by
/// [`check_push_target`] before the export); returns where it went.
fn push(dir: &Path, repo: &str) -> anyhow::Result<String> {
    if let Some(local) = repo.strip_prefix("file://") {
        let local = Path::new(local);
        copy_tree(dir, local).map_err(|e| anyhow::anyhow!("--push {repo}: copying {} there: {e}", dir.display()))?;
        return Ok(format!("{} (a local copy; on the Hub it would be tagged {})", local.display(), mimicgen_io::lerobot::CODEBASE_VERSION));
    }
    let python = std::env::var_os("MIMICGEN_PYTHON").unwrap_or_else(|| "python3".into());
    let out = std::process::Command::new(&python)
        .args(["-c", PUSH_SCRIPT, repo])
        .arg(dir)
        .arg(mimicgen_io::lerobot::CODEBASE_VERSION)
        .output()
        .map_err(|e| {
            anyhow::anyhow!(
                "--push {repo}: cannot run {} ({e}); set MIMICGEN_PYTHON to a Python with huggingface_hub",
                python.to_string_lossy()
            )
        })?;
    if !out.status.success() {
        let err = String::from_utf8_lossy(&out.stderr);
        let last = err.lines().rev().find(|l| !l.trim().is_empty()).unwrap_or("no message");
        anyhow::bail!("--push {repo}: the upload failed ({}): {last}", out.status);
    }
    Ok(String::from_utf8_lossy(&out.stdout).trim().to_owned())
}

/// Copies the directory `from` to `to` (files and folders; `to` made as needed).
fn copy_tree(from: &Path, to: &Path) -> std::io::Result<()> {
    std::fs::create_dir_all(to)?;
    for entry in std::fs::read_dir(from)? {
        let entry = entry?;
        let target = to.join(entry.file_name());
        if entry.file_type()?.is_dir() {
            copy_tree(&entry.path(), &target)?;
        } else {
            std::fs::copy(entry.path(), target)?;
        }
    }
    Ok(())
}

/// Runs `mimicgen export`.
///
/// # Errors
/// What the command reports (each names the file and field).
pub fn run(args: ExportArgs) -> anyhow::Result<ExitCode> {
    let ExportArgs { file, mcap, lerobot, state_keys, instruction, ffmpeg, overwrite, push: push_to } = args;

    if let Some(repo) = &push_to {
        check_push_target(repo)?;
    }
    let ds = DemoReader::open_with(&file, ReadOptions::default())?;
    if let Some(mcap) = mcap {
        check_output(&mcap, Some(&file), overwrite)?;
        let summary = mimicgen_io::mcap_export::export(&ds, &mcap)?;
        outln!("{}: {} demos, {} steps at 20 Hz", mcap.display(), summary.demos, summary.steps);
        for (topic, n) in &summary.messages {
            outln!("  {topic:<24} {n} messages");
        }
    }
    if let Some(out) = lerobot {
        let request = mimicgen_pipeline::lerobot::ExportRequest { state_keys: Some(state_keys), instruction, ffmpeg, overwrite };
        let bar = indicatif::ProgressBar::new(ds.demo_names().len() as u64).with_style(
            indicatif::ProgressStyle::with_template("exporting {bar:30} {pos}/{len} episodes, {elapsed} ({eta} left)")
                .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
        );
        drop(ds);
        let summary = mimicgen_pipeline::lerobot::export(&file, &out, &request, |done, _| bar.set_position(done as u64))?;
        bar.finish_and_clear();
        outln!(
            "{}: LeRobot {} dataset, {} episodes, {} frames at 20 fps",
            summary.out,
            mimicgen_io::lerobot::CODEBASE_VERSION,
            summary.episodes,
            summary.frames
        );
        let state: Vec<String> = summary.state.iter().map(|(k, n)| format!("{k} ({n})")).collect();
        outln!("  observation.state: {}", state.join(" + "));
        outln!("  task: {:?}", summary.task);
        for video in &summary.videos {
            outln!("  {video}: H.264 video");
        }
        for (i, subtask) in summary.subtasks.iter().enumerate() {
            outln!("  subtask_index {i}: {subtask:?}");
        }
        outln!("  dataset card: {}", out.join("README.md").display());
        if let Some(repo) = push_to {
            outln!("pushed: {}", push(&out, &repo)?);
        }
    }
    Ok(ExitCode::SUCCESS)
}
