//! Box-box contacts as the MuJoCo that robosuite 1.4 runs (2.3) computes them.
//!
//! MuJoCo's box-box collider changed between 2.3, which robosuite 1.4 runs, and 3.17, which we
//! run: in the same state 3.17 reports twice the penetration depth of a box-box contact, every
//! contact, while mesh and sphere contacts agree (`scripts/compare_physics.py` led there; in one
//! state the pads on a cube at 2.34 mm in 3.17 and 1.17 mm in 2.3, 45 N against 22 N). 3.17's
//! depth is the true one; robosuite's assets (the pads' stiffness, the objects' contacts) and the
//! reference's datasets were made with the half depth, so the same state pushes twice as hard on
//! a box resting on the table or squeezed between the finger pads. (Which MuJoCo release changed
//! it we did not pin down; MuJoCo Warp's port of the same collider is discussed in
//! google-deepmind/mujoco_warp#822.)
//!
//! A soft contact's reference acceleration is `-b v - k imp(|d|) d` (MuJoCo's solver parameters);
//! at half the depth it is `-b v - k imp(|d| / 2) d / 2`. So a box-box contact computed by MuJoCo
//! 3.17 with half the stiffness `k` and twice the impedance width behaves as MuJoCo 2.3's did.
//! That is what [`contact_section`] writes, as explicit contact pairs (`<pair>`, with solref in
//! MuJoCo's direct form) for every pair of box geoms that can collide, the dynamic contacts of
//! those body pairs excluded (and their other geom pairs kept as explicit pairs with MuJoCo's own
//! mixed parameters). Every task and arm gets it; only the simulation changes, never the
//! `model_file` written.
#![allow(
    clippy::indexing_slicing,
    reason = "MuJoCo ids and addresses come from the compiled model (name_to_id, a Scene's names resolved once) and index that model's own arrays; contact geoms are ids MuJoCo reported for this model"
)]

use std::collections::BTreeMap;
use std::fmt::Write as _;

use mujoco_rs::mujoco_c::mjtDisableBit;
use mujoco_rs::prelude::*;

/// Set to `1` in the environment, MuJoCo 3.17's own box-box depth is simulated instead (to
/// measure what the emulation changes, as BENCHMARKS.md does).
pub const TRUE_DEPTH_ENV: &str = "MIMICGEN_TRUE_BOX_DEPTH";

/// Whether box-box contacts are simulated at MuJoCo 2.3's depth (the default; see
/// [`TRUE_DEPTH_ENV`]).
#[must_use]
pub fn enabled() -> bool {
    std::env::var(TRUE_DEPTH_ENV).map_or(true, |v| v != "1")
}

/// Contact parameters of one geom pair, mixed from the two geoms as MuJoCo mixes them.
#[derive(Debug, Clone, PartialEq)]
struct PairParams {
    condim: i32,
    friction: [f64; 5],
    solref: [f64; 2],
    solimp: [f64; 5],
    margin: f64,
    gap: f64,
}

/// MuJoCo's `mj_contactParam` for geoms `g1` and `g2`.
fn mixed(model: &MjModel, g1: usize, g2: usize) -> PairParams {
    let (p1, p2) = (model.geom_priority()[g1], model.geom_priority()[g2]);
    let margin = model.geom_margin()[g1].max(model.geom_margin()[g2]);
    let gap = model.geom_gap()[g1].max(model.geom_gap()[g2]);
    let five = |f: [f64; 3]| [f[0], f[0], f[1], f[2], f[2]];
    if p1 != p2 {
        let g = if p1 > p2 { g1 } else { g2 };
        return PairParams {
            condim: model.geom_condim()[g],
            friction: five(model.geom_friction()[g]),
            solref: model.geom_solref()[g],
            solimp: model.geom_solimp()[g],
            margin,
            gap,
        };
    }
    let (f1, f2) = (model.geom_friction()[g1], model.geom_friction()[g2]);
    let friction = five([f1[0].max(f2[0]), f1[1].max(f2[1]), f1[2].max(f2[2])]);
    let (s1, s2) = (model.geom_solmix()[g1], model.geom_solmix()[g2]);
    let mix = match (s1 >= MIN_VAL, s2 >= MIN_VAL) {
        (true, true) => s1 / (s1 + s2),
        (false, false) => 0.5,
        (true, false) => 1.0,
        (false, true) => 0.0,
    };
    let (r1, r2) = (model.geom_solref()[g1], model.geom_solref()[g2]);
    let solref = if r1[0] > 0.0 && r2[0] > 0.0 {
        [mix * r1[0] + (1.0 - mix) * r2[0], mix * r1[1] + (1.0 - mix) * r2[1]]
    } else {
        [r1[0].min(r2[0]), r1[1].min(r2[1])]
    };
    let (i1, i2) = (model.geom_solimp()[g1], model.geom_solimp()[g2]);
    let solimp = std::array::from_fn(|k| mix * i1[k] + (1.0 - mix) * i2[k]);
    PairParams { condim: model.geom_condim()[g1].max(model.geom_condim()[g2]), friction, solref, solimp, margin, gap }
}

