//! The two-arm task spec: each arm's subtasks and the ties between them.

use serde::{Deserialize, Serialize};

use super::{ArmSubtask, Constraint, Schedule, ScheduleError, name};

/// A two-arm task spec: our TOML with an `[[arm]]` table per arm, each with its own
/// `[[arm.subtask]]`s (the fields of a one-arm `[[subtask]]`), then the ties between them:
///
/// ```
/// let spec = mimicgen_engine::two_arm::TwoArmSpec::from_toml_str(r#"
/// name = "two_arm_lift"
/// [generation]
/// num_trials = 10
///
/// [[arm]]
/// name = "robot0"
/// [[arm.subtask]]
/// object_ref = "pot"
/// term_signal = "grasp_handle0"
/// [[arm.subtask]]
/// object_ref = "pot"
///
/// [[arm]]
/// name = "robot1"
/// [[arm.subtask]]
/// object_ref = "pot"
/// term_signal = "grasp_handle1"
/// [[arm.subtask]]
/// object_ref = "pot"
///
/// ## Both arms lift the pot together: arm 0's subtask 1 with arm 1's subtask 1.
/// [[coordination]]
/// subtasks = [[0, 1], [1, 1]]
/// "#, "lift.toml").unwrap();
/// assert_eq!(spec.constraints().len(), 1);
/// ```
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TwoArmSpec {
    /// Task name (`two_arm_lift`).
    #[serde(default)]
    pub name: String,
    /// The robosuite environment to generate in, when the spec names one.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub env_name: Option<String>,
    /// Run settings, shared by both arms.
    #[serde(default)]
    pub generation: crate::GenerationSettings,
    /// The arms in the order of the action vector (robosuite's robot0 first).
    #[serde(rename = "arm")]
    pub arms: Vec<ArmSpec>,
    /// Pairs of subtasks (one per arm) that run together.
    #[serde(default, rename = "coordination", skip_serializing_if = "Vec::is_empty")]
    pub coordinations: Vec<CoordinationSpec>,
    /// Subtasks that wait for one of the other arm's to end.
    #[serde(default, rename = "sequential", skip_serializing_if = "Vec::is_empty")]
    pub sequentials: Vec<SequentialSpec>,
}

/// One arm's subtasks.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ArmSpec {
    /// The arm's name (`robot0`): its observations' prefix.
    pub name: String,
    /// Its subtasks in order (none: the arm holds still).
    #[serde(rename = "subtask", default)]
    pub subtasks: Vec<crate::SubtaskSpec>,
}

/// `[[coordination]]`: two subtasks, `[arm, subtask]` each, that run together.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CoordinationSpec {
    /// The two subtasks.
    pub subtasks: [ArmSubtask; 2],
}

/// `[[sequential]]`: `later` starts only after `first` has ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SequentialSpec {
    /// `[arm, subtask]` that must end first.
    pub first: ArmSubtask,
    /// `[arm, subtask]` that waits for it.
    pub later: ArmSubtask,
}

impl TwoArmSpec {
    /// Parses and checks a two-arm spec; `origin` names the file in errors.
    ///
    /// # Errors
    /// [`crate::EngineError::Config`] naming the file and field: TOML errors, an arm's subtask
    /// fields as a one-arm spec checks them (`arm[1].subtask[0].action_noise`), not two arms,
    /// coordinated subtasks on different objects, ties that cannot be met.
    pub fn from_toml_str(text: &str, origin: &str) -> Result<Self, crate::EngineError> {
        let spec: Self = toml::from_str(text).map_err(|e| crate::spec::toml_error(text, origin, &e))?;
        spec.check(origin)?;
        Ok(spec)
    }

    /// The ties, as the schedule takes them.
    #[must_use]
    pub fn constraints(&self) -> Vec<Constraint> {
        let coordinations = self.coordinations.iter().map(|c| Constraint::Coordination(c.subtasks[0], c.subtasks[1]));
        coordinations.chain(self.sequentials.iter().map(|s| Constraint::Sequential { first: s.first, later: s.later })).collect()
    }

    /// Arm `arm`'s subtasks as a one-arm spec with the shared settings (what segmentation,
    /// selection and the transform take).
    #[must_use]
    pub fn arm_spec(&self, arm: usize) -> Option<crate::TaskSpec> {
        self.arms.get(arm).map(|a| crate::TaskSpec {
            name: format!("{} ({})", self.name, a.name),
            env_name: None,
            generation: self.generation.clone(),
            source: crate::spec::SourceSelection::default(),
            subtasks: a.subtasks.clone(),
        })
    }

    /// A fresh schedule of this spec's subtasks and ties.
    ///
    /// # Errors
    /// As [`Schedule::new`].
    pub fn schedule(&self) -> Result<Schedule, ScheduleError> {
        let counts: Vec<usize> = self.arms.iter().map(|a| a.subtasks.len()).collect();
        Schedule::new(&counts, &self.constraints())
    }

    /// Checks the spec on its own.
    ///
    /// # Errors
    /// As [`TwoArmSpec::from_toml_str`].
    pub fn check(&self, origin: &str) -> Result<(), crate::EngineError> {
        let err =
            |field: &str, reason: String| Err(crate::EngineError::Config { file: origin.to_owned(), field: field.to_owned(), reason });
        if self.arms.len() != 2 {
            return err("arm", format!("a two-arm spec has two [[arm]] tables, this one has {}", self.arms.len()));
        }
        // An arm without subtasks holds still.
        for arm in 0..self.arms.len() {
            if let Some(spec) = self.arm_spec(arm).filter(|s| !s.subtasks.is_empty())
                && let Err(crate::EngineError::Config { field, reason, .. }) = spec.check(origin)
            {
                return err(&format!("arm[{arm}].{field}"), reason);
            }
        }
        if let Some(field) = super::generate::refuses_planned_transit(self) {
            return err(&field, "planned transit is for one arm only (a two-arm collision space is not built yet)".to_owned());
        }
        for (i, c) in self.coordinations.iter().enumerate() {
            let object = |(a, k): ArmSubtask| self.arms.get(a).and_then(|arm| arm.subtasks.get(k)).map(|s| s.object_ref.clone());
            let [x, y] = c.subtasks;
            if let (Some(ox), Some(oy)) = (object(x), object(y))
                && ox != oy
            {
                return err(
                    &format!("coordination[{i}].subtasks"),
                    format!("{} acts on {ox:?} and {} on {oy:?}; coordinated subtasks share one object frame", name(x), name(y)),
                );
            }
        }
        if let Err(e) = self.schedule() {
            let field = if self.sequentials.is_empty() { "coordination" } else { "sequential" };
            return err(field, e.0);
        }
        Ok(())
    }
}
