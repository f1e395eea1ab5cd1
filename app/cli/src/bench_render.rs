//! `mimicgen bench-render`: what a camera frame costs, drawn several ways, and whether the ways
//! give the same pixels.
#![allow(clippy::indexing_slicing, reason = "the per-way tables (best, images, rigs) have one entry per WAYS, indexed by its positions")]

use std::path::PathBuf;
use std::sync::{Arc, Barrier};
use std::time::Instant;

use mimicgen_sim::camera::{CameraConfig, Cameras, ImageStream, Pixels, RenderOptions};
use mimicgen_sim::{Scene, SimEnv, Task};

use crate::exit::outln;

/// Arguments of `mimicgen bench-render`.
#[derive(clap::Args, Debug)]
#[command(after_help = "\
Examples:
  mimicgen generate --num-demos 1 --guarantee --seed 1 --out /tmp/one.hdf5
  mimicgen bench-render /tmp/one.hdf5                       every way, 1 and 2 threads
  LP_NUM_THREADS=0 mimicgen bench-render /tmp/one.hdf5      Mesa's llvmpipe without its own threads

Renders every stored state of the demo from its cameras (default agentview and the wrist camera,
84 x 84, robosuite's 4x multisampling) and prints, per way of drawing, milliseconds per frame (one
camera image) and the difference from the first way's pixels (PSNR; inf = identical):
  mujoco     one camera per render and read-back, every geom: MuJoCo's renderer as robosuite uses it
  tiled      every camera side by side in one buffer, one read-back per state
  reflection tiled, and the geoms a camera cannot see left out (`--cameras --camera-reflection`)
  default    that without the floor's 1 % reflection (`--cameras`)
  fast       that without multisampling (`--cameras --camera-fast`)
Then one way (--threads-way) on 1 and on 2 threads at once (one renderer each), frames per second.
scripts/bench_render.py runs this beside robosuite rendering the same states.")]
pub struct BenchRenderArgs {
    /// A dataset with `states` and `model_file` per demo (e.g. from `mimicgen generate`).
    file: PathBuf,
    /// The demo whose states are drawn.
    #[arg(long, default_value = "demo_0")]
    demo: String,
    /// Cameras, comma-separated.
    #[arg(long, default_value = "agentview,robot0_eye_in_hand", value_delimiter = ',')]
    cameras: Vec<String>,
    /// Image size, N for N x N.
    #[arg(long, default_value_t = 84)]
    size: usize,
    /// Draw each way this many times (alternating) and report the fastest.
    #[arg(long, default_value_t = 3)]
    rounds: usize,
    /// The way timed on 1 and 2 threads at once.
    #[arg(long, default_value = "default", value_parser = ["mujoco", "tiled", "reflection", "default", "fast"])]
    threads_way: String,
    /// Task, when `env_args` does not name one of ours.
    #[arg(long)]
    task: Option<String>,
}

struct Way {
    name: &'static str,
    fast: bool,
    how: RenderOptions,
}

const WAYS: [Way; 5] = [
    Way { name: "mujoco", fast: false, how: RenderOptions { tile: false, cull: false, reflection: true } },
    Way { name: "tiled", fast: false, how: RenderOptions { tile: true, cull: false, reflection: true } },
    Way { name: "reflection", fast: false, how: RenderOptions { tile: true, cull: true, reflection: true } },
    Way { name: "default", fast: false, how: RenderOptions { tile: true, cull: true, reflection: false } },
    Way { name: "fast", fast: true, how: RenderOptions { tile: true, cull: true, reflection: false } },
];

/// Every state of `states` drawn by `cameras` in a fresh environment; returns the images and the
/// seconds the drawing took (the renderer is made, and its first frame drawn, before timing
/// starts, after `start` when given: threads timed together).
fn draw(
    scene: &Arc<Scene>,
    task: &Arc<dyn Task>,
    states: &mimicgen_engine::Rows,
    cameras: &Cameras,
    start: Option<&Barrier>,
) -> anyhow::Result<(Vec<ImageStream>, f64)> {
    let mut env = SimEnv::new(Arc::clone(scene), Arc::clone(task));
    let first = mimicgen_engine::Rows::from_vec(states.width(), states.iter().next().unwrap_or_default().to_vec(), "states")?;
    env.images_for_states(&first, cameras)?;
    if let Some(barrier) = start {
        barrier.wait();
    }
    let started = Instant::now();
    let images = env.images_for_states(states, cameras)?;
    Ok((images.into_values().collect(), started.elapsed().as_secs_f64()))
}