/// MuJoCo's `mjMINVAL`.
const MIN_VAL: f64 = 1e-15;

/// The same contact at half the depth: half the stiffness, twice the impedance width, with the
/// solver reference in MuJoCo's direct form (`-stiffness -damping`).
fn at_half_depth(mut p: PairParams, timestep: f64, refsafe: bool) -> PairParams {
    let (stiffness, damping) = if p.solref[0] > 0.0 {
        let timeconst = if refsafe { p.solref[0].max(2.0 * timestep) } else { p.solref[0] };
        let dampratio = p.solref[1];
        (1.0 / (timeconst * timeconst * dampratio * dampratio).max(MIN_VAL), 2.0 / timeconst.max(MIN_VAL))
    } else {
        (-p.solref[0], -p.solref[1])
    };
    p.solref = [-stiffness / 2.0, -damping];
    p.solimp[2] *= 2.0;
    p
}

/// Whether MuJoCo's broad phase lets geoms `g1` and `g2` collide (bodies, welds, parent filter,
/// excluded body pairs, contype/conaffinity).
fn collide(model: &MjModel, g1: usize, g2: usize, excluded: &[i32]) -> bool {
    let body = |g: usize| usize::try_from(model.geom_bodyid()[g]).unwrap_or_default();
    let (b1, b2) = (body(g1), body(g2));
    let weld = |b: usize| usize::try_from(model.body_weldid()[b]).unwrap_or_default();
    let (w1, w2) = (weld(b1), weld(b2));
    if b1 == b2 || w1 == w2 {
        return false;
    }
    let filterparent = model.opt().disableflags & (mjtDisableBit::mjDSBL_FILTERPARENT as i32) == 0;
    let parent_weld = |w: usize| weld(usize::try_from(model.body_parentid()[w]).unwrap_or_default());
    if filterparent && w1 != 0 && w2 != 0 && (w1 == parent_weld(w2) || w2 == parent_weld(w1)) {
        return false;
    }
    let (lo, hi) = (b1.min(b2), b1.max(b2));
    let signature = i32::try_from((lo << 16) + hi).unwrap_or(-1);
    if excluded.contains(&signature) {
        return false;
    }
    let (t1, a1) = (model.geom_contype()[g1], model.geom_conaffinity()[g1]);
    let (t2, a2) = (model.geom_contype()[g2], model.geom_conaffinity()[g2]);
    (t1 & a2) != 0 || (t2 & a1) != 0
}

