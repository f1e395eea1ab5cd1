//! How each front end names the choices a library error leaves to the user. The libraries return
//! typed errors ("this output exists") and never name a flag; the CLI says `--overwrite`, Python
//! `overwrite=True`, the app its checkbox.

/// A choice the user can make about an error.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Choice {
    /// Replace the outputs that exist.
    Overwrite,
    /// Continue the interrupted run that left its `.partial` files.
    Resume,
}

/// Who the user is talking to.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FrontEnd {
    /// `mimicgen <command> --flag`.
    Cli,
    /// `mimicgen_rs.function(keyword=...)`.
    Python,
    /// The app's forms, on the desktop or in a browser.
    App,
}

impl FrontEnd {
    /// How to make `choice` here ("pass --overwrite"), or `None` where this front end does not
    /// offer it (the app cannot resume a run).
    #[must_use]
    pub fn ask(self, choice: Choice) -> Option<&'static str> {
        Some(match (self, choice) {
            (Self::Cli, Choice::Overwrite) => "pass --overwrite",
            (Self::Cli, Choice::Resume) => "pass --resume",
            (Self::Python, Choice::Overwrite) => "pass overwrite=True",
            (Self::Python, Choice::Resume) => "pass resume=True",
            (Self::App, Choice::Overwrite) => "tick \"replace existing outputs\"",
            (Self::App, Choice::Resume) => return None,
        })
    }

    /// A run's field, named by its `mimicgen generate` flag (`--action-noise`), as this front
    /// end names it: Python's keyword (`num_demos`) or key of `spec` (`spec["action_noise"]`);
    /// the CLI and the app (whose form shows the flags) keep the flag.
    #[must_use]
    pub fn field(self, flag: &str) -> String {
        match (self, flag.strip_prefix("--")) {
            (Self::Python, Some(name)) => {
                let key = name.replace('-', "_");
                if crate::SpecOverrides::FIELDS.contains(&key.as_str()) { format!("spec[{key:?}]") } else { key }
            }
            _ => flag.to_owned(),
        }
    }

    /// What to do about an output that exists (`resumable`: an interrupted run left it), in this
    /// front end's words.
    #[must_use]
    pub fn output_exists_advice(self, resumable: bool) -> String {
        let overwrite = self.ask(Choice::Overwrite).unwrap_or("replace it");
        match self.ask(Choice::Resume).filter(|_| resumable) {
            Some(resume) => format!("{resume} to continue that run, or {overwrite} to start over"),
            None => format!("{overwrite} to replace it, or choose another output"),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn each_front_end_names_its_own_option() {
        assert_eq!(FrontEnd::Cli.output_exists_advice(false), "pass --overwrite to replace it, or choose another output");
        assert_eq!(
            FrontEnd::Python.output_exists_advice(true),
            "pass resume=True to continue that run, or pass overwrite=True to start over"
        );
        let app = FrontEnd::App.output_exists_advice(true);
        assert!(app.contains("replace existing outputs") && !app.contains("--") && !app.contains("resume"), "{app}");
    }

    #[test]
    fn python_names_every_spec_flag_as_a_key_of_spec() {
        use crate::{OffsetRange, Scoped, SpecOverrides};
        let every = SpecOverrides {
            selection: vec![Scoped::all("random".into())],
            nn_k: vec![Scoped::all(3)],
            action_noise: vec![Scoped::all(0.1)],
            offset_range: vec![Scoped::all(OffsetRange(0, 1))],
            interpolation_steps: vec![Scoped::all(5)],
            fixed_steps: vec![Scoped::all(0)],
            select_src_per_subtask: Some(true),
            transit: vec![Scoped::all(mimicgen_engine::spec::Transit::Plan)],
            approach_m: vec![Scoped::all(0.1)],
            exclude_source: vec![2, 6],
        };
        let flags: Vec<String> = every.to_args().into_iter().filter(|a| a.starts_with("--")).collect();
        assert_eq!(flags.len(), SpecOverrides::FIELDS.len());
        for flag in flags {
            let key = FrontEnd::Python.field(&flag);
            assert!(key.starts_with("spec[\"") && !key.contains('-'), "{flag} -> {key}");
        }
        assert_eq!(FrontEnd::Python.field("--num-demos"), "num_demos");
        assert_eq!(FrontEnd::Cli.field("--num-demos"), "--num-demos");
    }
}
