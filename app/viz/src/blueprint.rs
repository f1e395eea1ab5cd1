//! The default viewer layout, the same as `viewer_assets/mimicgen.rbl`.

use rerun::blueprint::components::{PanelState, PlayState};
use rerun::blueprint::{
    Blueprint, BlueprintPanel, Horizontal, SelectionPanel, Spatial2DView, Spatial3DView, Tabs, TextLogView, TimePanel, TimeSeriesView,
    Vertical,
};

use crate::record::timelines;

/// The 3D scene on the left; signal and gripper plots, run statistics and attempt outcomes on the
/// right; the time panel on the `frame` timeline (every step of the run in order), following the
/// newest data (the end of a saved run, the current attempt of a live one).
#[must_use]
pub fn default_blueprint() -> Blueprint {
    blueprint_with_cameras(&[])
}

/// [`default_blueprint`] with a row of camera images (`cameras/<name>`, one 2D view each) above the
/// plots, for datasets with camera observations.
#[must_use]
pub fn blueprint_with_cameras(cameras: &[String]) -> Blueprint {
    let mut right = Vec::new();
    if !cameras.is_empty() {
        right.push(
            Horizontal::new(
                cameras.iter().map(|c| Spatial2DView::new(c.as_str()).with_origin(format!("{}/{c}", crate::record::CAMERAS)).into()),
            )
            .into(),
        );
    }
    right.extend([
        TimeSeriesView::new("Signals and gripper").with_origin("plots").into(),
        TimeSeriesView::new("Run statistics").with_origin("stats").into(),
        TextLogView::new("Outcomes").with_origin("outcome").into(),
    ]);
    Blueprint::new(
        Horizontal::new([Spatial3DView::new("Scene").with_origin("world").into(), Vertical::new(right).into()])
            .with_column_shares([2.0, 1.0]),
    )
    .with_time_panel(TimePanel::new().with_timeline(timelines::FRAME).with_play_state(PlayState::Following))
}

/// The layout inside the app, which draws its own plots and lists: a 3D view of the workspace
/// (table top, objects, gripper, paths: framed close, without the arm and the room) with a tab
/// for the whole scene, the outcome log below, the viewer's side panels collapsed, and the time
/// panel on the `step` timeline, paused and collapsed to its bar, so the app's cursor drives it.
#[must_use]
pub fn app_blueprint() -> Blueprint {
    let workspace = Spatial3DView::new("Workspace").with_origin("world").with_contents([
        "+ /world/**",
        "- /world/scene/robot/**",
        "- /world/scene/arena/**",
    ]);
    let whole = Spatial3DView::new("Whole scene").with_origin("world");
    Blueprint::new(
        Vertical::new([Tabs::new([workspace.into(), whole.into()]).into(), TextLogView::new("Outcomes").with_origin("outcome").into()])
            .with_row_shares([6.0, 1.0]),
    )
    .with_blueprint_panel(BlueprintPanel::new().with_state(PanelState::Collapsed))
    .with_selection_panel(SelectionPanel::new().with_state(PanelState::Collapsed))
    .with_time_panel(TimePanel::new().with_timeline(timelines::STEP).with_play_state(PlayState::Paused).with_state(PanelState::Collapsed))
}