/// How `b` differs from `a` over all pixels: peak signal-to-noise ratio (dB; infinite when
/// equal), the share of values that differ and the largest difference (0-255).
#[allow(clippy::cast_precision_loss)]
fn difference(a: &[ImageStream], b: &[ImageStream]) -> serde_json::Value {
    let (mut sum, mut n, mut differ, mut max) = (0.0f64, 0usize, 0usize, 0u8);
    for (x, y) in a.iter().zip(b) {
        if let (Pixels::Rgb(x), Pixels::Rgb(y)) = (&x.pixels, &y.pixels) {
            for (p, q) in x.iter().zip(y) {
                sum += (f64::from(*p) - f64::from(*q)).powi(2);
                differ += usize::from(p != q);
                max = max.max(p.abs_diff(*q));
            }
            n += x.len();
        }
    }
    let mse = sum / n.max(1) as f64;
    let psnr = if mse == 0.0 { serde_json::json!("inf") } else { serde_json::json!(10.0 * (255.0f64 * 255.0 / mse).log10()) };
    serde_json::json!({ "psnr_db": psnr, "values_differing": differ as f64 / n.max(1) as f64, "max_abs_diff": max })
}

/// Runs the benchmark and prints one JSON object.
///
/// # Errors
/// Unreadable input, unknown demo or camera, a scene that does not compile, no EGL.
#[allow(clippy::cast_precision_loss)]
pub fn run(args: &BenchRenderArgs) -> anyhow::Result<()> {
    let (scene, task, states) = mimicgen_pipeline::render::demo_to_render(&args.file, &args.demo, args.task.as_deref())?;
    let config = |fast: bool| CameraConfig {
        names: args.cameras.clone(),
        height: args.size,
        width: args.size,
        depth: false,
        fast,
        reflection: true,
    };
    let rigs =
        WAYS.iter().map(|w| Ok(Cameras::new(&scene, config(w.fast))?.with_render_options(w.how))).collect::<anyhow::Result<Vec<_>>>()?;
    let frames = (states.len() * args.cameras.len()) as f64;
    let mut best = vec![f64::INFINITY; WAYS.len()];
    let mut images = vec![Vec::new(); WAYS.len()];
    for round in 0..args.rounds.max(1) {
        for (i, rig) in rigs.iter().enumerate() {
            let (drawn, seconds) = draw(&scene, &task, &states, rig, None)?;
            best[i] = best[i].min(seconds);
            if round == 0 {
                images[i] = drawn;
            }
            eprintln!("round {}: {:<10} {:6.2} ms per frame", round + 1, WAYS[i].name, seconds * 1e3 / frames);
        }
    }
    let ways: serde_json::Map<String, serde_json::Value> = WAYS
        .iter()
        .enumerate()
        .map(|(i, w)| {
            (
                w.name.to_owned(),
                serde_json::json!({ "ms_per_frame": best[i] * 1e3 / frames, "vs_mujoco": difference(&images[0], &images[i]) }),
            )
        })
        .collect();
    // One way on one thread and on two at once, each with its own renderer.
    let timed = &rigs[WAYS.iter().position(|w| w.name == args.threads_way).unwrap_or(3)];
    let one = draw(&scene, &task, &states, timed, None)?.1;
    let barrier = Barrier::new(2);
    let seconds = std::thread::scope(|s| {
        let runs: Vec<_> = (0..2).map(|_| s.spawn(|| draw(&scene, &task, &states, timed, Some(&barrier)))).collect();
        runs.into_iter()
            .map(|r| r.join().map_err(|_| anyhow::anyhow!("a render thread panicked"))?.map(|(_, t)| t))
            .collect::<anyhow::Result<Vec<f64>>>()
    })?;
    let two = seconds.into_iter().fold(0.0, f64::max);
    let json = serde_json::json!({
        "file": args.file.display().to_string(),
        "demo": args.demo,
        "states": states.len(),
        "cameras": args.cameras,
        "size": args.size,
        "lp_num_threads": std::env::var("LP_NUM_THREADS").ok(),
        "ways": ways,
        "threads": {
            "way": args.threads_way,
            "frames_per_s_1": frames / one,
            "frames_per_s_2": 2.0 * frames / two,
            "speedup_2_vs_1": 2.0 * one / two,
        },
    });
    outln!("{}", serde_json::to_string_pretty(&json)?);
    Ok(())
}
