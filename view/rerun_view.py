"""Rerun views of runs (``touchdown view``): the 3D scene in the landing-site frame, plots over
time, the seed's client display (status and HUD) and the events, with a saved layout.

Everything time-varying goes in as columns (``send_columns``: one call per entity for the whole
run, not one per tick), on two timelines: ``tick`` and ``sim_time`` (s). Several runs (a bug
report beside its what-if) go side by side under ``world/<run>/``, ``plots/<panel>/<run>/``
and so on, their plots on the same axes.

Force arrows: each starts where the force acts (normal and friction at the deepest foot, weight
and thrust at the centre of mass) and is ``com_height * log2(1 + F / W)`` long, W the ship's
weight: the weight itself is one com_height (it reaches the feet), an impact of 15 W four. The
friction arrow is drawn against the centre of mass's slip over the ground (the log records the
friction's size, not its direction).
"""
from __future__ import annotations

import math
import os
import shutil
import subprocess
import tempfile
import time
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from touchdown.sim.enums import SurfaceState
from touchdown.sim.errors import TouchdownError
from touchdown.view.scene import (ENERGY_PARTS, STATE_COLORS, LanderShape, Run, ShipTrack,
                                  framing_eye, read_run, terrain_grid)

FORCE_COLORS = {"normal": (40, 200, 80), "friction": (255, 140, 0), "weight": (150, 110, 255),
                "thrust": (255, 70, 40)}
#: one run of one ship: a colour per series
SERIES_COLORS = {
    "altitude_m": (70, 130, 255), "penetration_m": (255, 140, 0), "tilt_deg": (70, 130, 255),
    "v_radial_mps": (70, 130, 255), "v_tangential_mps": (255, 140, 0),
    "normal_force_n": (40, 200, 80), "friction_force_n": (255, 140, 0),
    "fuel_kg": (70, 130, 255), "energy_j": (245, 245, 245), "translational_j": (70, 130, 255),
    "rotational_j": (255, 110, 200), "gravity_j": (150, 110, 255), "centrifugal_j": (90, 200, 200),
    "centrifugal_spin_j": (60, 140, 140), "spring_j": (40, 200, 80)}
#: several runs or ships: a colour per (run, ship) trace, its panel's second series lighter
TRACE_COLORS = ((70, 130, 255), (255, 120, 40), (40, 190, 120), (230, 70, 170), (240, 220, 60),
                (150, 110, 255), (90, 200, 200), (200, 140, 90))
#: HUD and trajectory entries per ship at most (longer runs are thinned, keeping every change)
MAX_POINTS = 20_000
#: ships drawn at most without --ship (a fleet of thousands is picked one at a time)
MAX_SHIPS = 16

PANELS = (  # (entity under plots/, title, series names)
    ("altitude", "Feet: altitude and penetration (m)", ("altitude_m", "penetration_m")),
    ("tilt", "Tilt (deg)", ("tilt_deg",)),
    ("speed", "Speed relative to the surface (m/s)", ("v_radial_mps", "v_tangential_mps")),
    ("force", "Ground forces (N)", ("normal_force_n", "friction_force_n")),
    ("energy", "Energy (J): energy_j and its parts", ("energy_j",) + ENERGY_PARTS),
    ("fuel", "Fuel (kg)", ("fuel_kg",)),
)
SERIES_LABEL = {"altitude_m": "altitude", "penetration_m": "penetration", "tilt_deg": "tilt",
                "v_radial_mps": "vertical", "v_tangential_mps": "horizontal",
                "normal_force_n": "normal", "friction_force_n": "friction", "fuel_kg": "fuel",
                "energy_j": "energy_j", "translational_j": "translational",
                "rotational_j": "rotational", "gravity_j": "gravity",
                "centrifugal_j": "centrifugal", "centrifugal_spin_j": "centrifugal (spin)",
                "spring_j": "springs"}