/// The `<contact>` section that makes `model`'s box-box contacts behave as MuJoCo 2.3's (see the
/// module's documentation), or `None` when no two box geoms can touch (or one is unnamed, so no
/// pair can name it: the model is then simulated as it is).
#[must_use]
pub fn contact_section(model: &MjModel) -> Option<String> {
    let ngeom = model.geom_type().len();
    let excluded = model.exclude_signature().to_vec();
    let explicit: Vec<(i32, i32)> = model.pair_geom1().iter().zip(model.pair_geom2()).map(|(&a, &b)| (a.min(b), a.max(b))).collect();
    let is_box = |g: usize| model.geom_type()[g] == MjtGeomBase::mjGEOM_BOX;
    let name = |kind: MjtObjBase, id: usize| model.id_to_name(kind, id).filter(|n| !n.is_empty()).map(str::to_owned);
    // Every geom pair that collides dynamically, grouped by body pair.
    let mut by_bodies: BTreeMap<(usize, usize), Vec<(usize, usize)>> = BTreeMap::new();
    let colliding: Vec<usize> = (0..ngeom).filter(|&g| model.geom_contype()[g] != 0 || model.geom_conaffinity()[g] != 0).collect();
    for (i, &g1) in colliding.iter().enumerate() {
        for &g2 in &colliding[i + 1..] {
            let key = (i32::try_from(g1).unwrap_or(-1), i32::try_from(g2).unwrap_or(-1));
            if explicit.contains(&key) || !collide(model, g1, g2, &excluded) {
                continue;
            }
            let (b1, b2) = (model.geom_bodyid()[g1], model.geom_bodyid()[g2]);
            let bodies = (usize::try_from(b1.min(b2)).unwrap_or_default(), usize::try_from(b1.max(b2)).unwrap_or_default());
            by_bodies.entry(bodies).or_default().push((g1, g2));
        }
    }
    by_bodies.retain(|_, pairs| pairs.iter().any(|&(a, b)| is_box(a) && is_box(b)));
    if by_bodies.is_empty() {
        return None;
    }
    let timestep = model.opt().timestep;
    let refsafe = model.opt().disableflags & (mjtDisableBit::mjDSBL_REFSAFE as i32) == 0;
    let mut out = String::from("  <contact>\n");
    for ((b1, b2), pairs) in &by_bodies {
        let (n1, n2) = (name(MjtObjBase::mjOBJ_BODY, *b1)?, name(MjtObjBase::mjOBJ_BODY, *b2)?);
        let _ = writeln!(out, r#"    <exclude body1="{n1}" body2="{n2}"/>"#);
        for &(g1, g2) in pairs {
            let (n1, n2) = (name(MjtObjBase::mjOBJ_GEOM, g1)?, name(MjtObjBase::mjOBJ_GEOM, g2)?);
            let mut p = mixed(model, g1, g2);
            if is_box(g1) && is_box(g2) {
                p = at_half_depth(p, timestep, refsafe);
            }
            let _ = writeln!(
                out,
                r#"    <pair geom1="{n1}" geom2="{n2}" condim="{}" friction="{}" solref="{}" solimp="{}" margin="{}" gap="{}"/>"#,
                p.condim,
                crate::mjcf_edit::words(&p.friction),
                crate::mjcf_edit::words(&p.solref),
                crate::mjcf_edit::words(&p.solimp),
                p.margin,
                p.gap
            );
        }
    }
    out.push_str("  </contact>\n");
    Some(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn half_the_depth_is_half_the_stiffness_and_twice_the_width() {
        let p = PairParams {
            condim: 3,
            friction: [1.0, 1.0, 0.005, 0.0001, 0.0001],
            solref: [0.02, 1.0],
            solimp: [0.9, 0.95, 0.001, 0.5, 2.0],
            margin: 0.0,
            gap: 0.0,
        };
        let half = at_half_depth(p.clone(), 0.002, true);
        // Standard (0.02, 1): stiffness 1 / 0.02^2 = 2500, damping 2 / 0.02 = 100.
        assert!((half.solref[0] + 1250.0).abs() < 1e-9 && (half.solref[1] + 100.0).abs() < 1e-9, "{:?}", half.solref);
        assert!((half.solimp[2] - 0.002).abs() < 1e-15, "{:?}", half.solimp);
        // refsafe clamps the time constant to twice the timestep, as MuJoCo does.
        let fast = at_half_depth(PairParams { solref: [0.001, 1.0], ..p }, 0.002, true);
        assert!((fast.solref[0] + 0.5 / (0.004 * 0.004)).abs() < 1e-6, "{:?}", fast.solref);
    }
}
