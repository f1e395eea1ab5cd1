//! The arms a scene can have, each as robosuite 1.4.1 builds it: its base scene (table arena, the
//! arm on its mount, its default gripper; `viewer_assets/scenes/<name>_table.xml`, written from
//! robosuite by `scripts/make_robot_scene.py`), the names of its joints, actuators and finger
//! pads, its home posture (`init_qpos`), and how its gripper takes the open/close action.
//!
//! Generated end-effector poses do not depend on the arm, so source demos recorded with one arm
//! generate data for another (the paper's robot transfer).

/// An arm with its gripper, named as robosuite names them.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RobotModel {
    /// Name on the command line (`panda`).
    pub name: &'static str,
    /// robosuite's name (`env_args.env_kwargs.robots`).
    pub robosuite_name: &'static str,
    /// How well it generates from the bundled Panda demos (`mimicgen tasks` prints it).
    pub status: &'static str,
    /// The base scene, with `{ASSETS}` and the object markers.
    pub base_xml: &'static str,
    /// The arm's joints, base to wrist (seven, or six for the UR5e).
    pub arm_joints: &'static [&'static str],
    /// The torque actuator of each arm joint.
    pub arm_actuators: &'static [&'static str],
    /// robosuite's home posture.
    pub init_qpos: &'static [f64],
    /// The gripper's joints (observed as `robot0_gripper_qpos`).
    pub finger_joints: &'static [&'static str],
    /// The gripper's actuators, in robosuite's order.
    pub finger_actuators: [&'static str; 2],
    /// The gripper joints' positions at reset.
    pub finger_init_qpos: &'static [f64],
    /// Per actuator, the direction its command moves on "close" (robosuite's `format_action`).
    pub close_direction: [f64; 2],
    /// Left and right finger pad collision geoms (robosuite's grasp check).
    pub finger_pads: [&'static str; 2],
    /// What the simulation changes in robosuite's model so that it behaves under MuJoCo 3 as it
    /// does under robosuite 1.4.1's MuJoCo 2.3 (datasets keep robosuite's XML).
    pub sim_patch: SimPatch,
}

/// Simulation-only changes to an arm's model, each one measured against robosuite's behaviour.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SimPatch {
    /// Body pairs whose contacts are excluded.
    pub contact_excludes: &'static [(&'static str, &'static str)],
    /// Passive joints that follow a driven one.
    pub couplings: &'static [Coupling],
    /// Attributes set on named MJCF elements: `(element, name, attribute, value)`, e.g. a
    /// joint's damping, a limit lifted, a tendon's spring or equality switched off.
    pub attributes: &'static [(&'static str, &'static str, &'static str, &'static str)],
}

/// `joint = offset + slope * driver` (radians), held by an equality constraint.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Coupling {
    /// The passive joint.
    pub joint: &'static str,
    /// The joint it follows.
    pub driver: &'static str,
    /// Its position when the driver is at zero.
    pub offset: f64,
    /// Radians it turns per radian of the driver.
    pub slope: f64,
}

const NO_PATCH: SimPatch = SimPatch { contact_excludes: &[], couplings: &[], attributes: &[] };

/// robosuite's Robotiq 85 and 140 close their linkages by contacts between each side's inner
/// finger and inner knuckle meshes (and the outer finger), 6 to 14 mm deep under MuJoCo 2.3 and
/// holding joints outside their own ranges. MuJoCo 3 makes three or four shallower contacts per
/// pair instead of one: the 85's linkage sags 0.2 rad open and its pads never reach an object, the
/// 140's fingers chatter while closed. Patched, the linkage follows each side's driven knuckle as
/// robosuite's does (couplings fitted to robosuite's joints from open to closed under MuJoCo 2.3,
/// `scripts/robotiq_linkage.py`), without those contacts and the tendons robosuite adds to them,
/// and the driven knuckles are damped as the contacts damped them.
const ROBOTIQ_LINKAGE_CONTACTS: &[(&str, &str)] = &[
    ("gripper0_left_inner_finger", "gripper0_left_inner_knuckle"),
    ("gripper0_left_outer_knuckle", "gripper0_left_inner_knuckle"),
    ("gripper0_right_inner_finger", "gripper0_right_inner_knuckle"),
    ("gripper0_right_outer_knuckle", "gripper0_right_inner_knuckle"),
];

