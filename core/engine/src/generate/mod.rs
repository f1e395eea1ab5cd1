//! The generation loop: attempts, their records, and a run over several workers.
//!
//! Attempt `k` of a run draws every random number (scene, segment offsets, source choice, action
//! noise) from ChaCha8 stream `k` of the run seed, so an attempt is the same whichever worker runs
//! it and whenever. [`run`] hands attempts to the caller strictly in index order and stops at the
//! same index whatever the number of workers, so the same seed gives the same dataset.
//!
//! - `records.rs`: what an attempt leaves behind (its plans, trajectory, failure reason);
//! - `attempt.rs`: how one attempt runs (the [`Generator`], its plans, [`execute_step`]);
//! - `schedule.rs`: how a run is scheduled over workers and shards, and its statistics.

mod attempt;
mod records;
mod schedule;

pub use attempt::*;
pub use records::*;
pub use schedule::*;

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

/// The random stream of attempt `index` in a run seeded with `seed`.
#[must_use]
pub fn attempt_rng(seed: u64, index: u64) -> ChaCha8Rng {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    rng.set_stream(index);
    rng
}
