//! Tasks described as data: a task file (`core/sim/tasks/<task>.task.toml`, next to the task's
//! generation spec) names the scene's objects and how each variant places them, the subtask-end
//! signals and the success condition as [`Predicate`]s, robosuite's object observation as
//! [`ObsTerm`]s, and the scripted demonstrator's pick-and-places. [`crate::DataTask`] is the [`crate::Task`]
//! such a file describes; no task needs code of its own.
//!
//! ```toml
//! name = "stack"
//! env_name = "Stack"                      # robosuite's environment (`Stack_D0`)
//! description = "red cube onto green cube"
//! instruction = "stack the red cube on top of the green cube"
//! variants = ["D0", "D1"]
//!
//! [[object]]
//! name = "cubeA"
//! model = { kind = "box", name = "cubeA", half_size = [0.02, 0.02, 0.02], rgba = [0.5, 0, 0, 1], texture = ["redwood", "textures/red-wood.png"] }
//! height_m = 0.03                         # its origin above the table top at reset
//! radius_m = 0.028                        # kept this far from every object placed before it
//! place.D0 = { x = [-0.08, 0.08], y = [-0.08, 0.08] }   # yaw_deg defaults to [0, 360]
//! place.D1 = { x = [-0.2, 0.2], y = [-0.2, 0.2] }
//!
//! [signals]
//! grasp = { grasped = "cubeA" }
//!
//! [success]
//! all = [{ lifted = { object = "cubeA", above_m = 0.04 } }, { contact = ["cubeA", "cubeB"] }, { not = { grasped = "cubeA" } }]
//! ```

use std::collections::BTreeMap;

use mimicgen_engine::demonstrator::PickPlaceScript;
use serde::Deserialize;

use crate::compose::{BASE_TABLE_TOP_Z, ObjectModel};

/// A task file.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TaskFile {
    /// Name on the command line (`stack`).
    pub name: String,
    /// robosuite's environment name prefix (`Stack` -> `Stack_D0`).
    pub env_name: String,
    /// One line on what it is.
    pub description: String,
    /// The task as an instruction (LeRobot's `task` of each frame).
    pub instruction: String,
    /// Its variants (reset distributions), D0 first: the one the bundled demos were recorded in.
    pub variants: Vec<String>,
    /// Height of the table top (m), robosuite's `table_offset` z.
    #[serde(default = "base_table_top_z")]
    pub table_top_z: f64,
    /// How far the robot and the table stand from where the base scene has them (m, x and y):
    /// Pick Place keeps robosuite's bins-arena world frame, its robot 6 cm further forward and
    /// 10 cm to the right of the table scene's.
    #[serde(default)]
    pub robot_offset_m: [f64; 2],
    /// The arm stands on a mobile base that drives (Mobile Kitchen); absent: it stands still.
    #[serde(default)]
    pub mobile_base: Option<crate::mobile_base::MobileBaseModel>,
    /// The objects, in the order of the object observation and the datasets' `object_poses`.
    #[serde(rename = "object")]
    pub objects: Vec<ObjectDef>,
    /// The order objects are placed in at reset (each kept clear of those before it); the
    /// objects' order when empty.
    #[serde(default)]
    pub place_order: Vec<String>,
    /// Subtask-end signals by name.
    pub signals: BTreeMap<String, Predicate>,
    /// When the task is done.
    pub success: Predicate,
    /// robosuite's `object` observation, term by term.
    pub observation: Vec<ObsEntry>,
    /// The scripted demonstrator's pick-and-places, in order.
    #[serde(default, rename = "script")]
    pub scripts: Vec<PickPlaceScript>,
}

/// The most scenes a variant's instances may make (every combination is compiled).
const MAX_INSTANCE_SCENES: usize = 64;

fn base_table_top_z() -> f64 {
    BASE_TABLE_TOP_Z
}

/// One object of a task.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ObjectDef {
    /// Name in datasets and predicates (`cubeA`).
    pub name: String,
    /// What the composed scene adds for it.
    pub model: ObjectModel,
    /// Height of its origin above the table top at reset (m).
    pub height_m: f64,
    /// Radius of the circle kept clear of every object placed before it (m); 0 keeps nothing
    /// clear, not even later objects off its centre (a bin the objects start in).
    #[serde(default)]
    pub radius_m: f64,
    /// Where each variant places it.
    pub place: BTreeMap<String, Region>,
    /// Its orientation before the reset's flip and yaw (w, x, y, z): robosuite's `init_quat`
    /// (the reference's hammer lies on its side: its handle, the frame's z, along world +x).
    #[serde(default = "no_turn")]
    pub init_quat: [f64; 4],
    /// Other objects of its category that variants use in its place (the paper's object
    /// transfer: O1 an unseen mug, O2 one of twelve drawn per episode).
    #[serde(default, rename = "instance")]
    pub instances: Vec<Instance>,
    /// The variants the object is in (empty: all of them): clutter only some variants have.
    #[serde(default)]
    pub variants: Vec<String>,
    /// Whether it is an obstacle: clutter the robot and what it carries should not touch, counted
    /// per attempt and avoided by planned transit.
    #[serde(default)]
    pub obstacle: bool,
}

