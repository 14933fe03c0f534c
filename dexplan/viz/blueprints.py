"""The Rerun blueprints (viewer layouts) of dexplan's recordings.

``rerun.blueprint`` is reached inside each function, never when the package is imported.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from dexplan.viz.session import PLAN_STEP, REJECTED_SAMPLE, ROADMAP_NODE, rerun_module

if TYPE_CHECKING:  # rerun's types for annotations; at run time rerun loads on first use
    import rerun.blueprint

# Default 3D camera (the hand's workspace, seen from the front right).
EYE = [0.19, -0.22, 0.21]
LOOK_AT = [0.0, 0.0, 0.06]


def _world_view(name: str) -> rerun.blueprint.Spatial3DView:
    """The 3D view of ``world`` from the default camera, z up."""
    rrb = rerun_module().blueprint
    return rrb.Spatial3DView(
        origin="world",
        name=name,
        eye_controls=rrb.EyeControls3D(position=EYE, look_target=LOOK_AT, eye_up=[0.0, 0.0, 1.0]),
    )


def _world_beside(
    name: str, side: rerun.blueprint.View | rerun.blueprint.Container
) -> rerun.blueprint.Horizontal:
    """The 3D view of ``world`` (three quarters of the width) with ``side`` on its right."""
    rrb = rerun_module().blueprint
    return rrb.Horizontal(_world_view(name), side, column_shares=[3, 1])


def roadmap_blueprint(with_scene: bool) -> rerun.blueprint.Blueprint:
    """A roadmap: the 3D view and the component table (the node timeline with a scene)."""
    rrb = rerun_module().blueprint
    side = rrb.Vertical(
        rrb.Spatial3DView(origin="orientation", name="Orientations (rotation vector, rad)"),
        rrb.TextDocumentView(origin="roadmap/summary", name="Components"),
    )
    return rrb.Blueprint(
        _world_beside("GSn roadmap", side),
        rrb.TimePanel(timeline=ROADMAP_NODE, state="collapsed" if with_scene else "hidden"),
        rrb.BlueprintPanel(state="collapsed"),
        collapse_panels=False,
    )


def plan_blueprint(has_roadmap: bool) -> rerun.blueprint.Blueprint:
    """A plan: the 3D view beside the FC plot, mode lanes, segment log and summaries."""
    rrb = rerun_module().blueprint
    side = [
        rrb.TimeSeriesView(
            origin="plan/fc",
            name="Force-closure quality",
            plot_legend=rrb.PlotLegend(corner=rrb.Corner2D.RightTop),
        ),
        rrb.StateTimelineView(origin="plan/state", name="Mode and free finger"),
        rrb.TextLogView(origin="plan/segment", name="Segments"),
        rrb.Tabs(
            rrb.TextDocumentView(origin="plan/summary", name="Plan"),
            rrb.TextDocumentView(origin="plan/quality", name="Quality"),
            *(
                [rrb.TextDocumentView(origin="roadmap/summary", name="Roadmap")]
                if has_roadmap
                else []
            ),
        ),
    ]
    return rrb.Blueprint(
        rrb.Horizontal(
            _world_view("Hand, object, roadmap"),
            rrb.Vertical(*side, row_shares=[3, 1.2, 2, 2]),
            column_shares=[3, 2],
        ),
        rrb.TimePanel(timeline=PLAN_STEP, state="collapsed"),
        rrb.BlueprintPanel(state="collapsed"),
        rrb.SelectionPanel(state="collapsed"),
        collapse_panels=False,
    )


def rejections_blueprint() -> rerun.blueprint.Blueprint:
    """Rejected samples: the 3D view and the log of why each was rejected."""
    rrb = rerun_module().blueprint
    return rrb.Blueprint(
        _world_beside("Rejected samples", rrb.TextLogView(origin="rejected", name="Why")),
        rrb.TimePanel(timeline=REJECTED_SAMPLE, state="expanded"),
        collapse_panels=False,
    )


def replay_blueprint() -> rerun.blueprint.Blueprint:
    """A physics replay: the plan and the replay side by side, the object error below."""
    rrb = rerun_module().blueprint
    return rrb.Blueprint(
        rrb.Vertical(
            rrb.Horizontal(
                rrb.Spatial3DView(origin="world/plan", name="plan"),
                rrb.Spatial3DView(origin="world/replay", name="replay (MuJoCo)"),
            ),
            rrb.TimeSeriesView(origin="errors", name="object error vs plan"),
            row_shares=[3, 1],
        ),
        collapse_panels=True,
    )
