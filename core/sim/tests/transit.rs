//! Planned transit on the MuJoCo backend: the arm's configuration space, and paths round clutter.
#![allow(clippy::unwrap_used)] // tests fail loudly by design

use std::sync::Arc;

use mimicgen_engine::Environment as _;
use mimicgen_engine::spec::Transit;
use mimicgen_engine::transit::TransitSpace as _;
use mimicgen_sim::{Scene, SimEnv, registry};

fn env(task: &str, variant: &str) -> SimEnv {
    let task = registry::task(task, variant).unwrap();
    let scene = Arc::new(Scene::for_task(task.as_ref()).unwrap());
    SimEnv::new(scene, task)
}

#[test]
fn debug_square() {
    let task = std::env::var("DBG_TASK").unwrap_or("square".into());
    let mut e = env(&task, "C0");
    let sources = mimicgen_io::read_source_dataset(
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join(format!("data/{task}_D0_source.hdf5")),
        &Default::default(),
    )
    .unwrap();
    let mut spec = mimicgen_engine::TaskSpec::from_toml_str(&std::fs::read_to_string(format!("tasks/{task}.toml")).unwrap(), "t").unwrap();
    for s in &mut spec.subtasks {
        s.transit = Transit::Plan;
    }
    let generator = mimicgen_engine::Generator::new(spec, sources).unwrap();
    {
        use rand::SeedableRng;
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(1);
        e.reset(&mut rng).unwrap();
        eprintln!("contacts at reset {} {:?}", e.obstacle_contacts(), e.object_poses().get("post").map(|p| p.translation.vector));
        let names: Vec<_> = e
            .data()
            .contact()
            .iter()
            .map(|c| (e.scene().geom_names(&[c.geom[0] as usize]), e.scene().geom_names(&[c.geom[1] as usize])))
            .collect();
        eprintln!("{names:?}");
    }
    let mut idx = 0;
    let a = loop {
        let a = generator.attempt(&mut e, idx).unwrap();
        if a.obstacle_contact_steps > 0 {
            break a;
        }
        idx += 1;
    };
    eprintln!("attempt {idx} {:?}", a.failure);
    for p in &a.plans {
        eprintln!("plan span {:?} first {} transit {:?}", p.src_span, p.first_step, p.transit);
    }
    let t = &a.trajectory;
    let mut replay = env(&task, "C0");
    for k in 0..t.len() {
        replay.set_state(t.states.row(k)).unwrap();
        replay.place_fixed_objects(&a.initial_object_poses);
        let c = replay.obstacle_contacts();
        if c > 0 {
            let names: Vec<_> = replay
                .data()
                .contact()
                .iter()
                .map(|c| (replay.scene().geom_names(&[c.geom[0] as usize]), replay.scene().geom_names(&[c.geom[1] as usize])))
                .filter(|(a, b)| {
                    (a[0].contains("post") || b[0].contains("post") || a[0].contains("wall") || b[0].contains("wall"))
                        && !a[0].contains("table")
                        && !b[0].contains("table")
                })
                .collect();
            eprintln!("{k} {:?} {c} eef {:?} {names:?}", t.kinds[k], t.eef_poses[k].translation.vector.as_slice());
        }
    }
    let goal = a.plans.last().unwrap().transformed_poses[0];
    eprintln!("goal {:?}", goal.translation.vector);
    let mut space = e.arm_space();
    let q0 = space.joints();
    let q = space.inverse_kinematics(&goal, &q0);
    eprintln!("ik {q:?}");
    if let Some(q) = q {
        eprintln!("collisions {:?}", space.collisions_at(&q));
        eprintln!("fk {:?}", space.eef_pose_at(&q).translation.vector);
    }
    eprintln!("start collisions {:?}", space.collisions_at(&q0));
}
#[test]
fn debug_square_d0() {
    let mut e = env("square", "C0");
    let sources = mimicgen_io::read_source_dataset(
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("data/square_D0_source.hdf5"),
        &Default::default(),
    )
    .unwrap();
    let mut spec = mimicgen_engine::TaskSpec::from_toml_str(include_str!("../tasks/square.toml"), "square").unwrap();
    for s in &mut spec.subtasks {
        s.transit = Transit::Plan;
    }
    let generator = mimicgen_engine::Generator::new(spec, sources).unwrap();
    let a = generator.attempt(&mut e, 0).unwrap();
    eprintln!("{:?}", a.failure);
    for p in &a.plans {
        eprintln!(
            "plan src {} span {:?} first {} transit {:?} tp0 {:?}",
            p.src_demo,
            p.src_span,
            p.first_step,
            p.transit,
            p.transformed_poses[0].translation.vector.as_slice()
        );
    }
    let t = &a.trajectory;
    for k in 0..t.len().min(90) {
        let nut = t.object_poses["square_nut"][k].translation.vector;
        eprintln!(
            "{k} {:?} eef {:.3?} tgt {:.3?} nut {:.3?} g {:?} sig {:?}",
            t.kinds[k],
            t.eef_poses[k].translation.vector.as_slice(),
            t.target_poses[k].translation.vector.as_slice(),
            nut.as_slice(),
            t.gripper_actions.row(k),
            t.subtask_term_signals["grasp"][k]
        );
    }
}