/// An object that stands in for a task's object in some variants: same name, same frame
/// conventions, another shape.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Instance {
    /// What datasets record as the episode's instance (`tall_green`).
    pub label: String,
    /// The variants that use it; a variant with several draws one per episode.
    pub variants: Vec<String>,
    /// Its model, named like the object's (its body is the object's body).
    pub model: ObjectModel,
}

/// Where an object is placed: uniform x, y (m, around the table centre) and yaw (deg). A range
/// whose ends are equal is that value.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Region {
    /// x range (m).
    pub x: [f64; 2],
    /// y range (m).
    pub y: [f64; 2],
    /// Yaw range (deg).
    #[serde(default = "any_yaw")]
    pub yaw_deg: [f64; 2],
    /// Half the resets (a seeded draw) turn the object 180 deg about the world's x axis after its
    /// `init_quat` and before its yaw: robosuite's placement sampler does this to the hammer of
    /// Hammer Cleanup (it composes the hammer's two possible initial orientations with the
    /// sampled rotation).
    #[serde(default)]
    pub flip: bool,
}

fn no_turn() -> [f64; 4] {
    [1.0, 0.0, 0.0, 0.0]
}

fn any_yaw() -> [f64; 2] {
    [0.0, 360.0]
}

/// A condition on the scene's state, from which signals and success are built. `eef` names the
/// gripper's grip site where an object is expected.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
pub enum Predicate {
    /// Both finger pads touch the object (robosuite's `check_grasp`).
    Grasped(String),
    /// The object's origin is more than `above_m` above the table top.
    Lifted {
        /// The object.
        object: String,
        /// Height (m).
        above_m: f64,
    },
    /// The two objects' collision geoms touch; a side `object.part` means only the geoms of that
    /// object's parts named `part` (Coffee Preparation's `coffee_machine.base`, the plate the mug
    /// must stand on).
    Contact([String; 2]),
    /// `object`'s origin is within `xy_m` of `of`'s along world x and y (one bound for both, or
    /// `[x, y]`), and its height above `of`'s origin is within `dz_m` (robosuite's `on_peg`).
    Inside {
        /// The object.
        object: String,
        /// The one it should be in.
        of: String,
        /// The point of `of` it is measured from (m, `of`'s frame): a compartment of a bin.
        #[serde(default)]
        of_point_m: [f64; 3],
        /// Largest |dx| and |dy| (m).
        xy_m: XyBound,
        /// Range of z(object) - z(of) (m).
        #[serde(default = "any_height")]
        dz_m: [f64; 2],
    },
    /// A point of `object` is within `within_m` of a point of `of` (each in its object's frame;
    /// robosuite's threading check: the needle's middle inside the ring).
    Near {
        /// The object.
        object: String,
        /// The point on it (m, its frame).
        #[serde(default)]
        point_m: [f64; 3],
        /// The other object.
        of: String,
        /// The point on that one (m, its frame).
        #[serde(default)]
        of_point_m: [f64; 3],
        /// Distance (m).
        within_m: f64,
    },
    /// A hinge or slide joint of the scene (`coffee_machine_hinge`) reads within `[min, max]` (deg for a
    /// hinge).
    Joint {
        /// MuJoCo joint name.
        joint: String,
        /// Lower bound.
        #[serde(default = "minus_infinity")]
        min: f64,
        /// Upper bound.
        #[serde(default = "plus_infinity")]
        max: f64,
    },
    /// `object`'s yaw matches `with`'s within `tolerance_deg`, modulo `symmetry_deg`.
    Aligned {
        /// The object.
        object: String,
        /// The one it should be turned like.
        with: String,
        /// Tolerance (deg).
        tolerance_deg: f64,
        /// The object's yaw symmetry (deg): 90 for a square.
        #[serde(default = "full_turn")]
        symmetry_deg: f64,
    },
    /// `object`'s origin is at least `min_m` from `from`'s.
    Apart {
        /// The object (or `eef`).
        object: String,
        /// The other (or `eef`).
        from: String,
        /// Distance (m).
        min_m: f64,
    },
    /// `object`'s z axis is within `tolerance_deg` of the world's vertical (robosuite's
    /// `z_axis[2] > cos(tolerance)`: a mug standing in a drawer).
    Upright {
        /// The object.
        object: String,
        /// Largest tilt (deg).
        tolerance_deg: f64,
    },
    /// `object` moves slower than `max_speed_m_s`.
    AtRest {
        /// The object.
        object: String,
        /// Speed (m/s).
        max_speed_m_s: f64,
    },
    /// It held at some step since the episode's reset (robosuite's history flags, e.g. Kitchen's
    /// "the stove was on with the pot on it and the bread in the pot"). The environment checks it
    /// after every step.
    Ever(Box<Predicate>),
    /// Every one holds.
    All(Vec<Predicate>),
    /// At least one holds.
    Any(Vec<Predicate>),
    /// It does not hold.
    Not(Box<Predicate>),
}

