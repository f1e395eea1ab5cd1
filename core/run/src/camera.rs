//! Which camera observations a run renders into its dataset.

use serde::{Deserialize, Serialize};

/// Which cameras, at what size, with or without depth.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct CameraConfig {
    /// robosuite camera names (`agentview`, `robot0_eye_in_hand`).
    pub names: Vec<String>,
    /// Image height in pixels.
    pub height: usize,
    /// Image width in pixels.
    pub width: usize,
    /// Also render depth (`<camera>_depth`, robosuite's normalized depth buffer, `float32`).
    pub depth: bool,
    /// Render without multisampling: about twice as fast on a software renderer, but edges differ
    /// from robosuite's images (which use MuJoCo's default 4x multisampling).
    #[serde(default)]
    pub fast: bool,
    /// Mirror the scene in the floor as robosuite does (its floor reflects 1 %): robosuite's
    /// pixels exactly, at about three times the cost on a software renderer. Off, the floor's
    /// pixels differ by a few levels (BENCHMARKS.md, "Where a frame's time goes").
    #[serde(default)]
    pub reflection: bool,
}

impl Default for CameraConfig {
    /// robomimic's image datasets: `agentview` and the wrist camera at 84 x 84, no depth.
    fn default() -> Self {
        Self {
            names: vec!["agentview".into(), "robot0_eye_in_hand".into()],
            height: 84,
            width: 84,
            depth: false,
            fast: false,
            reflection: false,
        }
    }
}
