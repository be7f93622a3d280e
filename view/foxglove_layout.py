"""The Foxglove layout for Touchdown's channels (view.foxglove), built with the Foxglove SDK's
typed layout classes (``foxglove.layouts``, generated from Foxglove's own layout schema) and
committed as ``docs/foxglove-layout.json`` (import it in Foxglove: Layouts, Import from file):

- a 3-D panel in the frame ``site`` (x east, y north, z up) with the landers, the ground and a
  grid; each ship's frame is named by its id;
- plots of the ship chosen by the layout variable ``ship`` (default ``ship-1``; set it in the
  Variables sidebar): altitude and penetration, vertical and horizontal speed, tilt, the ground
  forces and the energy, each addressed by ship id
  (``/foxglove/ships.ships[:]{ship_id==$ship}.altitude``);
- the state of every ship over time (one row per ship id) and the events as a log.

``python -m touchdown.view.foxglove_layout [OUT.json]`` writes it (a test holds the committed
file to this code).
"""
from __future__ import annotations

import json
import sys
from pathlib import Path

from touchdown.view import foxglove as fx

#: the layout variable that picks the plotted ship, and its default
SHIP_VARIABLE = "ship"
DEFAULT_SHIP = "ship-1"
#: (title, ((field, label), ...)) of each plot of the chosen ship
PLOTS = (
    ("Feet: altitude and penetration (m)", (("altitude", "altitude"),
                                           ("penetration", "penetration"))),
    ("Speed relative to the surface (m/s)", (("v_radial", "vertical (+ up)"),
                                            ("v_tangential", "horizontal"))),
    ("Tilt (deg)", (("tilt_deg", "tilt"),)),
    ("Ground forces (N)", (("normal_force", "normal"), ("friction_force", "friction"))),
    ("Energy (J)", (("energy_j", "energy_j"),)),
)


def ship_path(field: str) -> str:
    """The chosen ship's ``field``, addressed by its id (never by its place in the array)."""
    return f"{fx.TOPIC_SHIPS}.ships[:]{{ship_id==${SHIP_VARIABLE}}}.{field}"


def layout():
    import foxglove.layouts as fl

    three_d = fl.ThreeDeePanel(title="Landing site (east, north, up; m)", config=fl.ThreeDeeConfig(
        follow_tf=fx.SITE_FRAME, fixed_frame=fx.SITE_FRAME, follow_mode="follow-none",
        camera_state=fl.ThreeDeeCameraState(distance=80.0, perspective=True, phi=60.0,
                                            theta_offset=45.0, fovy=45.0),
        scene=fl.BaseRendererSceneSettings(transforms=fl.BaseRendererTransforms(
            show_label=False, axis_size=1.0)),
        layers={"grid": fl.BaseRendererGridLayerSettings(frame_id=fx.SITE_FRAME, size=200.0,
                                                         divisions=40)},
        topics={fx.TOPIC_LANDERS: fl.BaseRendererSceneUpdateTopicSettings(visible=True),
                fx.TOPIC_GROUND: fl.BaseRendererSceneUpdateTopicSettings(visible=True)}))
    plots = [fl.PlotPanel(title=f"{title}: ship ${SHIP_VARIABLE}", config=fl.PlotConfig(
        paths=[fl.PlotSeries(value=ship_path(field), label=label,
                             timestamp_method="receiveTime") for field, label in series]))
        for title, series in PLOTS]
    states = fl.StateTransitionsPanel(title="State of every ship", config=fl.StateTransitionsConfig(
        paths=[fl.StateTransitionsSeries(value=f"{fx.TOPIC_SHIPS}.ships", label="state",
                                         dynamic_label_field="ship_id",
                                         dynamic_value_field="state",
                                         timestamp_method="receiveTime")]))
    events = fl.LogPanel(title="Events", config=fl.LogConfig(topic_to_render=fx.TOPIC_EVENTS,
                                                             show_name=True, show_level=True))
    right = fl.SplitContainer(direction="column", items=[
        fl.SplitItem(proportion=1, content=p) for p in plots])
    bottom = fl.SplitContainer(direction="row", items=[fl.SplitItem(proportion=2, content=states),
                                                       fl.SplitItem(proportion=1, content=events)])
    left = fl.SplitContainer(direction="column", items=[fl.SplitItem(proportion=3, content=three_d),
                                                        fl.SplitItem(proportion=1, content=bottom)])
    return fl.Layout(variables={SHIP_VARIABLE: DEFAULT_SHIP}, content=fl.SplitContainer(
        direction="row", items=[fl.SplitItem(proportion=3, content=left),
                                fl.SplitItem(proportion=2, content=right)]))


def layout_json() -> str:
    """The layout as the committed file holds it (indented, a newline at the end)."""
    return json.dumps(json.loads(layout().to_json()), indent=2) + "\n"


if __name__ == "__main__":
    out = Path(sys.argv[1]) if len(sys.argv) > 1 else \
        Path(__file__).resolve().parent.parent / "docs" / "foxglove-layout.json"
    out.write_text(layout_json())
    print(out)
