//! The default viewer layout, the same as `viewer_assets/mimicgen.rbl`.

use rerun::blueprint::components::PlayState;
use rerun::blueprint::{Blueprint, Horizontal, Spatial3DView, TextLogView, TimePanel, TimeSeriesView, Vertical};

use crate::record::timelines;

/// The 3D scene on the left; signal and gripper plots, run statistics and attempt outcomes on the
/// right; the time panel on the `frame` timeline (every step of the run in order), following the
/// newest data (the end of a saved run, the current attempt of a live one).
#[must_use]
pub fn default_blueprint() -> Blueprint {
    Blueprint::new(
        Horizontal::new([
            Spatial3DView::new("Scene").with_origin("world").into(),
            Vertical::new([
                TimeSeriesView::new("Signals and gripper").with_origin("plots").into(),
                TimeSeriesView::new("Run statistics").with_origin("stats").into(),
                TextLogView::new("Outcomes").with_origin("outcome").into(),
            ])
            .into(),
        ])
        .with_column_shares([2.0, 1.0]),
    )
    .with_time_panel(TimePanel::new().with_timeline(timelines::FRAME).with_play_state(PlayState::Following))
}

/// The layout inside the app, which draws its own plots: the 3D scene (with the outcome log
/// below it), the time panel on the `step` timeline, paused, so the app's time cursor drives it.
#[must_use]
pub fn app_blueprint() -> Blueprint {
    Blueprint::new(
        Vertical::new([
            Spatial3DView::new("Scene").with_origin("world").into(),
            TextLogView::new("Outcomes").with_origin("outcome").into(),
        ])
        .with_row_shares([5.0, 1.0]),
    )
    .with_time_panel(TimePanel::new().with_timeline(timelines::STEP).with_play_state(PlayState::Paused))
}