/// `Coupling` for one side of a Robotiq linkage.
const fn follows(joint: &'static str, driver: &'static str, offset: f64, slope: f64) -> Coupling {
    Coupling { joint, driver, offset, slope }
}

/// The arm's torque actuators as robosuite names them for the Panda and the IIWA.
const TORQUE_ACTUATORS: &[&str] =
    &["robot0_torq_j1", "robot0_torq_j2", "robot0_torq_j3", "robot0_torq_j4", "robot0_torq_j5", "robot0_torq_j6", "robot0_torq_j7"];

/// The Franka Panda with its gripper: the arm of the paper's source demos and of ours.
pub const PANDA: RobotModel = RobotModel {
    name: "panda",
    robosuite_name: "Panda",
    status: "the arm of the bundled source demos",
    base_xml: include_str!("../../../viewer_assets/scenes/panda_table.xml"),
    arm_joints: &["robot0_joint1", "robot0_joint2", "robot0_joint3", "robot0_joint4", "robot0_joint5", "robot0_joint6", "robot0_joint7"],
    arm_actuators: TORQUE_ACTUATORS,
    init_qpos: &[
        0.0,
        std::f64::consts::PI / 16.0,
        0.0,
        -std::f64::consts::PI / 2.0 - std::f64::consts::PI / 3.0,
        0.0,
        std::f64::consts::PI - 0.2,
        std::f64::consts::PI / 4.0,
    ],
    finger_joints: &["gripper0_finger_joint1", "gripper0_finger_joint2"],
    finger_actuators: ["gripper0_gripper_finger_joint1", "gripper0_gripper_finger_joint2"],
    finger_init_qpos: &[0.020833, -0.020833],
    close_direction: [-1.0, 1.0],
    finger_pads: ["gripper0_finger1_pad_collision", "gripper0_finger2_pad_collision"],
    sim_patch: NO_PATCH,
};

/// Rethink Robotics' Sawyer with robosuite's Rethink gripper.
pub const SAWYER: RobotModel = RobotModel {
    name: "sawyer",
    robosuite_name: "Sawyer",
    status: "Square D0 / D1 79.0 / 78.0 % (paper 55.8 / 38.8)",
    base_xml: include_str!("../../../viewer_assets/scenes/sawyer_table.xml"),
    arm_joints: &[
        "robot0_right_j0",
        "robot0_right_j1",
        "robot0_right_j2",
        "robot0_right_j3",
        "robot0_right_j4",
        "robot0_right_j5",
        "robot0_right_j6",
    ],
    arm_actuators: &[
        "robot0_torq_right_j0",
        "robot0_torq_right_j1",
        "robot0_torq_right_j2",
        "robot0_torq_right_j3",
        "robot0_torq_right_j4",
        "robot0_torq_right_j5",
        "robot0_torq_right_j6",
    ],
    init_qpos: &[0.0, -1.18, 0.0, 2.18, 0.0, 0.57, -1.57],
    finger_joints: &["gripper0_l_finger_joint", "gripper0_r_finger_joint"],
    finger_actuators: ["gripper0_gripper_r_finger_joint", "gripper0_gripper_l_finger_joint"],
    finger_init_qpos: &[0.020833, -0.020833],
    close_direction: [1.0, -1.0],
    finger_pads: ["gripper0_l_fingerpad_g0", "gripper0_r_fingerpad_g0"],
    // The first link's collision sphere rests exactly on the base's cylinder: in MuJoCo 3 that
    // contact's friction holds joint 0 back (3.7 N m at rest), which robosuite's arm never feels.
    sim_patch: SimPatch { contact_excludes: &[("robot0_right_arm_base_link", "robot0_right_l0")], ..NO_PATCH },
};