/// A bound on |dx| and |dy| (m): one number for both, or `[x, y]`.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(untagged)]
pub enum XyBound {
    /// The same bound along x and y.
    Both(f64),
    /// `[x, y]`.
    PerAxis([f64; 2]),
}

impl XyBound {
    /// Whether `|dx|` and `|dy|` are both under their bounds.
    #[must_use]
    pub fn holds(self, dx: f64, dy: f64) -> bool {
        let [x, y] = match self {
            Self::Both(both) => [both; 2],
            Self::PerAxis(per_axis) => per_axis,
        };
        dx.abs() < x && dy.abs() < y
    }
}

fn any_height() -> [f64; 2] {
    [f64::NEG_INFINITY, f64::INFINITY]
}

fn minus_infinity() -> f64 {
    f64::NEG_INFINITY
}

fn plus_infinity() -> f64 {
    f64::INFINITY
}

fn full_turn() -> f64 {
    360.0
}

/// One term of the object observation, optionally only in some variants.
#[derive(Debug, Clone, PartialEq, Deserialize)]
pub struct ObsEntry {
    /// What it observes.
    #[serde(flatten)]
    pub term: ObsTerm,
    /// The variants that have it; all when empty.
    #[serde(default)]
    pub variants: Vec<String>,
}

/// robosuite's object observables.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ObsTerm {
    /// Position and `xyzw` quaternion (MuJoCo's own, so its sign matches robosuite's): 7 values.
    Pose(String),
    /// Position: 3 values.
    Position(String),
    /// Object position minus the grip site's: 3 values.
    FromEef(String),
    /// Grip site position minus the object's: 3 values.
    ToEef(String),
    /// Second object's position minus the first's: 3 values.
    Between([String; 2]),
    /// The object's pose in the gripper frame (grip site position, hand orientation), position
    /// and `xyzw` quaternion with w >= 0: 7 values.
    InGripper(String),
    /// A joint's position (rad for a hinge): 1 value.
    Joint(String),
}

impl TaskFile {
    /// Parses and checks a task file; `origin` names it in errors.
    ///
    /// # Errors
    /// A message naming `origin` and the field: TOML that does not parse, a name that is not one
    /// of the objects, a variant without a placement for some object, an empty range.
    pub fn from_toml_str(text: &str, origin: &str) -> Result<Self, String> {
        let file: Self = toml::from_str(text).map_err(|e| format!("{origin}: {e}"))?;
        file.check().map_err(|e| format!("{origin}: {e}"))?;
        Ok(file)
    }

