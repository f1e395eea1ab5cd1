//! Exit status, for scripts: 0 done, 1 the run or the machine failed (I/O, simulation), 2 the
//! user's mistake (an argument, a missing or malformed file, an unknown task or field, an output
//! that exists), 130 interrupted (Ctrl-C; a generation run resumes with `--resume`).

use std::fmt;

use mimicgen_pipeline::{FrontEnd, PipelineError};

/// The exit status table, as `--help` and the README print it.
pub const TABLE: &str = "\
Exit status:
  0    done
  1    the run or the machine failed (I/O, simulation); worth retrying
  2    the user's mistake: an argument, a missing or malformed file, an unknown task or field,
       an output that exists; retrying the same command fails the same way
  130  interrupted (Ctrl-C); `mimicgen generate ... --resume` continues the run";

/// A mistake in the command line the libraries never saw (exit status 2).
#[derive(Debug)]
pub struct Usage(pub String);

impl fmt::Display for Usage {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for Usage {}

/// `Err` of a [`Usage`] error from a `format!`-style message.
macro_rules! usage {
    ($($arg:tt)*) => {
        return Err(anyhow::Error::new($crate::exit::Usage(format!($($arg)*))))
    };
}
pub(crate) use usage;

/// `println!` for a command's output: an error instead of a panic when stdout is gone (`mimicgen
/// tasks | head -1`), which [`closed_pipe`] lets `main` end quietly on, as `cat` and ripgrep do.
macro_rules! outln {
    ($($arg:tt)*) => {{
        use std::io::Write as _;
        writeln!(std::io::stdout().lock(), $($arg)*)?
    }};
}
pub(crate) use outln;

/// `print!` for a command's output; see [`outln`].
macro_rules! out {
    ($($arg:tt)*) => {{
        use std::io::Write as _;
        write!(std::io::stdout().lock(), $($arg)*)?
    }};
}
pub(crate) use out;

/// Whether `e` is a write to a closed stdout (the reader of a pipe left): the command ends
/// quietly with status 0, its output having gone where it was asked to.
pub fn closed_pipe(e: &anyhow::Error) -> bool {
    e.chain().any(|cause| cause.downcast_ref::<std::io::Error>().is_some_and(|io| io.kind() == std::io::ErrorKind::BrokenPipe))
}

/// 2 when a typed error in `e`'s chain says the user's input is at fault, else 1.
pub fn code(e: &anyhow::Error) -> u8 {
    let user = e.chain().find_map(|cause| {
        if cause.is::<Usage>() {
            return Some(true);
        }
        if let Some(e) = cause.downcast_ref::<PipelineError>() {
            return Some(e.is_user_error());
        }
        if let Some(e) = cause.downcast_ref::<mimicgen_io::IoError>() {
            return Some(e.is_user_error());
        }
        if let Some(e) = cause.downcast_ref::<mimicgen_engine::EngineError>() {
            return Some(e.is_user_error());
        }
        if let Some(e) = cause.downcast_ref::<mimicgen_sim::SimError>() {
            return Some(e.is_user_error());
        }
        if let Some(e) = cause.downcast_ref::<mimicgen_viz::VizError>() {
            return Some(e.is_user_error());
        }
        if let Some(e) = cause.downcast_ref::<mimicgen_server::ServerError>() {
            return Some(e.is_user_error());
        }
        None
    });
    if user == Some(true) { 2 } else { 1 }
}

/// The error's message with what the user can do about it, in the CLI's words (`pass
/// --overwrite ...`).
pub fn message(e: &anyhow::Error) -> String {
    let advice = e.chain().find_map(|cause| {
        if let Some(e) = cause.downcast_ref::<PipelineError>() {
            return e.advice(FrontEnd::Cli);
        }
        cause
            .downcast_ref::<mimicgen_io::IoError>()
            .filter(|e| matches!(e, mimicgen_io::IoError::Exists { .. }))
            .map(|_| FrontEnd::Cli.output_exists_advice(false))
    });
    // Each cause once: many errors already print their source in their own message.
    let mut text = e.to_string();
    for cause in e.chain().skip(1) {
        let cause = cause.to_string();
        if !text.contains(&cause) {
            text = format!("{text}: {cause}");
        }
    }
    match advice {
        Some(advice) => format!("{text}; {advice}"),
        None => text,
    }
}