class ViewError(TouchdownError):
    """A view that cannot be made (one line): exit 1, or 2 for a bad --redis."""

    exit_code = 1


@dataclass(frozen=True)
class Layout:
    """Where each run's entities go."""

    runs: tuple[Run, ...]

    def prefix(self, run: Run) -> str:
        return f"{run.label}/" if len(self.runs) > 1 else ""

    def name(self, run: Run, track: ShipTrack) -> str:
        """A ship's label on plots: its id, with the run's where there are several."""
        return f"{run.label}: {track.ship_id}" if len(self.runs) > 1 else track.ship_id


def _lighter(c, amount: float) -> list[int]:
    """``c`` mixed with white: amount 0 leaves it, 1 is white."""
    return [int(round(x + (255 - x) * amount)) for x in c]


def _thin(n: int, keep: np.ndarray) -> np.ndarray:
    """Indices of at most about MAX_POINTS of n entries, always including ``keep`` (bool)."""
    if n <= MAX_POINTS:
        return np.arange(n)
    step = int(math.ceil(n / MAX_POINTS))
    mask = np.zeros(n, dtype=bool)
    mask[::step] = True
    mask[-1] = True
    return np.flatnonzero(mask | keep)


def _times(rr, track: ShipTrack, idx: np.ndarray | None = None) -> list:
    tick, t = (track.tick, track.t_s) if idx is None else (track.tick[idx], track.t_s[idx])
    return [rr.TimeColumn("tick", sequence=tick), rr.TimeColumn("sim_time", duration=t)]


def _force_arrows(track: ShipTrack) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """(origins, vectors) per force, scaled as the module docstring says."""
    mass = track.series["mass_kg"]
    g = np.linalg.norm(track.gravity_site_mps2, axis=1)
    weight = mass * g
    h = track.com_height_m

    def length(f):
        return h * np.log2(1.0 + np.abs(f) / np.where(weight > 0, weight, 1.0))

    def along(direction, f):
        n = np.linalg.norm(direction, axis=1)
        unit = direction / np.where(n > 0, n, 1.0)[:, None]
        return unit * np.where(n > 0, length(f), 0.0)[:, None]

    slip = np.nan_to_num(track.slip_site_mps)
    slip_tan = slip - np.sum(slip * track.up_site, axis=1)[:, None] * track.up_site
    com = track.pos_site_m
    foot = track.lowest_foot_site_m
    thrust_n = np.linalg.norm(track.thrust_site_n, axis=1)
    return {
        "normal": (foot, along(track.up_site, track.series["normal_force_n"])),
        "friction": (foot, along(-slip_tan, track.series["friction_force_n"])),
        "weight": (com, along(track.gravity_site_mps2, weight)),
        "thrust": (com, along(track.thrust_site_n, thrust_n)),
    }


def _ship_geometry(rr, rec, path: str, track: ShipTrack, label: str | None) -> None:
    """A lander in its own frame (static): descent stage, ascent stage, four legs, footpads and
    the footprint the topple turns about."""
    a = track.leg_radius_m
    shape = LanderShape.of(a, track.com_height_m)
    box_half, box_center = shape.descent_half, shape.descent_center
    rec.log(f"{path}/ascent_stage", rr.Ellipsoids3D(
        centers=[shape.ascent_center], half_sizes=[shape.ascent_half],
        colors=[(200, 200, 205)], fill_mode="solid", labels=[label] if label else None,
        show_labels=bool(label)), static=True)
    feet = list(shape.feet)
    rec.log(f"{path}/legs", rr.LineStrips3D([[t, f] for t, f in zip(shape.leg_tops, feet)],
                                             radii=shape.leg_radius, colors=[(180, 180, 180)]),
            static=True)
    rec.log(f"{path}/footprint", rr.LineStrips3D([feet + [feet[0]]], radii=0.015 * a,
                                                  colors=[(255, 255, 255)]), static=True)
    rec.log(f"{path}/footpads", rr.Points3D(feet, radii=shape.pad_radius,
                                            colors=[(160, 160, 160)]), static=True)
    # the descent stage wears the state's colour: the status is visible in the 3D view too
    changes = np.flatnonzero(track.changes)
    colors = [[*STATE_COLORS[SurfaceState(int(s))], 255] for s in track.state[changes]]
    rec.log(f"{path}/descent_stage", rr.Boxes3D(half_sizes=[box_half], centers=[box_center],
                                                fill_mode="solid"), static=True)
    rr.send_columns(f"{path}/descent_stage", indexes=_times(rr, track, changes),
                    columns=rr.Boxes3D.columns(colors=np.array(colors, dtype=np.uint8)),
                    recording=rec)