/// KUKA's LBR IIWA 7 with robosuite's Robotiq 140 gripper (six coupled joints, two actuators).
pub const IIWA: RobotModel = RobotModel {
    name: "iiwa",
    robosuite_name: "IIWA",
    status: "Square D0 / D1 32.9 / 38.2 % (paper 37.7 / 26.5)",
    base_xml: include_str!("../../../viewer_assets/scenes/iiwa_table.xml"),
    arm_joints: &[
        "robot0_joint_1",
        "robot0_joint_2",
        "robot0_joint_3",
        "robot0_joint_4",
        "robot0_joint_5",
        "robot0_joint_6",
        "robot0_joint_7",
    ],
    arm_actuators: TORQUE_ACTUATORS,
    init_qpos: &[0.0, 0.65, 0.0, -1.89, 0.0, 0.6, 0.0],
    finger_joints: &[
        "gripper0_finger_joint",
        "gripper0_left_inner_finger_joint",
        "gripper0_left_inner_knuckle_joint",
        "gripper0_right_outer_knuckle_joint",
        "gripper0_right_inner_finger_joint",
        "gripper0_right_inner_knuckle_joint",
    ],
    finger_actuators: ["gripper0_finger_1", "gripper0_finger_2"],
    finger_init_qpos: &[0.012, 0.065, 0.065, -0.012, 0.065, 0.065],
    close_direction: [1.0, -1.0],
    finger_pads: ["gripper0_left_fingerpad_collision", "gripper0_right_fingerpad_collision"],
    // See ROBOTIQ_LINKAGE_CONTACTS. robosuite's own 140 is not symmetric: its left inner finger
    // turns 0.24 rad on closing, its right one stays put.
    sim_patch: SimPatch {
        contact_excludes: ROBOTIQ_LINKAGE_CONTACTS,
        couplings: &[
            follows("gripper0_left_inner_knuckle_joint", "gripper0_finger_joint", 0.0727, -0.893),
            follows("gripper0_left_inner_finger_joint", "gripper0_finger_joint", 0.0565, 0.515),
            follows("gripper0_right_inner_knuckle_joint", "gripper0_right_outer_knuckle_joint", 0.0722, 0.832),
            follows("gripper0_right_inner_finger_joint", "gripper0_right_outer_knuckle_joint", 0.034, -0.014),
        ],
        attributes: &[
            ("joint", "gripper0_finger_joint", "damping", "1"),
            ("joint", "gripper0_finger_joint", "armature", "0.001"),
            ("joint", "gripper0_right_outer_knuckle_joint", "damping", "1"),
            ("joint", "gripper0_right_outer_knuckle_joint", "armature", "0.001"),
            // robosuite's tendon equalities, which the couplings replace.
            ("tendon", "gripper0_finger2_12_cpl", "active", "false"),
            ("tendon", "gripper0_finger2_23_cpl", "active", "false"),
            ("tendon", "gripper0_finger1_12_cpl", "active", "false"),
            ("tendon", "gripper0_finger1_23_cpl", "active", "false"),
        ],
    },
};

/// Universal Robots' UR5e (six joints) with robosuite's Robotiq 85 gripper, whose two actuators
/// take the same command (robosuite broadcasts its one-number action to both).
pub const UR5E: RobotModel = RobotModel {
    name: "ur5e",
    robosuite_name: "UR5e",
    status: "Square D0 / D1 77.0 / 72.6 % (paper 64.7 / 34.1)",
    base_xml: include_str!("../../../viewer_assets/scenes/ur5e_table.xml"),
    arm_joints: &[
        "robot0_shoulder_pan_joint",
        "robot0_shoulder_lift_joint",
        "robot0_elbow_joint",
        "robot0_wrist_1_joint",
        "robot0_wrist_2_joint",
        "robot0_wrist_3_joint",
    ],
    arm_actuators: TORQUE_ACTUATORS.split_at(6).0,
    init_qpos: &[-0.470, -1.735, 2.480, -2.275, -1.590, -1.991],
    finger_joints: IIWA.finger_joints,
    finger_actuators: IIWA.finger_actuators,
    finger_init_qpos: &[-0.026, -0.267, -0.200, -0.026, -0.267, -0.200],
    close_direction: [1.0, 1.0],
    finger_pads: IIWA.finger_pads,
    // See ROBOTIQ_LINKAGE_CONTACTS.
    sim_patch: SimPatch {
        contact_excludes: ROBOTIQ_LINKAGE_CONTACTS,
        couplings: &[
            follows("gripper0_left_inner_knuckle_joint", "gripper0_finger_joint", -0.175, 0.849),
            follows("gripper0_left_inner_finger_joint", "gripper0_finger_joint", -0.278, 0.118),
            follows("gripper0_right_inner_knuckle_joint", "gripper0_right_outer_knuckle_joint", -0.175, 0.849),
            follows("gripper0_right_inner_finger_joint", "gripper0_right_outer_knuckle_joint", -0.278, 0.116),
        ],
        attributes: &[
            // robosuite's closed stop (its contacts held the knuckles there): 0.50 rad.
            ("joint", "gripper0_finger_joint", "range", "-0.028 0.5"),
            ("joint", "gripper0_finger_joint", "solreflimit", "0.004 1"),
            ("joint", "gripper0_finger_joint", "damping", "1"),
            ("joint", "gripper0_finger_joint", "armature", "0.001"),
            ("joint", "gripper0_right_outer_knuckle_joint", "range", "-0.028 0.5"),
            ("joint", "gripper0_right_outer_knuckle_joint", "solreflimit", "0.004 1"),
            ("joint", "gripper0_right_outer_knuckle_joint", "damping", "1"),
            ("joint", "gripper0_right_outer_knuckle_joint", "armature", "0.001"),
            // robosuite's rest posture lies outside these joints' ranges.
            ("joint", "gripper0_left_inner_knuckle_joint", "limited", "false"),
            ("joint", "gripper0_left_inner_finger_joint", "limited", "false"),
            ("joint", "gripper0_right_inner_knuckle_joint", "limited", "false"),
            ("joint", "gripper0_right_inner_finger_joint", "limited", "false"),
            // robosuite's spring between the three joints of a side, which the couplings replace.
            ("fixed", "gripper0_finger2_12_cpl", "limited", "false"),
            ("fixed", "gripper0_finger2_12_cpl", "stiffness", "0"),
            ("fixed", "gripper0_finger1_12_cpl", "limited", "false"),
            ("fixed", "gripper0_finger1_12_cpl", "stiffness", "0"),
        ],
    },
};