    fn check(&self) -> Result<(), String> {
        if self.variants.is_empty() {
            return Err("field `variants`: a task needs at least one variant".to_owned());
        }
        let objects = self.object_names().join(", ");
        // `eef` (the gripper) stands for a position only; an object's own state (its grasp,
        // contacts, pose, speed, placement) needs an object.
        let known = |(name, eef_ok): (&str, bool), field: &str| -> Result<(), String> {
            if name == "eef" && !eef_ok {
                Err(format!(
                    "field `{field}` names \"eef\", which only a position may name (lifted, inside, apart, position, from_eef, to_eef, between); here name one of the objects: {objects}"
                ))
            } else if self.objects.iter().any(|o| o.name == name && !o.variants.is_empty()) {
                Err(format!("field `{field}` names object {name:?}, which only some variants have (its `variants`)"))
            } else if name == "eef" || self.objects.iter().any(|o| o.name == name) {
                Ok(())
            } else {
                Err(format!("field `{field}` names object {name:?}, which is not one of {objects}"))
            }
        };
        if let Some(base) = &self.mobile_base {
            base.check()?;
        }
        if !self.robot_offset_m.iter().all(|v| v.is_finite() && v.abs() < 1.0) {
            return Err(format!("field `robot_offset_m` {:?} must be finite and within 1 m", self.robot_offset_m));
        }
        for object in &self.objects {
            let q = object.init_quat;
            if !(q.iter().all(|c| c.is_finite()) && q.iter().map(|c| c * c).sum::<f64>() > 1e-6) {
                return Err(format!("object {:?}: `init_quat` {q:?} is not a rotation (w, x, y, z; finite, not zero)", object.name));
            }
            if let Some(v) = object.variants.iter().find(|v| !self.variants.contains(v)) {
                return Err(format!("object {:?}: `variants` names {v}, which the task does not have", object.name));
            }
            for variant in self.variants.iter().filter(|v| object.variants.is_empty() || object.variants.contains(v)) {
                let region = object
                    .place
                    .get(variant)
                    .ok_or_else(|| format!("object {:?} has no `place.{variant}` for variant {variant}", object.name))?;
                if [region.x, region.y, region.yaw_deg].iter().any(|[lo, hi]| lo > hi || !lo.is_finite() || !hi.is_finite()) {
                    return Err(format!("object {:?}: `place.{variant}` has a range whose ends are not finite and ordered", object.name));
                }
            }
            if !(object.height_m.is_finite() && object.radius_m.is_finite()) {
                return Err(format!("object {:?}: `height_m` and `radius_m` must be finite", object.name));
            }
            for model in std::iter::once(&object.model).chain(object.instances.iter().map(|i| &i.model)) {
                if let Some(what) = model_numbers_not_finite(model) {
                    return Err(format!("object {:?}: {what} must be finite", object.name));
                }
                if let ObjectModel::Compound { hinge: Some(h), .. } = model {
                    if let Some([low, high]) = h.range_deg
                        && !(low.is_finite() && high.is_finite() && low <= h.start_deg && h.start_deg <= high && low < high)
                    {
                        return Err(format!(
                            "object {:?}: `hinge.range_deg` [{low}, {high}] must be finite, ordered and hold `start_deg` {} (where the part starts)",
                            object.name, h.start_deg
                        ));
                    }
                    // Finite already (model_numbers_not_finite); here the signs.
                    if h.damping < 0.0 || h.frictionloss < 0.0 || !h.inertial.as_deref().is_none_or(inertial_signs_hold) {
                        return Err(format!(
                            "object {:?}: `hinge` needs a finite `start_deg`, `damping` and `frictionloss` >= 0, and an `inertial` with a positive mass and inertia and a non-zero `quat`",
                            object.name
                        ));
                    }
                }
                if let ObjectModel::Compound { slide: Some(slide), .. } = model
                    && !slide.inertial.as_deref().is_none_or(inertial_signs_hold)
                {
                    return Err(format!(
                        "object {:?}: `slide.inertial` needs a positive mass and inertia and a non-zero `quat`",
                        object.name
                    ));
                }
                if let ObjectModel::Compound { geoms, fixed: false, .. } = model
                    && geoms.iter().all(|g| g.visual)
                {
                    return Err(format!(
                        "object {:?}: a free object needs a geom that is not `visual` (it would have no mass)",
                        object.name
                    ));
                }
            }
            if let Some(extra) = object.place.keys().find(|v| !self.variants.contains(v)) {
                return Err(format!("object {:?} has `place.{extra}` but the variants are {}", object.name, self.variants.join(", ")));
            }
            for instance in &object.instances {
                if let Some(v) = instance.variants.iter().find(|v| !self.variants.contains(v)) {
                    return Err(format!(
                        "object {:?}: instance {:?} names variant {v}, which the task does not have",
                        object.name, instance.label
                    ));
                }
                if instance.model.body_name() != object.model.body_name() {
                    return Err(format!(
                        "object {:?}: instance {:?} must name its model {:?} like the object's (its body stands in for the object's)",
                        object.name,
                        instance.label,
                        object.model.body_name().trim_end_matches("_main")
                    ));
                }
            }
        }
        for variant in &self.variants {
            // Each combination of instances is a scene compiled once per worker.
            let combinations: usize =
                self.objects.iter().map(|o| o.instances.iter().filter(|i| i.variants.contains(variant)).count().max(1)).product();
            if combinations > MAX_INSTANCE_SCENES {
                return Err(format!(
                    "variant {variant}: its objects' instances make {combinations} scenes, more than {MAX_INSTANCE_SCENES}"
                ));
            }
        }
        let labels: Vec<&str> = self.objects.iter().flat_map(|o| o.instances.iter().map(|i| i.label.as_str())).collect();
        if let Some(label) = labels.iter().find(|l| l.contains('+') || labels.iter().filter(|m| m == l).count() > 1) {
            return Err(format!(
                "instance label {label:?} must be unique in the task and have no `+` (it joins the labels of a combination)"
            ));
        }
        for name in &self.place_order {
            if !self.objects.iter().any(|o| &o.name == name) {
                return Err(format!("field `place_order` names object {name:?}, which is not one of {objects}"));
            }
        }
        if !self.place_order.is_empty() && self.place_order.len() != self.objects.len() {
            return Err("field `place_order` must list every object once".to_owned());
        }
        for (signal, predicate) in &self.signals {
            predicate.names().into_iter().try_for_each(|n| known(n, &format!("signals.{signal}")))?;
        }
        self.success.names().into_iter().try_for_each(|n| known(n, "success"))?;
        let fields = self.signals.iter().map(|(signal, p)| (format!("signals.{signal}"), p)).chain([("success".to_owned(), &self.success)]);
        for (field, predicate) in fields {
            for (object, part) in predicate.contact_parts() {
                if !self.objects.iter().any(|o| o.name == object && o.model.has_part(part)) {
                    return Err(format!(
                        "field `{field}` touches {object}.{part}, but object {object:?} has no part named {part:?} (a compound part's `name`)"
                    ));
                }
            }
        }
        for entry in &self.observation {
            entry.term.names().into_iter().try_for_each(|n| known(n, "observation"))?;
            if let Some(v) = entry.variants.iter().find(|v| !self.variants.contains(v)) {
                return Err(format!("an `observation` term names variant {v}, which the task does not have"));
            }
        }
        for script in &self.scripts {
            if script.path_on.is_empty() {
                known((&script.pick, false), "script.pick")?;
                known((&script.place_on, false), "script.place_on")?;
            } else if !script.pick.is_empty() || !script.place_on.is_empty() || script.path_m.is_empty() {
                return Err("a `script` with `path_on` is a path: give it `path_m` and no `pick` or `place_on`".to_owned());
            } else {
                known((&script.path_on, false), "script.path_on")?;
            }
        }
        Ok(())
    }

