//! Helpers shared by the simulator's integration tests.

use std::ops::ControlFlow;
use std::sync::Arc;

use mimicgen_engine::Generator;
use mimicgen_sim::{Scene, SimEnv, registry};

/// Generates with `generator` in one simulator of `task`'s `variant`, attempt by attempt, until
/// `want` attempts succeeded or `cap` were made. Returns (successes, attempts).
pub fn generate_until(generator: &Generator, task: &str, variant: &str, want: usize, cap: usize) -> (usize, usize) {
    let task = registry::task(task, variant).unwrap_or_else(|e| panic!("{e}"));
    let mut envs = vec![SimEnv::new(Arc::new(Scene::for_task(task.as_ref()).unwrap_or_else(|e| panic!("{e}"))), task)];
    let (mut successes, mut attempts) = (0, 0);
    mimicgen_engine::run_with(
        generator,
        &mut envs,
        mimicgen_engine::RunControl::default(),
        |_, _| Ok(()),
        |a, (), _| {
            attempts += 1;
            successes += usize::from(a.success);
            if successes < want && attempts < cap { ControlFlow::Continue(()) } else { ControlFlow::Break(Ok(())) }
        },
    )
    .unwrap_or_else(|e| panic!("{e}"));
    (successes, attempts)
}