def _trajectory(rr, rec, path: str, track: ShipTrack) -> None:
    """The centre of mass's path, one strip per stretch in one state, in that state's colour."""
    ch = track.changes
    idx = _thin(track.tick.shape[0], ch)
    strips, colors = [], []
    starts = np.flatnonzero(ch)
    ends = list(starts[1:]) + [track.tick.shape[0] - 1]
    for s0, s1 in zip(starts, ends):  # each stretch runs to the next one's first point
        sel = idx[(idx >= s0) & (idx <= s1)]
        if sel.size < 1:
            continue
        pts = track.pos_site_m[np.unique(np.concatenate([[s0], sel, [s1]]))]
        if pts.shape[0] == 1:
            pts = np.repeat(pts, 2, axis=0)
        strips.append(pts)
        colors.append(STATE_COLORS[SurfaceState(int(track.state[s0]))])
    rec.log(f"{path}/trajectory", rr.LineStrips3D(strips, colors=colors, radii=0.04),
            static=True)


def _hud_text(track: ShipTrack, k: int) -> str:
    s = SurfaceState(int(track.state[k]))
    ser = track.series
    head = f"# {s.label.upper()}\n\n"
    data = (f"t = {track.t_s[k]:.2f} s (tick {track.tick[k]})  \n"
            f"altitude {ser['altitude_m'][k]:.3f} m · vertical {ser['v_radial_mps'][k]:+.2f} m/s"
            f" · horizontal {ser['v_tangential_mps'][k]:.2f} m/s  \n"
            f"tilt {ser['tilt_deg'][k]:.1f}° · fuel {ser['fuel_kg'][k]:.1f} kg")
    if s == SurfaceState.TIPPED:
        return (head + f"## Tilt {ser['tilt_deg'][k]:.1f}°\n\n"
                "**Use RCS rotation to right the ship**\n\n" + data)
    if s == SurfaceState.LANDED:
        return head + "## Landed\n\n" + data
    if s == SurfaceState.CRASHED:
        return head + "## Crashed\n\n" + data
    return head + data


def _plots(rr, rec, layout: Layout, run: Run, track: ShipTrack, trace: int) -> None:
    times = _times(rr, track)
    base = f"{layout.prefix(run)}{track.ship_id}"
    who = layout.name(run, track)
    alone = len(layout.runs) == 1 and len(run.ships) == 1
    for panel, _title, names in PANELS:
        for j, name in enumerate(names):
            path = f"plots/{panel}/{base}/{name}"
            color = (SERIES_COLORS[name] if alone else
                     _lighter(TRACE_COLORS[trace % len(TRACE_COLORS)], min(0.7, 0.2 * j)))
            rec.log(path, rr.SeriesLines(colors=[color], names=f"{who} {SERIES_LABEL[name]}",
                                         widths=2.5 if name == "energy_j" else 1.5),
                    static=True)
            rr.send_columns(path, indexes=times,
                            columns=rr.Scalars.columns(scalars=track.series[name]),
                            recording=rec)


