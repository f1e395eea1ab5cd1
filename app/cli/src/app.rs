//! `mimicgen app`: the inspection app in a desktop window.

use std::path::PathBuf;

use crate::generate;

/// `mimicgen app`'s arguments.
#[derive(Debug, clap::Args)]
pub struct AppArgs {
    /// Source demos to open (default: the bundled Stack D0 demos).
    file: Option<PathBuf>,
    /// Screen to show once the file is open.
    #[arg(long, value_enum, default_value = "annotate")]
    screen: ScreenArg,
    /// Demo to show (index in the file).
    #[arg(long)]
    demo: Option<usize>,
    /// Step to put the time cursor at.
    #[arg(long)]
    step: Option<usize>,
    /// Try the previewed attempt in simulation once the preview is shown.
    #[arg(long)]
    try_it: bool,
    /// Start a run of this many attempts on the generate screen (to out/app_run.hdf5, replaced).
    #[arg(long, value_name = "ATTEMPTS")]
    run: Option<usize>,
    /// The task variant the preview and --run draw scenes from (see `mimicgen tasks`; default
    /// the source demos').
    #[arg(long)]
    variant: Option<String>,
    /// With --run: the arm (see `mimicgen tasks`; default the source demos').
    #[arg(long, requires = "run")]
    robot: Option<String>,
    /// With --run: render robomimic's two cameras (agentview, the wrist) into the dataset.
    #[arg(long, requires = "run")]
    cameras: bool,
    /// After --run: select this attempt (the 3D view stays on it) and, if it failed, show it
    /// beside the nearest successful attempt.
    #[arg(long, requires = "run")]
    attempt: Option<u64>,
    /// After --run: diagnose the run (`mimicgen doctor`, the best 3 changes) with this many
    /// attempts in all, and show the Doctor panel.
    #[arg(long, requires = "run", value_name = "BUDGET")]
    doctor: Option<usize>,
    /// Once everything is shown, save the window to this PNG and exit.
    #[arg(long, value_name = "FILE.png")]
    screenshot: Option<PathBuf>,
    /// Spec fields for the preview and the run form, as `generate` takes them.
    #[command(flatten)]
    spec: generate::SpecArgs,
}

/// The app's screens, as `--screen` names them.
#[derive(clap::ValueEnum, Debug, Clone, Copy, PartialEq, Eq)]
enum ScreenArg {
    /// Demo timelines and subtask ends.
    Annotate,
    /// An attempt over a new scene, and "try it".
    Preview,
    /// A generation run, live.
    Generate,
}

/// Opens the window as `args` say and returns when it closes.
///
/// # Errors
/// No bundled demos to open, or no window (no display).
pub fn run(args: AppArgs) -> anyhow::Result<()> {
    let AppArgs { file, screen, demo, step, try_it, run, variant, robot, cameras, attempt, doctor, screenshot, spec } = args;
    let file = match file {
        Some(f) => f,
        None => mimicgen_pipeline::bundled::source_demos("stack")?,
    };
    let screen = match screen {
        ScreenArg::Annotate => mimicgen_gui::Screen::Annotate,
        ScreenArg::Preview => mimicgen_gui::Screen::Preview,
        ScreenArg::Generate => mimicgen_gui::Screen::Generate,
    };
    let options = mimicgen_gui::RunOptions {
        file: Some(file),
        screen,
        demo,
        step,
        try_it,
        run,
        variant,
        robot,
        cameras,
        attempt,
        doctor,
        screenshot,
        spec: spec.overrides(),
        vet: mimicgen_server::Vetter::this_binary(),
    };
    mimicgen_gui::run(options).map_err(|e| {
        anyhow::anyhow!(
            "cannot open the app's window ({e}); without a display, use the batch commands (`mimicgen generate`, `mimicgen annotate`)"
        )
    })?;
    Ok(())
}
