//! `mimicgen info`: a summary of a robomimic / MimicGen HDF5 dataset.

use std::path::PathBuf;
use std::process::ExitCode;

use mimicgen_io::info::DatasetInfo;
use mimicgen_io::{DemoReader, ReadOptions};

use crate::exit::outln;

/// `mimicgen info`'s arguments.
#[derive(Debug, clap::Args)]
pub struct InfoArgs {
    /// The dataset.
    pub file: PathBuf,
    /// Print JSON instead of text.
    #[arg(long)]
    pub json: bool,
    /// Open a file an interrupted writer left behind (keeps its complete demos).
    #[arg(long)]
    pub recover: bool,
}

/// Runs `mimicgen info`.
///
/// # Errors
/// What the command reports (each names the file and field).
pub fn run(args: InfoArgs) -> anyhow::Result<ExitCode> {
    let InfoArgs { file, json, recover } = args;

    let ds = DemoReader::open_with(&file, ReadOptions { recover })?;
    let info = DatasetInfo::of(&ds)?;
    if json {
        outln!("{}", serde_json::to_string_pretty(&info)?);
    } else {
        print_info(&info)?;
    }
    Ok(ExitCode::SUCCESS)
}

fn print_info(info: &DatasetInfo) -> anyhow::Result<()> {
    let l = &info.lengths;
    outln!("{}", info.file);
    let total = info.total_attr.map_or_else(String::new, |t| format!(" (data/total says {t})"));
    outln!("  demos {}, samples {}{total}", info.num_demos, info.num_samples);
    outln!("  lengths: mean {:.1}, std {:.1}, min {}, max {}", l.mean, l.std, l.min, l.max);
    outln!(
        "  env: {}, controller {}",
        info.env_name.as_deref().unwrap_or("(no env_args)"),
        info.controller_type.as_deref().unwrap_or("(unknown)")
    );
    outln!("  actions: {} dims, min {}, max {}", info.action_dim, fmt_list(&info.action_min), fmt_list(&info.action_max));
    if info.obs.is_empty() {
        outln!("  obs: (none)");
    }
    for (key, shape) in &info.obs {
        let dtype = info.obs_dtypes.get(key).map(String::as_str).unwrap_or_default();
        outln!("  obs/{key}: {shape:?}{}", if dtype == "float64" || dtype.is_empty() { String::new() } else { format!(" {dtype}") });
    }
    outln!("  objects: {}", if info.objects.is_empty() { "(none)".to_owned() } else { info.objects.join(", ") });
    for (name, s) in &info.signals {
        let f = &s.first_on_step;
        outln!(
            "  signal {name}: first 0->1 at step min {}, mean {:.1}, max {} ({} of {} demos){}",
            f.min,
            f.mean,
            f.max,
            f.count,
            s.demos,
            if s.never_on.is_empty() { String::new() } else { format!("; never on in {}", s.never_on.join(", ")) }
        );
    }
    if info.filter_keys.is_empty() {
        outln!("  filter keys: (none)");
    }
    for (key, n) in &info.filter_keys {
        outln!("  filter key {key}: {n} demos");
    }
    if info.report.is_mimicgen_source() {
        outln!("  MimicGen source: yes (datagen_info complete)");
    } else {
        outln!("  MimicGen source: no: {}", info.report);
    }
    Ok(())
}

fn fmt_list(v: &[f64]) -> String {
    let parts: Vec<String> = v.iter().map(|x| format!("{x:.3}")).collect();
    format!("[{}]", parts.join(", "))
}