def _threshold(rr, rec, path: str, label: str, value: float, color, t_range) -> None:
    """A horizontal line over the run: two samples."""
    rec.log(path, rr.SeriesLines(colors=[color], names=label, widths=1.0), static=True)
    tick, t = t_range
    rr.send_columns(path, indexes=[rr.TimeColumn("tick", sequence=tick),
                                   rr.TimeColumn("sim_time", duration=t)],
                    columns=rr.Scalars.columns(scalars=np.array([value, value])), recording=rec)


def _thresholds(rr, rec, layout: Layout, run: Run) -> None:
    cp = run.params.contact
    first = run.ships[0]
    t_range = (np.array([first.tick[0], first.tick[-1]]), np.array([first.t_s[0], first.t_s[-1]]))
    p = layout.prefix(run).rstrip("/") or "limits"
    grey, red, amber = (150, 150, 150), (230, 40, 40), (255, 170, 0)
    tag = f"{run.label}: " if len(layout.runs) > 1 else ""
    _threshold(rr, rec, f"plots/tilt/{p}/tipped_angle", f"{tag}tipped_angle "
               f"{cp.tipped_angle_deg:g}°", cp.tipped_angle_deg, red, t_range)
    foot = float(run.critical_tilt_foot_deg[0])
    edge = float(run.critical_tilt_edge_deg[0])
    _threshold(rr, rec, f"plots/tilt/{p}/critical_toward_foot",
               f"{tag}topples past {foot:.1f}° toward a foot", foot, amber, t_range)
    _threshold(rr, rec, f"plots/tilt/{p}/critical_toward_edge",
               f"{tag}topples past {edge:.1f}° toward an edge", edge, grey, t_range)
    _threshold(rr, rec, f"plots/speed/{p}/bounce_speed", f"{tag}bounce_speed "
               f"{cp.bounce_speed_mps:g} m/s (descending)", -cp.bounce_speed_mps, amber, t_range)
    _threshold(rr, rec, f"plots/speed/{p}/crash_speed", f"{tag}crash_speed "
               f"{cp.crash_speed_mps:g} m/s (descending)", -cp.crash_speed_mps, red, t_range)


def _status(rr, rec, layout: Layout, run: Run, track: ShipTrack) -> None:
    base = f"{layout.prefix(run)}{track.ship_id}"
    labels = [s.label.upper() for s in SurfaceState]
    rec.log(f"status/{base}", rr.StateConfiguration(
        values=labels, labels=labels,
        colors=[[*STATE_COLORS[s], 255] for s in SurfaceState]), static=True)
    ch = np.flatnonzero(track.changes)
    rr.send_columns(f"status/{base}", indexes=_times(rr, track, ch),
                    columns=rr.StateChange.columns(
                        state=[SurfaceState(int(s)).label.upper() for s in track.state[ch]]),
                    recording=rec)
    keep = _thin(track.tick.shape[0], track.changes)
    rr.send_columns(f"hud/{base}", indexes=_times(rr, track, keep),
                    columns=rr.TextDocument.columns(
                        text=[_hud_text(track, int(k)) for k in keep],
                        media_type=["text/markdown"] * keep.size),
                    recording=rec)


def _events(rr, rec, layout: Layout, run: Run) -> None:
    if not run.events:
        return
    tag = f"[{run.label}] " if len(layout.runs) > 1 else ""
    texts, levels, colors = [], [], []
    for ev in run.events:
        to = SurfaceState(ev.to_state)
        texts.append(f"{tag}t={ev.t_s:.3f} s  {ev.event}  {ev.ship_id}: "
                     f"{SurfaceState(ev.from_state).label} -> {to.label}  "
                     f"v_radial {ev.v_radial_mps:+.2f} m/s  tilt {ev.tilt_deg:.1f}°")
        levels.append("ERROR" if to == SurfaceState.CRASHED else
                      "WARN" if to == SurfaceState.TIPPED else "INFO")
        colors.append([*STATE_COLORS[to], 255])
    path = f"events/{layout.prefix(run).rstrip('/') or 'log'}"
    tick = np.array([ev.tick for ev in run.events])
    t = np.array([ev.t_s for ev in run.events])
    rr.send_columns(path, indexes=[rr.TimeColumn("tick", sequence=tick),
                                   rr.TimeColumn("sim_time", duration=t)],
                    columns=rr.TextLog.columns(text=texts, level=levels,
                                               color=np.array(colors, dtype=np.uint8)),
                    recording=rec)