/// Every arm, in the order `mimicgen tasks` lists them.
pub const ROBOTS: &[RobotModel] = &[PANDA, SAWYER, IIWA, UR5E];

/// The arm named `name` (ours, `sawyer`, or robosuite's, `Sawyer`).
///
/// # Errors
/// A message listing the arms when there is none of that name.
pub fn robot(name: &str) -> Result<&'static RobotModel, String> {
    ROBOTS.iter().find(|r| r.name.eq_ignore_ascii_case(name) || r.robosuite_name == name).ok_or_else(|| {
        let names: Vec<&str> = ROBOTS.iter().map(|r| r.name).collect();
        format!("no robot named {name:?}: the robots are {}", names.join(", "))
    })
}

/// `xml` as the simulation runs it: with `robot`'s [`SimPatch`] (datasets keep robosuite's XML).
/// An element the patch names that the XML lacks is left as it is (a coupling of a joint it lacks
/// fails to compile, naming the joint).
#[must_use]
pub fn for_simulation(xml: &str, robot: &RobotModel) -> String {
    let patch = &robot.sim_patch;
    let mut xml = xml.to_owned();
    for (element, name, attribute, value) in patch.attributes {
        xml = crate::mjcf_edit::edit_element(&xml, element, name, &[(attribute, (*value).to_owned())], &[]).unwrap_or(xml);
    }
    let excludes: String = patch.contact_excludes.iter().map(|(a, b)| format!(r#"<exclude body1="{a}" body2="{b}"/>"#)).collect();
    // Stiffer than MuJoCo's default (0.02 s): the fingers' links weigh grams and the default
    // lets the linkage's spring bend them 0.2 rad off.
    let couplings: String = patch
        .couplings
        .iter()
        .map(|c| {
            format!(r#"<joint joint1="{}" joint2="{}" polycoef="{} {} 0 0 0" solref="0.004 1"/>"#, c.joint, c.driver, c.offset, c.slope)
        })
        .collect();
    let mut sections = String::new();
    if !excludes.is_empty() {
        sections += &format!("<contact>{excludes}</contact>\n");
    }
    if !couplings.is_empty() {
        sections += &format!("<equality>{couplings}</equality>\n");
    }
    crate::mjcf_edit::with_section(&xml, &sections)
}

/// The arm whose joints `has_joint` finds in a scene (Panda for a scene with none of them).
#[must_use]
pub fn detect(has_joint: impl Fn(&str) -> bool) -> &'static RobotModel {
    ROBOTS.iter().find(|r| r.arm_joints.first().is_some_and(|&joint| has_joint(joint))).unwrap_or(&PANDA)
}
