//! `mimicgen bench-app`: the app's own work per frame (layout, plots and tessellation; not GPU
//! raster) with a file loaded, and the time until a file is browsable. Frames run headless on an
//! egui context at 1280x800, as the window would run them.

use std::path::PathBuf;
use std::time::{Duration, Instant};

use anyhow::bail;
use mimicgen_gui::egui;
use mimicgen_gui::{Command, MimicgenApp, Screen};
use serde_json::json;

use crate::exit::outln;

/// Arguments of `mimicgen bench-app`.
#[derive(clap::Args, Debug)]
#[command(after_help = "\
Examples:
  mimicgen generate --num-demos 1100 --out /tmp/big/stack.hdf5      # a ~1000-demo dataset
  mimicgen bench-app /tmp/big/stack.hdf5 --frames 600
  mimicgen bench-app                                                  # the bundled Stack demos

Prints JSON: seconds until the file is browsable (its first demos listed) and until every demo
is read, frame times while it loads (the UI keeps drawing), and p50/p95/max of the frame time while browsing (the cursor steps every frame, the
shown demo changes every 10 frames) and on the preview screen.")]
pub struct BenchAppArgs {
    /// The file to open (default: the bundled Stack D0 source demos).
    file: Option<PathBuf>,
    /// Frames measured per screen.
    #[arg(long, default_value_t = 300)]
    frames: usize,
    /// Also start a run of this many attempts (1 worker) from the app, measure the frame time
    /// while it goes, and compare its throughput with the same run through the pipeline alone
    /// (what `mimicgen generate` does). 0: skip.
    #[arg(long, default_value_t = 0)]
    run: usize,
    /// Directory for the runs' datasets (default: a temporary one).
    #[arg(long)]
    dir: Option<PathBuf>,
    /// Also open this finished run (a dataset `generate` wrote) on the generate screen and measure
    /// its frames (attempt table, plots and coverage over every attempt).
    #[arg(long, value_name = "DATASET")]
    open_run: Option<PathBuf>,
}

fn percentile(sorted_ms: &[f64], p: f64) -> f64 {
    if sorted_ms.is_empty() {
        return f64::NAN;
    }
    #[allow(clippy::cast_possible_truncation, clippy::cast_sign_loss, clippy::cast_precision_loss)]
    let i = ((sorted_ms.len() - 1) as f64 * p).round() as usize;
    sorted_ms.get(i).copied().unwrap_or(f64::NAN)
}

fn summary(mut ms: Vec<f64>) -> serde_json::Value {
    ms.sort_by(f64::total_cmp);
    json!({"frames": ms.len(), "p50_ms": percentile(&ms, 0.5), "p95_ms": percentile(&ms, 0.95), "max_ms": ms.last().copied().unwrap_or(f64::NAN)})
}

/// A headless window: runs the app's frames on an egui context and times each.
struct Frames {
    ctx: egui::Context,
    app: MimicgenApp,
    started: Instant,
    /// Vertices tessellated in the last frame (a check that the frame drew what it should).
    vertices: usize,
}

impl Frames {
    /// One frame (with `events`), timed in ms: the app's `show` plus tessellation.
    fn frame(&mut self, events: Vec<egui::Event>) -> f64 {
        let input = egui::RawInput {
            screen_rect: Some(egui::Rect::from_min_size(egui::Pos2::ZERO, egui::vec2(1280.0, 800.0))),
            time: Some(self.started.elapsed().as_secs_f64()),
            events,
            ..egui::RawInput::default()
        };
        let t = Instant::now();
        let out = self.ctx.run_ui(input, |ui| self.app.show(ui));
        let primitives = self.ctx.tessellate(out.shapes, out.pixels_per_point);
        let ms = t.elapsed().as_secs_f64() * 1e3;
        self.vertices = primitives
            .iter()
            .map(|p| match &p.primitive {
                egui::epaint::Primitive::Mesh(m) => m.vertices.len(),
                egui::epaint::Primitive::Callback(_) => 0,
            })
            .sum();
        ms
    }

    /// Runs frames at ~60 Hz until the backend has answered everything; returns their times
    /// and when a file was first open (seconds since the app started).
    fn until_idle(&mut self, limit: Duration) -> anyhow::Result<(Vec<f64>, Option<f64>)> {
        let deadline = Instant::now() + limit;
        let mut ms = Vec::new();
        let mut first_open = None;
        loop {
            ms.push(self.frame(Vec::new()));
            if first_open.is_none() && self.app.model.file.is_some() {
                first_open = Some(self.started.elapsed().as_secs_f64());
            }
            if self.app.model.in_flight == 0 {
                return Ok((ms, first_open));
            }
            if Instant::now() > deadline {
                bail!("the backend did not answer within {limit:?}");
            }
            std::thread::sleep(Duration::from_millis(16));
        }
    }
}