LEGEND = """### Reading the view
**3D** (landing-site frame: east, north, up, m). The ship's descent stage wears its state's
colour; its path is drawn in the colour of the state it was in: flying blue, contact yellow,
landed green, tipped red, crashed purple (the status lane below the 3D view uses the same).

**Arrows**: normal force (green) and friction (orange) at the deepest foot; weight (violet) and
thrust (red) at the centre of mass. Length = com_height × log2(1 + F / weight): the weight is one
com_height (it reaches the feet), 3 × weight two, 15 × weight four. Friction is drawn against the
slip of the centre of mass over the ground.

**Plots**: tilt with the topple angles (toward a foot, toward an edge) and `tipped_angle`; vertical
speed with `bounce_speed` and `crash_speed` (descending, negative); energy_j with its parts: with
no thrust and no RCS it never rises.
"""


def _eye(rrb, points: np.ndarray):
    """A camera holding every one of ``points`` in view over the whole run (view.scene
    .framing_eye), not only what is shown when the view opens."""
    position, target = framing_eye(points)
    return rrb.EyeControls3D(position=position.tolist(), look_target=target.tolist(),
                             eye_up=[0.0, 0.0, 1.0])


def blueprint(layout: Layout):
    import rerun.blueprint as rrb

    huds = [rrb.TextDocumentView(origin=f"hud/{layout.prefix(r)}{t.ship_id}",
                                 name=f"Status: {layout.name(r, t)}")
            for r in layout.runs for t in r.ships][:4]
    plots = [rrb.TimeSeriesView(origin=f"plots/{panel}", name=title,
                                plot_legend=rrb.PlotLegend(corner="RightTop", visible=True))
             for panel, title, _ in PANELS]
    if any(r.overview is not None for r in layout.runs):  # a fleet: the whole of it first
        fleet = np.concatenate([r.overview.pos_site_m for r in layout.runs
                                if r.overview is not None])
        plots = [rrb.Spatial3DView(origin="fleet", name="Fleet: every ship, coloured by state",
                                   eye_controls=_eye(rrb, fleet)),
                 rrb.TimeSeriesView(origin="fleet_states", name="Fleet: ships per state",
                                    plot_legend=rrb.PlotLegend(corner="RightTop", visible=True))
                 ] + plots
    return rrb.Blueprint(
        rrb.Horizontal(
            rrb.Vertical(
                rrb.Spatial3DView(origin="world", name="Landing site (east, north, up; m)",
                                  eye_controls=_eye(rrb, np.concatenate(
                                      [t.feet_site_m.reshape(-1, 3) for r in layout.runs
                                       for t in r.ships] + [np.zeros((0, 3))]))),
                rrb.StateTimelineView(origin="status", name="Status"),
                row_shares=[4, 1]),
            rrb.Grid(*plots, grid_columns=2, name="Over time"),
            rrb.Vertical(
                rrb.Tabs(*huds) if len(huds) > 1 else huds[0],
                rrb.TextLogView(origin="events", name="Events"),
                rrb.TextDocumentView(origin="legend", name="Legend"),
                row_shares=[2, 2, 2]),
            column_shares=[3, 3, 1.6]),
        rrb.TimePanel(timeline="sim_time", play_state="paused", state="collapsed"),
        collapse_panels=True,
    )


