//! Colours every screen shares.

use egui::Color32;

/// Colours of subtasks 0, 1, 2, ... (segments and their end markers).
const SUBTASK_COLORS: [Color32; 6] = [
    Color32::from_rgb(66, 133, 244),
    Color32::from_rgb(234, 67, 53),
    Color32::from_rgb(52, 168, 83),
    Color32::from_rgb(251, 188, 5),
    Color32::from_rgb(171, 71, 188),
    Color32::from_rgb(0, 172, 193),
];

/// The colour of subtask `k`.
#[must_use]
pub fn subtask_color(k: usize) -> Color32 {
    #[allow(clippy::indexing_slicing, reason = "k % len is below len")]
    SUBTASK_COLORS[k % SUBTASK_COLORS.len()]
}

/// Colour of successes in the run's plots.
pub const SUCCESS: Color32 = Color32::from_rgb(60, 180, 90);
/// Colour of failures in the run's plots.
pub const FAILURE: Color32 = Color32::from_rgb(220, 70, 70);