/// A run of `args.run` attempts on 1 worker started from the app (frames drawn at ~60 Hz while it
/// goes), then the same run through the pipeline alone; their throughputs and the frame times.
fn run_in_app(frames: &mut Frames, args: &BenchAppArgs, file: &std::path::Path) -> anyhow::Result<serde_json::Value> {
    let tmp = tempfile::tempdir()?;
    let dir = args.dir.clone().unwrap_or_else(|| tmp.path().to_path_buf());
    let source = frames.app.model.file.as_ref().map_or_else(|| file.to_path_buf(), |f| f.path.clone());
    let form = mimicgen_gui::model::RunForm {
        attempts: args.run,
        workers: 1,
        keep_failed: false,
        overwrite: true,
        out: dir.join("app_run.hdf5").display().to_string(),
        ..mimicgen_gui::model::RunForm::default()
    };
    // The pipeline alone before and after the app's run, so drift (caches, clock) does not favour either.
    let alone = |name: &str| -> anyhow::Result<mimicgen_pipeline::Report> {
        let config = mimicgen_gui::model::RunForm { out: dir.join(name).display().to_string(), ..form.clone() }.config(&source, None);
        Ok(mimicgen_pipeline::Pipeline::prepare(&config)?.run(&std::sync::atomic::AtomicBool::new(false), |_| {})?)
    };
    let before = alone("cli_run_before.hdf5")?;
    frames.app.command(Command::Show(Screen::Generate));
    frames.app.command(Command::SetRunForm(Box::new(form.clone())));
    frames.app.command(Command::StartRun);
    let mut during = Vec::new();
    let deadline = Instant::now() + Duration::from_secs(3600);
    while frames.app.model.run.as_ref().is_some_and(mimicgen_gui::model::RunState::running) {
        during.push(frames.frame(Vec::new()));
        if Instant::now() > deadline {
            bail!("the run did not end within an hour");
        }
        std::thread::sleep(Duration::from_millis(16));
    }
    let Some(app_report) = frames.app.model.run.as_ref().and_then(|r| r.report.clone()) else {
        bail!("the run from the app failed: {:?}", frames.app.model.run.as_ref().and_then(|r| r.error.clone()))
    };
    let after = alone("cli_run_after.hdf5")?;
    let pipeline_rate = 0.5 * (before.attempts_per_s + after.attempts_per_s);
    #[allow(clippy::cast_precision_loss)]
    let frames_per_s = during.len() as f64 / app_report.wall_time_s.max(1e-9);
    Ok(json!({
        "attempts": args.run,
        "app_attempts_per_s": app_report.attempts_per_s,
        "pipeline_attempts_per_s": pipeline_rate,
        "pipeline_attempts_per_s_before_and_after": [before.attempts_per_s, after.attempts_per_s],
        "app_over_pipeline": app_report.attempts_per_s / pipeline_rate,
        "same_successes": app_report.successes == before.successes && before.successes == after.successes,
        "frames_while_running": summary(during),
        "frames_drawn_per_s": frames_per_s,
    }))
}

fn key(key: egui::Key) -> Vec<egui::Event> {
    let press = |pressed| egui::Event::Key { key, physical_key: None, pressed, repeat: false, modifiers: egui::Modifiers::NONE };
    vec![press(true), press(false)]
}

/// Runs `mimicgen bench-app`.
///
/// # Errors
/// The file cannot be opened, or the backend does not answer.
pub fn run(args: &BenchAppArgs) -> anyhow::Result<()> {
    let file = match &args.file {
        Some(f) => f.clone(),
        None => mimicgen_pipeline::bundled::source_demos("stack")?,
    };
    let started = Instant::now();
    let mut frames =
        Frames { ctx: egui::Context::default(), app: mimicgen_gui::desktop(|| {}, Some(file.clone()), None, None), started, vertices: 0 };
    let (loading, first_open) = frames.until_idle(Duration::from_secs(600))?;
    let all_read_s = started.elapsed().as_secs_f64();
    if let Some(e) = &frames.app.model.error {
        bail!("{e}");
    }
    let demos = frames.app.model.file.as_ref().map_or(0, |f| f.demos.len());
    let browsable_s = first_open.unwrap_or(all_read_s);
    eprintln!(
        "browsable after {browsable_s:.2} s, all {demos} demos read after {all_read_s:.2} s; measuring {} frames per screen",
        args.frames
    );
    let check = |frames: &Frames| -> anyhow::Result<()> {
        match &frames.app.model.error {
            Some(e) => bail!("{e}"),
            None => Ok(()),
        }
    };
    let mut browsing = Vec::with_capacity(args.frames);
    for i in 0..args.frames {
        if i % 10 == 0 {
            frames.app.command(Command::SelectDemo((i / 10 * 7) % demos.max(1)));
        }
        browsing.push(frames.frame(key(egui::Key::ArrowRight)));
    }
    let browsing_vertices = frames.vertices;
    frames.app.command(Command::Show(Screen::Preview));
    let (planning, _) = frames.until_idle(Duration::from_secs(120))?;
    check(&frames)?;
    let preview: Vec<f64> = (0..args.frames).map(|_| frames.frame(Vec::new())).collect();
    let preview_vertices = frames.vertices;
    let opened_run = match &args.open_run {
        Some(path) => {
            frames.app.command(Command::Show(Screen::Generate));
            frames.app.command(Command::OpenRun(path.clone()));
            let t = Instant::now();
            let (_, _) = frames.until_idle(Duration::from_secs(600))?;
            check(&frames)?;
            let read_s = t.elapsed().as_secs_f64();
            let rows = frames.app.model.run.as_ref().map_or(0, |r| r.rows.len());
            let ms: Vec<f64> = (0..args.frames).map(|_| frames.frame(Vec::new())).collect();
            Some(
                json!({"dataset": path.display().to_string(), "attempts": rows, "read_s": read_s, "frames": summary(ms), "vertices_per_frame": frames.vertices}),
            )
        }
        None => None,
    };
    let run = if args.run > 0 { Some(run_in_app(&mut frames, args, &file)?) } else { None };
    let report = json!({
        "run": run,
        "opened_run": opened_run,
        "file": file.display().to_string(),
        "demos": demos,
        "browsable_after_s": browsable_s,
        "all_demos_read_after_s": all_read_s,
        "while_loading": summary(loading),
        "browsing": summary(browsing),
        "browsing_vertices_per_frame": browsing_vertices,
        "preview_while_planning": summary(planning),
        "preview": summary(preview),
        "preview_vertices_per_frame": preview_vertices,
    });
    outln!("{}", serde_json::to_string_pretty(&report)?);
    Ok(())
}