def _surface(rr, rec, layout: Layout) -> None:
    """The body's surface (with its terrain) around the site, over the ships' paths, from the
    first run's body."""
    run = layout.runs[0]
    pts = np.concatenate([t.pos_site_m for r in layout.runs for t in r.ships])
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    reach = max(t.leg_radius_m + t.com_height_m for r in layout.runs for t in r.ships)
    margin = max(1.5 * reach, 0.1 * float(max(hi[0] - lo[0], hi[1] - lo[1])))
    verts, tris = terrain_grid(run.params, (lo[0] - margin, hi[0] + margin),
                               (lo[1] - margin, hi[1] + margin))
    shade = np.clip(0.55 + 0.08 * (verts[:, 2] - verts[:, 2].min()), 0.55, 0.9)
    colors = (np.outer(shade, [200, 195, 185])).astype(np.uint8)
    rec.log("world/surface", rr.Mesh3D(vertex_positions=verts, triangle_indices=tris,
                                       vertex_colors=colors), static=True)


def build(runs: list[Run], recording_id: str):
    """A RecordingStream holding the runs (nothing is sent anywhere until a sink is set)."""
    import rerun as rr

    labels = [r.label for r in runs]
    if len(set(labels)) != len(labels):
        runs = [replace(r, label=f"{chr(65 + i)} {r.label}") for i, r in enumerate(runs)]
    layout = Layout(tuple(runs))
    rec = rr.RecordingStream("touchdown", recording_id=recording_id, send_properties=False)
    return rec, layout


def _overview(rr, rec, layout: Layout, run: Run) -> None:
    """The whole fleet: ships per state over time (one line per state), and every ship's
    position coloured by its state at the sampled ticks (the latest at the time cursor)."""
    ov = run.overview
    if ov is None or ov.tick.size == 0:
        return
    p = layout.prefix(run)
    times = [rr.TimeColumn("tick", sequence=ov.tick), rr.TimeColumn("sim_time", duration=ov.t_s)]
    for s in SurfaceState:
        path = f"fleet_states/{p}{s.label}"
        rec.log(path, rr.SeriesLines(colors=[STATE_COLORS[s]],
                                     names=f"{run.label + ': ' if p else ''}{s.label}"),
                static=True)
        rr.send_columns(path, indexes=times,
                        columns=rr.Scalars.columns(scalars=ov.counts[:, int(s)].astype(float)),
                        recording=rec)
    if ov.frame_tick.size:
        palette = np.array([STATE_COLORS[s] for s in SurfaceState], dtype=np.uint8)
        rec.log(f"fleet/{p}ships", rr.Points3D.from_fields(radii=[-3.0]), static=True)
        rr.send_columns(
            f"fleet/{p}ships",
            indexes=[rr.TimeColumn("tick", sequence=ov.frame_tick),
                     rr.TimeColumn("sim_time", duration=ov.frame_t_s)],
            columns=rr.Points3D.columns(positions=ov.pos_site_m,
                                        colors=palette[ov.state]).partition(ov.frame_rows),
            recording=rec)