    /// `(field, joint)` of every joint its predicates and observation terms read.
    pub(crate) fn joints_read(&self) -> Vec<(String, String)> {
        let mut read: Vec<(String, String)> = Vec::new();
        let mut add = |field: String, joints: Vec<&str>| read.extend(joints.into_iter().map(|j| (field.clone(), j.to_owned())));
        for (signal, predicate) in &self.signals {
            add(format!("signals.{signal}"), predicate.joints());
        }
        add("success".to_owned(), self.success.joints());
        for entry in &self.observation {
            add("observation".to_owned(), entry.term.joints());
        }
        read
    }

    fn object_names(&self) -> Vec<&str> {
        self.objects.iter().map(|o| o.name.as_str()).collect()
    }

    /// The object indices in placement order.
    pub(crate) fn placement_order(&self) -> Vec<usize> {
        if self.place_order.is_empty() {
            return (0..self.objects.len()).collect();
        }
        self.place_order.iter().filter_map(|n| self.objects.iter().position(|o| &o.name == n)).collect()
    }
}

impl Predicate {
    /// What it asks, in words (`coffee_pod in coffee_machine`), for failure reports.
    pub(crate) fn words(&self) -> String {
        let list = |all: &[Self], sep: &str| all.iter().map(Self::words).collect::<Vec<_>>().join(sep);
        match self {
            Self::Grasped(o) => format!("{o} grasped"),
            Self::Lifted { object, above_m } => format!("{object} lifted {above_m:.3} m"),
            Self::Contact([a, b]) => format!("{a} touching {b}"),
            Self::Inside { object, of, .. } => format!("{object} in {of}"),
            Self::Near { object, of, .. } => format!("{object} at {of}"),
            Self::Joint { joint, min, max } => format!("{joint} in [{min}, {max}]"),
            Self::Aligned { object, with, .. } => format!("{object} turned like {with}"),
            Self::Apart { object, from, min_m } => format!("{object} at least {min_m:.3} m from {from}"),
            Self::AtRest { object, .. } => format!("{object} at rest"),
            Self::Upright { object, .. } => format!("{object} upright"),
            Self::Ever(p) => format!("once ({})", p.words()),
            Self::All(all) => list(all, " and "),
            Self::Any(all) => format!("any of ({})", list(all, ", ")),
            Self::Not(p) => format!("not ({})", p.words()),
        }
    }

    /// The joint names it reads.
    fn joints(&self) -> Vec<&str> {
        match self {
            Self::Joint { joint, .. } => vec![joint],
            Self::All(all) | Self::Any(all) => all.iter().flat_map(Self::joints).collect(),
            Self::Not(p) | Self::Ever(p) => p.joints(),
            _ => Vec::new(),
        }
    }

    /// The `(object, part)` of every `object.part` side of its contacts.
    fn contact_parts(&self) -> Vec<(&str, &str)> {
        match self {
            Self::Contact(sides) => sides.iter().filter_map(|side| side.split_once('.')).collect(),
            Self::All(all) | Self::Any(all) => all.iter().flat_map(Self::contact_parts).collect(),
            Self::Not(p) | Self::Ever(p) => p.contact_parts(),
            _ => Vec::new(),
        }
    }

    /// The object names it refers to, each with whether `eef` (the gripper) may stand there:
    /// where a position is read, not an object's own state (grasp, contacts, pose, speed).
    fn names(&self) -> Vec<(&str, bool)> {
        match self {
            Self::Grasped(o) | Self::AtRest { object: o, .. } | Self::Upright { object: o, .. } => vec![(o, false)],
            Self::Joint { .. } => Vec::new(),
            Self::Lifted { object, .. } => vec![(object, true)],
            Self::Contact(sides) => sides.iter().map(|side| (side.split_once('.').map_or(side.as_str(), |(o, _)| o), false)).collect(),
            Self::Near { object, of: other, .. } | Self::Aligned { object, with: other, .. } => vec![(object, false), (other, false)],
            Self::Inside { object, of: other, .. } | Self::Apart { object, from: other, .. } => vec![(object, true), (other, true)],
            Self::All(all) | Self::Any(all) => all.iter().flat_map(Self::names).collect(),
            Self::Not(p) | Self::Ever(p) => p.names(),
        }
    }
}

impl ObsTerm {
    fn joints(&self) -> Vec<&str> {
        match self {
            Self::Joint(joint) => vec![joint],
            _ => Vec::new(),
        }
    }

    /// As [`Predicate::names`]: `eef` may stand where a position is read.
    fn names(&self) -> Vec<(&str, bool)> {
        match self {
            Self::Pose(o) | Self::InGripper(o) => vec![(o, false)],
            Self::Position(o) | Self::FromEef(o) | Self::ToEef(o) => vec![(o, true)],
            Self::Joint(_) => Vec::new(),
            Self::Between([a, b]) => vec![(a, true), (b, true)],
        }
    }
}

