"""Writes viewer_assets/mimicgen.rbl, the default Rerun layout for mimicgen recordings.

Run with the venv's Python (scripts/setup.sh installs rerun-sdk==0.36.3 there):
    ~/.cache/mimicgen/venv/bin/python viewer_assets/make_blueprint.py
Keep it in step with app/viz/src/blueprint.rs, which sends the same layout with every recording.
"""

from pathlib import Path

import rerun as rr
import rerun.blueprint as rrb

blueprint = rrb.Blueprint(
    rrb.Horizontal(
        rrb.Spatial3DView(name="Scene", origin="world"),
        rrb.Vertical(
            rrb.TimeSeriesView(name="Signals and gripper", origin="plots"),
            rrb.TimeSeriesView(name="Run statistics", origin="stats"),
            rrb.TextLogView(name="Outcomes", origin="outcome"),
        ),
        column_shares=[2, 1],
    ),
    rrb.TimePanel(timeline="frame", play_state="following"),
)

out = Path(__file__).with_name("mimicgen.rbl")
blueprint.save("mimicgen", out)
print(f"wrote {out}")