def populate(rec, layout: Layout) -> None:
    import rerun as rr

    rec.set_log_tick_enabled(False)
    rec.log("world", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
    _surface(rr, rec, layout)
    rec.log("legend", rr.TextDocument(LEGEND, media_type="text/markdown"), static=True)
    trace = 0
    for run in layout.runs:
        _thresholds(rr, rec, layout, run)
        _events(rr, rec, layout, run)
        _overview(rr, rec, layout, run)
        for track in run.ships:
            base = f"world/{layout.prefix(run)}{track.ship_id}"
            rr.send_columns(f"{base}/ship", indexes=_times(rr, track),
                            columns=rr.Transform3D.columns(translation=track.pos_site_m,
                                                           quaternion=track.quat_site_xyzw),
                            recording=rec)
            several = len(layout.runs) > 1 or len(run.ships) > 1
            _ship_geometry(rr, rec, f"{base}/ship", track,
                           layout.name(run, track) if several else None)
            _trajectory(rr, rec, base, track)
            for name, (origins, vectors) in _force_arrows(track).items():
                rec.log(f"{base}/forces/{name}", rr.Arrows3D.from_fields(
                    colors=[FORCE_COLORS[name]], radii=0.05), static=True)
                rr.send_columns(f"{base}/forces/{name}", indexes=_times(rr, track),
                                columns=rr.Arrows3D.columns(origins=origins, vectors=vectors),
                                recording=rec)
            _plots(rr, rec, layout, run, track, trace)
            trace += 1
            _status(rr, rec, layout, run, track)


def load_runs(paths: list[str | Path], ship_id: str | None) -> tuple[list[Run], list[str]]:
    """The runs to show and the notes to print (a log read only in part, ships left out)."""
    runs, notes = [], []
    for p in paths:
        # only what is drawn is held: up to MAX_SHIPS ships in full, and the fleet's overview
        run = read_run(p, ship_id=ship_id, max_ships=MAX_SHIPS)
        if run.partial_note:
            notes.append(run.partial_note)
        if run.structure_note:
            notes.append(run.structure_note)
        if ship_id is None and run.fleet_size > MAX_SHIPS:
            notes.append(f"{p}: showing {MAX_SHIPS} of its {run.fleet_size} ships in full, every "
                         f"ship in the fleet overview; pick one with --ship ID")
        runs.append(run)
    return runs, notes


def write_rrd(runs: list[Run], out: str | Path) -> Path:
    """Write the view to ``out`` (via ``out.partial``, renamed when complete)."""
    import hashlib

    out = Path(out)
    rid = hashlib.sha256("|".join(str(r.path.resolve()) for r in runs).encode()).hexdigest()[:32]
    rec, layout = build(runs, rid)
    partial = Path(f"{out}.partial")
    try:
        rec.save(partial, default_blueprint=blueprint(layout))
        populate(rec, layout)
        rec.flush()
        rec.disconnect()
        os.replace(partial, out)
    except BaseException:
        partial.unlink(missing_ok=True)
        raise
    return out


def _free_port() -> int:
    import socket
    with socket.socket() as sock:  # never the default port a user's own viewer may hold
        sock.bind(("127.0.0.1", 0))
        return sock.getsockname()[1]


def start_viewer(args: list[str], env: dict | None = None) -> tuple[subprocess.Popen, int, Path]:
    """The viewer binary on a free port of 127.0.0.1, in a session of its own (so that it can
    be stopped as a whole), its stderr in a file. Returns the process, port and that file."""
    port = _free_port()
    err = Path(tempfile.mkstemp(prefix="touchdown-rerun-", suffix=".log")[1])
    with open(err, "w") as f:
        proc = subprocess.Popen([rerun_executable(), *args, "--bind", "127.0.0.1", "--port",
                                 str(port)], env=env, stdout=subprocess.DEVNULL, stderr=f,
                                start_new_session=True)
    return proc, port, err


def last_line(path: Path) -> str:
    try:
        lines = [ln for ln in path.read_text(errors="replace").splitlines() if ln.strip()]
    except OSError:
        return "no message"
    return (lines or ["no message"])[-1].strip()[:200]


def _stop(proc: subprocess.Popen) -> None:
    import signal
    try:
        os.killpg(proc.pid, signal.SIGTERM)
        proc.wait(timeout=10)
    except (ProcessLookupError, subprocess.TimeoutExpired):
        try:
            os.killpg(proc.pid, signal.SIGKILL)
        except ProcessLookupError:
            pass
        proc.wait()


def spawn_viewer(runs: list[Run], wait_s: float = 2.0) -> None:
    """Open the native viewer on the runs (it stays open; closing it is the user's). Without a
    display it cannot open a window: that is one line naming what to do instead."""
    proc, port, err = start_viewer(["--hide-welcome-screen"])
    try:
        time.sleep(wait_s)
        if proc.poll() is not None:
            raise ViewError(f"the viewer could not open a window ({last_line(err)}); write the "
                            f"view to a file with -o OUT.rrd, or a picture with --screenshot PNG")
        rec, layout = build(runs, "touchdown-view")
        rec.connect_grpc(f"rerun+http://127.0.0.1:{port}/proxy",
                         default_blueprint=blueprint(layout))
        populate(rec, layout)
        rec.flush()
        # a loaded machine can take longer than wait_s to find it has no display: a viewer that
        # stops while (or soon after) it is sent the run never showed it
        end = time.monotonic() + wait_s
        while time.monotonic() < end and proc.poll() is None:
            time.sleep(0.1)
        if proc.poll() is not None:
            raise ViewError(f"the viewer could not open a window ({last_line(err)}); write the "
                            f"view to a file with -o OUT.rrd, or a picture with --screenshot PNG")
    finally:
        err.unlink(missing_ok=True)


def rerun_executable() -> str:
    """The viewer binary that rerun-sdk ships (rerun_cli), else one on PATH."""
    try:
        import rerun_cli
        exe = Path(rerun_cli.__file__).with_name("rerun")
        if exe.exists():
            return str(exe)
    except ImportError:
        pass
    found = shutil.which("rerun")
    if not found:
        raise ViewError("cannot find the rerun viewer (pip install rerun-sdk)")
    return found


def screenshot(rrd: Path, png: Path, at_s: float | None = None, size: str = "1920x1080",
               settle_s: float = 4.0, start_timeout_s: float = 30.0) -> Path:
    """A picture of the view without a display or GPU: Rerun's headless viewer on software
    Vulkan (Debian's mesa-vulkan-drivers; ../shared/DEPENDENCY-NOTES.md), bound to 127.0.0.1 on
    a free port, its time cursor at ``at_s`` (default: the end of the run), taken ``settle_s``
    after loading so that the plots have fitted their data."""
    from rerun.experimental import ViewerClient

    png = Path(png)
    with tempfile.TemporaryDirectory(prefix="touchdown-rerun-") as home:
        # the viewer's first run writes settings and analytics ids: not into the user's home
        env = dict(os.environ, XDG_CONFIG_HOME=home, XDG_DATA_HOME=home, XDG_CACHE_HOME=home)
        proc, port, err = start_viewer(["--headless", "--hide-welcome-screen", "--window-size",
                                         size], env)
        try:
            client, t0 = None, time.monotonic()
            while client is None:
                if proc.poll() is not None:
                    raise ViewError(f"the headless viewer stopped (exit {proc.returncode}: "
                                    f"{last_line(err)}); it needs software Vulkan (apt install "
                                    f"mesa-vulkan-drivers)")
                try:
                    client = ViewerClient.connect(f"rerun+http://127.0.0.1:{port}/proxy")
                except Exception:  # noqa: BLE001 - not listening yet
                    if time.monotonic() - t0 > start_timeout_s:
                        raise ViewError(f"the headless viewer did not start within "
                                        f"{start_timeout_s:g} s") from None
                    time.sleep(0.2)
            client.open(str(Path(rrd).resolve()))
            if at_s is None:
                client.set_time("sim_time", play_state="following")
            else:
                client.set_time("sim_time", duration=float(at_s), play_state="paused")
            time.sleep(settle_s)
            client.save_screenshot(str(png.resolve()))
        except ViewError:
            raise
        except Exception as exc:  # noqa: BLE001 - the viewer's own failure, in one line
            raise ViewError(f"the headless viewer failed: {str(exc).splitlines()[0][:200]}") from None
        finally:
            _stop(proc)
            err.unlink(missing_ok=True)
    if not png.exists():
        raise ViewError(f"{png}: the headless viewer wrote no picture")
    return png