/// Every number of a hinged or sliding part's given mass and inertia is finite.
fn inertial_finite(i: &crate::compose::Inertial) -> bool {
    [i.pos.as_slice(), &i.quat, &[i.mass], &i.diaginertia].iter().all(|v| v.iter().all(|x| x.is_finite()))
}

/// A given mass and inertia MuJoCo accepts: positive mass and principal moments, a turn.
fn inertial_signs_hold(i: &crate::compose::Inertial) -> bool {
    i.quat.iter().any(|v| *v != 0.0) && i.mass > 0.0 && i.diaginertia.iter().all(|v| *v > 0.0)
}

/// The first number of `model` that is not finite (a NaN size, a NaN `base_m`), named as the
/// task file names it; `None` if every number is finite.
fn model_numbers_not_finite(model: &ObjectModel) -> Option<String> {
    let finite = |v: &[f64]| v.iter().all(|x| x.is_finite());
    let parts = |field: &str, parts: &[crate::compose::Part]| {
        parts.iter().enumerate().find_map(|(i, p)| {
            let numbers = [p.yaw_deg, p.roll_deg, p.density.unwrap_or(1.0), p.margin.unwrap_or_default()];
            let contact = finite(&p.friction.unwrap_or_default()) && finite(&p.solref.unwrap_or_default());
            (!(finite(&p.size) && finite(&p.pos) && finite(&numbers) && contact))
                .then(|| format!("`{field}[{i}]`'s size, pos, yaw_deg, roll_deg, density, friction, solref and margin"))
        })
    };
    match model {
        ObjectModel::Mug { radius_m, height_m, wall_m, handle_m, base_m, handle_yaw_deg, density, friction, solref, margin, .. } => {
            let numbers = [*radius_m, *height_m, *wall_m, *handle_yaw_deg, *density, margin.unwrap_or_default()];
            let contact = finite(&friction.unwrap_or_default()) && finite(&solref.unwrap_or_default());
            (!(finite(&numbers) && finite(handle_m) && finite(base_m) && contact)).then(|| {
                "the mug's `radius_m`, `height_m`, `wall_m`, `handle_m`, `base_m`, `handle_yaw_deg`, `density`, `friction`, `solref` and `margin`"
                    .to_owned()
            })
        }
        ObjectModel::Compound { geoms, hinge, slide, .. } => parts("geoms", geoms)
            .or_else(|| {
                hinge.as_ref().and_then(|h| {
                    let numbers = [h.open_deg, h.start_deg, h.damping, h.frictionloss];
                    let inertial = h.inertial.as_deref().is_none_or(inertial_finite);
                    (!(finite(&h.pos) && finite(&h.axis) && finite(&numbers) && inertial))
                        .then(|| "`hinge.pos`, `hinge.axis`, `hinge.open_deg`, `hinge.start_deg`, `hinge.damping`, `hinge.frictionloss` and `hinge.inertial`".to_owned())
                })
            })
            .or_else(|| hinge.as_ref().and_then(|h| parts("hinge.geoms", &h.geoms)))
            .or_else(|| {
                slide.as_ref().and_then(|s| {
                    (!(finite(&s.axis) && s.travel_m.is_finite() && s.damping.is_finite() && s.inertial.as_deref().is_none_or(inertial_finite)))
                        .then(|| "`slide.axis`, `slide.travel_m`, `slide.damping` and `slide.inertial`".to_owned())
                })
            })
            .or_else(|| slide.as_ref().and_then(|s| parts("slide.geoms", &s.geoms))),
        _ => None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::DataTask;
    use crate::task::Task as _;

    const STACK: &str = include_str!("../tasks/stack.task.toml");

    #[test]
    fn bad_task_files_name_the_file_and_field() {
        let wrong_object = STACK.replace("grasped = \"cubeA\"", "grasped = \"cubeZ\"");
        let err = TaskFile::from_toml_str(&wrong_object, "my.task.toml").unwrap_err();
        assert!(err.contains("my.task.toml") && err.contains("signals.grasp") && err.contains("cubeZ"), "{err}");
        let missing_variant = STACK.replace("variants = [\"D0\", \"D1\", \"C0\"]", "variants = [\"D0\", \"D1\", \"C0\", \"D2\"]");
        let err = TaskFile::from_toml_str(&missing_variant, "my.task.toml").unwrap_err();
        assert!(err.contains("place.D2"), "{err}");
        let typo = STACK.replace("above_m", "abov_m");
        let err = TaskFile::from_toml_str(&typo, "my.task.toml").unwrap_err();
        assert!(err.contains("my.task.toml") && err.contains("abov_m"), "{err}");
        let file = TaskFile::from_toml_str(STACK, "stack").unwrap_or_else(|e| panic!("{e}"));
        assert!(DataTask::new(file.clone(), "D7").unwrap_err().contains("D0, D1 and C0"));
        // The clutter is in C0's scene only, and names only variants the task has.
        assert_eq!(DataTask::new(file.clone(), "D0").unwrap().file().objects.len(), 2);
        assert_eq!(DataTask::new(file, "C0").unwrap().file().objects.len(), 3);
        let unknown = STACK.replace("variants = [\"C0\"]", "variants = [\"C9\"]");
        let err = TaskFile::from_toml_str(&unknown, "my.task.toml").unwrap_err();
        assert!(err.contains("\"wall\"") && err.contains("C9"), "{err}");
        let named = STACK.replace("grasped = \"cubeA\"", "grasped = \"wall\"");
        let err = TaskFile::from_toml_str(&named, "my.task.toml").unwrap_err();
        assert!(err.contains("only some variants"), "{err}");
        let unturned = STACK.replacen("height_m = 0.03", "height_m = 0.03\ninit_quat = [0.0, 0.0, 0.0, 0.0]", 1);
        assert_ne!(unturned, STACK);
        let err = TaskFile::from_toml_str(&unturned, "my.task.toml").unwrap_err();
        assert!(err.contains("my.task.toml") && err.contains("\"cubeA\"") && err.contains("init_quat"), "{err}");
        let far = STACK.replacen("variants = ", "robot_offset_m = [0.1, nan]\nvariants = ", 1);
        let err = TaskFile::from_toml_str(&far, "my.task.toml").unwrap_err();
        assert!(err.contains("my.task.toml") && err.contains("robot_offset_m"), "{err}");
    }

    #[test]
    fn object_instances_belong_to_variants_and_stand_in_for_the_object() {
        let mugs = include_str!("../tasks/mug_cleanup.task.toml");
        let file = TaskFile::from_toml_str(mugs, "mug_cleanup").unwrap_or_else(|e| panic!("{e}"));
        let count = |variant: &str| DataTask::new(file.clone(), variant).map(|t| t.instances().len()).unwrap_or_default();
        assert_eq!([count("D0"), count("D1"), count("O1"), count("O2")], [0, 0, 1, 12]);
        // O1's scene is its instance's mug, not the sources' one.
        let o1 = DataTask::new(file.clone(), "O1").unwrap_or_else(|e| panic!("{e}"));
        let d0 = DataTask::new(file, "D0").unwrap_or_else(|e| panic!("{e}"));
        assert_ne!(o1.object_models()[0], d0.object_models()[0]);
        assert_eq!(o1.object_models()[1], d0.object_models()[1], "the cabinet is the same");
        let unknown = mugs.replacen("variants = [\"O1\", \"O2\"]", "variants = [\"O3\"]", 1);
        assert_ne!(unknown, mugs);
        let err = TaskFile::from_toml_str(&unknown, "my.task.toml").unwrap_err();
        assert!(err.contains("my.task.toml") && err.contains("bronze_slim") && err.contains("O3"), "{err}");
        let renamed = mugs.replacen(
            "label = \"red_round\"\nvariants = [\"O2\"]\nmodel = { kind = \"mug\", name = \"object\"",
            "label = \"red_round\"\nvariants = [\"O2\"]\nmodel = { kind = \"mug\", name = \"cup\"",
            1,
        );
        assert_ne!(renamed, mugs);
        let err = TaskFile::from_toml_str(&renamed, "my.task.toml").unwrap_err();
        assert!(err.contains("red_round") && err.contains("\"object\""), "{err}");
    }

    /// The error of `text` (a task file) with its first `from` replaced by `to`; the edit must
    /// change something and the file must be refused.
    fn refused_after(text: &str, from: &str, to: &str) -> String {
        let broken = text.replacen(from, to, 1);
        assert_ne!(broken, text, "no {from:?} to replace");
        TaskFile::from_toml_str(&broken, "my.task.toml").unwrap_err()
    }

    #[test]
    fn a_nan_in_a_model_is_named() {
        let mugs = include_str!("../tasks/mug_cleanup.task.toml");
        let err = refused_after(mugs, "base_m = [0.0, -0.0181, -0.0309]", "base_m = [0.0, nan, -0.0309]");
        assert!(err.contains("my.task.toml") && err.contains("\"object\"") && err.contains("base_m"), "{err}");
        let kitchen = include_str!("../tasks/kitchen.task.toml");
        let err = refused_after(kitchen, "size = [0.043, 0.053, 0.005]", "size = [0.043, nan, 0.005]");
        assert!(err.contains("\"pot\"") && err.contains("`geoms[0]`"), "{err}");
        let err = refused_after(kitchen, "damping = 0.1", "damping = nan");
        assert!(err.contains("\"button\"") && err.contains("hinge.damping"), "{err}");
    }

    #[test]
    fn a_hinge_s_start_joint_and_mass_are_checked() {
        let kitchen = include_str!("../tasks/kitchen.task.toml");
        TaskFile::from_toml_str(kitchen, "kitchen").unwrap_or_else(|e| panic!("{e}"));
        for (from, to, names) in [
            ("start_deg = -17.188733853924695", "start_deg = -20.0", "start_deg"),
            ("frictionloss = 0.1", "frictionloss = -0.1", "frictionloss"),
            ("mass = 0.243455", "mass = 0.0", "inertial"),
            ("quat = [0.701072, 0.0, 0.0, 0.713091]", "quat = [0.0, 0.0, 0.0, 0.0]", "inertial"),
        ] {
            let err = refused_after(kitchen, from, to);
            assert!(err.contains("my.task.toml") && err.contains("\"button\"") && err.contains(names), "{to}: {err}");
        }
        // A free object drawn only would have no mass.
        let err = refused_after(
            kitchen,
            "geoms = [{ type = \"box\", size = [0.015, 0.025, 0.02], density = 500.0 }]",
            "geoms = [{ type = \"box\", size = [0.015, 0.025, 0.02], density = 500.0, visual = true }]",
        );
        assert!(err.contains("\"bread\"") && err.contains("visual"), "{err}");
    }

    #[test]
    fn a_hinge_range_must_hold_where_the_part_starts() {
        let coffee = include_str!("../tasks/coffee_preparation.task.toml");
        let file = TaskFile::from_toml_str(coffee, "coffee_preparation").unwrap_or_else(|e| panic!("{e}"));
        let range = |model: &ObjectModel| match model {
            ObjectModel::Compound { hinge: Some(h), .. } => h.range_deg,
            _ => None,
        };
        assert_eq!(file.objects.iter().find_map(|o| range(&o.model)), Some([0.0, 120.0]), "the lid opens by 120 deg (the reference's)");
        for bad in ["[5.0, 100.0]", "[100.0, 0.0]", "[0.0, nan]"] {
            let err = refused_after(coffee, "range_deg = [0.0, 120.0]", &format!("range_deg = {bad}"));
            assert!(err.contains("my.task.toml") && err.contains("\"coffee_machine\"") && err.contains("hinge.range_deg"), "{bad}: {err}");
        }
    }

    #[test]
    fn a_slide_s_inertial_is_checked_as_a_hinge_s() {
        let coffee = include_str!("../tasks/coffee_preparation.task.toml");
        for (to, what) in [
            ("mass = -7.85398", "slide.inertial"),
            ("mass = nan", "slide.inertial"),
            ("quat = [0.0, 0.0, 0.0, 0.0], mass = 7.85398", "slide.inertial"),
        ] {
            let from = if to.starts_with("quat") { "quat = [0.5, 0.5, 0.5, 0.5], mass = 7.85398" } else { "mass = 7.85398" };
            let err = refused_after(coffee, from, to);
            assert!(err.contains("my.task.toml") && err.contains("\"drawer\"") && err.contains(what), "{to}: {err}");
        }
    }

    #[test]
    fn a_contact_may_name_a_part_the_object_has() {
        let coffee = include_str!("../tasks/coffee_preparation.task.toml");
        let file = TaskFile::from_toml_str(coffee, "coffee_preparation").unwrap_or_else(|e| panic!("{e}"));
        let plate = file.objects.iter().find(|o| o.name == "coffee_machine").map(|o| o.model.has_part("base"));
        assert_eq!(plate, Some(true), "the machine's base plate is named");
        // A part no object has, and a part of another object, are refused with the field.
        for (side, object) in [("coffee_machine.plate", "coffee_machine"), ("drawer.base", "drawer")] {
            let err = refused_after(
                coffee,
                "contact = [\"mug\", \"coffee_machine.base\"] }, { upright",
                &format!("contact = [\"mug\", \"{side}\"] }}, {{ upright"),
            );
            assert!(err.contains("signals.mug_place") && err.contains(&format!("object \"{object}\" has no part named")), "{side}: {err}");
        }
        let err =
            refused_after(coffee, "{ contact = [\"mug\", \"coffee_machine.base\"] },\n", "{ contact = [\"mug\", \"kettle.base\"] },\n");
        assert!(err.contains("`success` names object \"kettle\""), "{err}");
    }

    #[test]
    fn eef_is_refused_where_an_object_is_needed_and_kept_where_a_position_is() {
        let grasped = STACK.replace("grasped = \"cubeA\"", "grasped = \"eef\"");
        let err = TaskFile::from_toml_str(&grasped, "my.task.toml").unwrap_err();
        assert!(err.starts_with("my.task.toml: field `signals.grasp` names \"eef\""), "{err}");
        assert!(err.contains("cubeA, cubeB"), "{err}");
        let contact = STACK.replace("contact = [\"cubeA\", \"cubeB\"]", "contact = [\"cubeA\", \"eef\"]");
        assert_ne!(contact, STACK);
        assert!(TaskFile::from_toml_str(&contact, "my.task.toml").unwrap_err().contains("`success` names \"eef\""));
        // Where a position is read, eef is the gripper's.
        let lifted = STACK.replace("lifted = { object = \"cubeA\"", "lifted = { object = \"eef\"");
        assert_ne!(lifted, STACK);
        TaskFile::from_toml_str(&lifted, "my.task.toml").unwrap_or_else(|e| panic!("{e}"));
    }
}
