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
    match advice {
        Some(advice) => format!("{e:#}; {advice}"),
        None => format!("{e:#}"),
    }
}
