"""Replay a trajectory in the browser: one self-contained HTML file, no network needed.

The page is meshcat's static viewer (three.js, inlined) with the robot, its
contacts and an animation recorded in it, plus a timeline of the events::

    traj = simulate(scene, 3.0, dense=True)
    traj.to_html("trot.html", scene)          # or write_html(traj, scene, "trot.html")

What is drawn:

- the robot's visual geometry (meshes, boxes, spheres, cylinders of the URDF's
  ``<visual>`` elements, loaded by Pinocchio's meshcat visualiser); a model
  without any (the project's own ``robots/``) gets a sphere at the origin of
  every body frame instead;
- each object of the scene (`contactdiff.model.objects`) as its shape (box,
  sphere, cylinder); a URDF object as spheres at its body frames;
- the planes that ground contacts press against (`contact_surfaces`: the floor,
  a table under an object) as thin light slabs whose top face is the plane
  (instead of meshcat's grid);
- one red sphere per contact at its contact point (the frame origin, or the
  lowest point of a round contact along its normal), shown exactly while the
  contact is in the segment's mode (closed: sticking or sliding), drawn over
  whatever hides it (a pad inside a grasp) and at least about 1 % of the view
  across (`visible_marker_radius`);
- the events as ticks on a timeline under the view (colour by kind, with a
  legend of the kinds that occur, a cursor at the animation's time, a click
  seeks there) and listed as text.

Frames: the states on a uniform grid of ``fps`` frames per second of simulated
time from ``traj.t0`` to ``traj.t`` (the last one at ``traj.t``), plus the
state at every event time (where a contact's marker switches), taken from the
dense output (``simulate(..., dense=True)``). Animation time 0 is ``traj.t0``;
the viewer plays one simulated second per second (its ``timeScale`` slider
changes that). Positions are in metres in the world frame (z up), as in the
model.

meshcat (the optional extra ``contactdiff[viz]``) is imported only here and only
when a page is written. Its own export (``Visualizer.static_html``) starts a
ZMQ/web server process; this module records meshcat's commands in-process
instead (`_Recorder`) and writes the page the same way that server does, so no
process is started and no port is opened.
"""

from __future__ import annotations

import base64
import html
import json
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import pinocchio as pin

from .errors import InvalidInputError, check_output_file, require_extra, write_failed
from .errors import MissingExtraError as MissingExtraError  # its home until it moved to errors.py
from .replay_frames import DEFAULT_FPS, Frames, ReplayedRun, positive_option, sample_frames
from .replay_geometry import contact_surfaces, drawn_geometry, marker_radius, model_size, visible_marker_radius

if TYPE_CHECKING:
    from .model.scene import Scene


ROOT = "contactdiff"
"""Name of the meshcat node under which the robot and the contacts are drawn."""

EVENT_COLOURS = {
    "touchdown": "#d62728",
    "lift-off": "#2ca02c",
    "slip": "#bcbd22",
    "stick": "#17becf",
    "bounce": "#ff7f0e",
    "grazing": "#9467bd",
    "zeno": "#000000",
    "bear": "#8c564b",
}
"""Timeline colour of each event kind (CSS)."""


def require_meshcat():
    """The meshcat modules, or `MissingExtraError` naming the extra to install."""
    meshcat = require_extra("meshcat", "viz", "the browser replay")
    for module in ("meshcat.animation", "meshcat.geometry"):  # meshcat's attributes once imported
        require_extra(module, "viz", "the browser replay")
    return meshcat, require_extra("umsgpack", "viz", "the browser replay")


# -- recording meshcat's commands --------------------------------------------------------
class _Recorder:
    """Stands in for meshcat's server window: keeps the scene's commands by path, as
    the server's scene tree does, so the page can be written without a server."""

    def __init__(self, umsgpack):
        self._pack = umsgpack.packb
        self.nodes: dict[tuple[str, ...], dict] = {}
        self.animation: bytes | None = None

    def _node(self, path: tuple[str, ...]) -> dict:
        return self.nodes.setdefault(path, {"object": None, "properties": [], "transform": None})

    def send(self, command) -> None:
        """Record a meshcat command (``set_object``, ``set_transform``, ``set_property``,
        ``set_animation``, ``delete``)."""
        data = command.lower()
        path = tuple(p for p in data["path"].split("/") if p)
        packed = self._pack(data)
        kind = data["type"]
        if kind == "set_object":
            node = self._node(path)
            node["object"], node["properties"] = packed, []
        elif kind == "set_transform":
            self._node(path)["transform"] = packed
        elif kind == "set_property":
            self._node(path)["properties"].append(packed)
        elif kind == "set_animation":
            self.animation = packed
        elif kind == "delete":
            for key in [k for k in self.nodes if k[: len(path)] == path]:
                del self.nodes[key]

    def commands(self) -> list[bytes]:
        """Every command, in the order meshcat's server replays them (objects, their
        properties and transforms node by node, the animation last)."""
        out = []
        for node in self.nodes.values():
            out += ([node["object"]] if node["object"] else []) + node["properties"]
            out += [node["transform"]] if node["transform"] else []
        return out + ([self.animation] if self.animation else [])


# -- the page --------------------------------------------------------------------------------
def replay_html(
    traj: ReplayedRun,
    scene: Scene,
    *,
    fps: float = DEFAULT_FPS,
    contact_radius: float | None = None,
    title: str | None = None,
    package_dirs: Sequence[str | Path] = (),
) -> str:
    """The replay page of ``traj`` as HTML text (see the module docstring).

    Args:
        traj: a `Trajectory` with dense output (``simulate(..., dense=True)``).
        scene: the `Scene` it was computed on (its robot and contacts).
        fps: frames per second of simulated time (> 0).
        contact_radius: radius of the contact markers (m); default 4% of the robot's
            size at the first state (`model_size`), at most 30 % of its objects' smallest
            half-dimension, at least `visible_marker_radius` of the camera's distance.
        title: the page's title; default the scene's name.
        package_dirs: folders (a path or a list) in which the URDF's ``package://NAME/...``
            meshes are found as ``DIR/NAME/...``, before the folders above the URDF.

    Raises:
        MissingExtraError: meshcat is not installed.
        InvalidInputError: no dense output, a bad ``fps`` or radius, a scene whose
            robot does not match the trajectory, a package folder that is not one or a
            mesh found nowhere.
    """
    meshcat, umsgpack = require_meshcat()
    from pinocchio.visualize import MeshcatVisualizer

    robot = scene.robot
    if len(traj.q0) != robot.nq:
        raise InvalidInputError(
            f"replay: the trajectory's q has {len(traj.q0)} entries but scene "
            f"{scene.name!r}'s robot has nq = {robot.nq}; pass the scene it was computed on"
        )
    size = model_size(robot, traj.q0)
    radius = marker_radius(robot, size) if contact_radius is None else positive_option(contact_radius, "contact_radius")
    frames = sample_frames(traj, fps)
    fps = positive_option(fps, "fps", "frames per second")
    distance = _camera_distance(robot, frames, size)
    points = _contact_points(scene, frames)

    geoms = drawn_geometry(robot, 0.6 * radius, package_dirs)
    recorder = _Recorder(umsgpack)
    viewer = meshcat.Visualizer(window=recorder)
    viz = MeshcatVisualizer(robot.model, None, geoms)
    viz.initViewer(viewer=viewer)
    viz.loadViewerModel(rootNodeName=ROOT)
    _load_surfaces(viewer, contact_surfaces(scene, points, size), meshcat)
    viewer["/Grid"].set_property("visible", False)  # meshcat's faint grid reads as a band at the horizon
    shown = visible_marker_radius(radius, distance) if contact_radius is None else radius
    contacts = _load_contact_markers(viewer, scene, shown, meshcat)

    animation = meshcat.animation.Animation(default_framerate=fps)
    _record_robot(animation, viewer, viz, robot, geoms, frames, fps, meshcat)
    _record_contacts(animation, scene, contacts, points, frames, fps, meshcat)
    viewer.set_animation(animation, play=True, repetitions=1)
    _place_camera(viewer, distance)

    info = {
        "scene": scene.name,
        "t0": traj.t0,
        "t": traj.t,
        "fps": fps,
        "frames": len(frames.times),
        "contacts": list(contacts),
        "events": [{"t": e.t, "kind": e.kind, "contacts": list(e.contacts)} for e in traj.events],
    }
    return _page(recorder.commands(), info, title or f"contactdiff replay: {scene.name}", meshcat)


def write_html(traj: ReplayedRun, scene: Scene, path: str | Path, **options) -> Path:
    """Write `replay_html` to ``path`` (UTF-8) and return the path.

    ``options`` are those of `replay_html`; a folder that is missing or takes no file
    raises `OutputFileError` (an `InvalidInputError`), before the page is built, and so
    does a write that fails.
    """
    target = check_output_file("replay: file", path, "replay.html")
    page = replay_html(traj, scene, **options)
    try:
        target.write_text(page, encoding="utf-8")
    except OSError as exc:
        raise write_failed("replay: file", path, exc) from None
    return target


def _load_surfaces(viewer, surfaces, meshcat) -> None:
    """Each contact plane (`contact_surfaces`) as a box under ``ROOT/surfaces`` (static)."""
    for surface in surfaces:
        node = viewer[f"{ROOT}/surfaces/{surface.name}"]
        node.set_object(
            meshcat.geometry.Box(list(surface.size)), meshcat.geometry.MeshLambertMaterial(color=surface.colour)
        )
        node.set_transform(surface.pose)


def _load_contact_markers(viewer, scene, radius: float, meshcat) -> dict[str, tuple[str, ...]]:
    """A red sphere per contact under ``ROOT/contacts``; returns name -> meshcat path.

    The markers are drawn over everything (no depth test; transparent, so three.js draws
    them after the opaque robot): a pad's contact point lies inside the grasp."""
    geometry, paths = meshcat.geometry, {}
    material = geometry.MeshPhongMaterial(color=0xD62728, opacity=0.9, depthTest=False)
    for c in scene.contacts:
        node = viewer[f"{ROOT}/contacts/{c.name}"]
        node.set_object(geometry.Sphere(radius), material)
        node.set_property("visible", False)
        paths[c.name] = node.path
    return paths


def _track(clip_tracks: dict, name: str, jstype: str, keys: np.ndarray, values: list, meshcat) -> None:
    clip_tracks[name] = meshcat.animation.AnimationTrack(name, jstype, list(keys), values)


def _clip(animation, path, fps: float, meshcat):
    clip = meshcat.animation.AnimationClip(fps=fps)
    animation.clips[path] = clip
    return clip.tracks


def _record_robot(animation, viewer, viz, robot, geoms, frames: Frames, fps: float, meshcat) -> None:
    """Position and quaternion tracks of every visual geometry, one key per frame;
    a constant scale key where the mesh is scaled."""
    model, data, gdata = robot.model, robot.model.createData(), pin.GeometryData(geoms)
    keys = _frame_keys(frames, fps)
    poses: list[list[pin.SE3]] = [[] for _ in range(geoms.ngeoms)]
    for q in frames.q:
        pin.forwardKinematics(model, data, q)
        pin.updateGeometryPlacements(model, data, geoms, gdata)
        for i in range(geoms.ngeoms):
            poses[i].append(pin.SE3(gdata.oMg[i]))
    for i, g in enumerate(geoms.geometryObjects):
        node = viewer[viz.getViewerNodeName(g, pin.GeometryType.VISUAL)]
        tracks = _clip(animation, node.path, fps, meshcat)
        _track(tracks, "position", "vector3", keys, [p.translation.tolist() for p in poses[i]], meshcat)
        _track(
            tracks,
            "quaternion",
            "quaternion",
            keys,
            [pin.Quaternion(p.rotation).coeffs().tolist() for p in poses[i]],
            meshcat,
        )  # x y z w
        scale = np.asarray(g.meshScale, dtype=float)
        if not np.allclose(scale, 1.0):
            _track(tracks, "scale", "vector3", keys[:1], [scale.tolist()], meshcat)


def _contact_points(scene, frames: Frames) -> dict[str, np.ndarray]:
    """Each contact's point at every frame (n, 3), m, world frame: the frame origin, less
    the radius along the normal for a round contact."""
    model, data = scene.robot.model, scene.robot.model.createData()
    points: dict[str, list[np.ndarray]] = {c.name: [] for c in scene.contacts}
    for q in frames.q:
        pin.framesForwardKinematics(model, data, q)
        for c in scene.contacts:
            points[c.name].append(data.oMf[c.fid].translation - c.radius * c.normal)
    return {name: np.array(p).reshape(-1, 3) for name, p in points.items()}


def _record_contacts(animation, scene, paths: dict, points: dict, frames: Frames, fps: float, meshcat) -> None:
    """Position and visibility tracks of the contact markers: visible exactly while
    the contact is in the mode (a discrete track: each key holds until the next)."""
    keys = _frame_keys(frames, fps)
    for c in scene.contacts:
        tracks = _clip(animation, paths[c.name], fps, meshcat)
        _track(tracks, "position", "vector3", keys, points[c.name].tolist(), meshcat)
        _track(tracks, "visible", "boolean", keys, [c.name in m for m in frames.modes], meshcat)


def _camera_distance(robot, frames: Frames, size: float) -> float:
    """The camera's distance from the world origin (m): one that covers the robot's
    size and how far its joints travel from the origin."""
    model, data = robot.model, robot.model.createData()
    reach = 0.0
    for q in frames.q[:: max(1, len(frames.q) // 50)]:
        pin.forwardKinematics(model, data, q)
        reach = max(reach, max(float(np.linalg.norm(data.oMi[j].translation)) for j in range(model.njoints)))
    return 2.2 * max(size, reach)


def _place_camera(viewer, distance: float) -> None:
    """Put the viewer's camera where it sees the whole run: it looks at the world
    origin (meshcat's orbit target) from the side and above, at ``distance`` (m)."""
    x, y, z = distance * np.array([0.55, -0.75, 0.35])  # world frame, z up
    # meshcat's camera node is rotated to three.js's y-up axes: (x, y, z) -> (x, z, -y)
    viewer["/Cameras/default/rotated/<object>"].set_property("position", [float(x), float(z), float(-y)])


def _frame_keys(frames: Frames, fps: float) -> np.ndarray:
    """Key times in frames (meshcat divides by the clip's fps): (t - t0) * fps."""
    return ((frames.times - frames.times[0]) * fps).tolist()


def _page(commands: list[bytes], info: dict, title: str, meshcat) -> str:
    """The HTML page: meshcat's viewer script inlined, every command as a ``data:``
    URI, the replay's facts as JSON and the timeline, as meshcat's server writes it."""
    script = Path(meshcat.__file__).parent / "viewer" / "dist" / "main.min.js"
    if not script.is_file():
        raise MissingExtraError(
            f"meshcat's viewer script {str(script)!r} is missing: pip install --force-reinstall meshcat"
        )
    viewer_js = script.read_text(encoding="utf-8").replace("</script", "<\\/script")
    drawing = "".join(
        'fetch("data:application/octet-binary;base64,{}")'
        ".then(r => r.arrayBuffer()).then(b => viewer.handle_command_bytearray(new Uint8Array(b)));\n".format(
            base64.b64encode(c).decode("ascii")
        )
        for c in commands
    )
    info_json = json.dumps(info).replace("</", "<\\/")
    events = (
        "".join(
            f"<li>{e['t']:.6f} s: {html.escape(e['kind'])} ({html.escape(', '.join(e['contacts']))})</li>"
            for e in info["events"]
        )
        or "<li>none</li>"
    )
    return _TEMPLATE.format(
        title=html.escape(title),
        viewer_js=viewer_js,
        drawing=drawing,
        info=info_json,
        n_events=len(info["events"]),
        events=events,
        timeline_js=_TIMELINE_JS,
        colours=json.dumps(EVENT_COLOURS),
        legend=_legend(info["events"]),
    )


def _legend(events: list[dict]) -> str:
    """The timeline's key: a swatch and the name of each event kind that occurs (in
    `EVENT_COLOURS` order), and the cursor's."""
    kinds = {e["kind"] for e in events}
    keys = [(kind, colour) for kind, colour in EVENT_COLOURS.items() if kind in kinds]
    keys += sorted((kind, "#555") for kind in kinds - set(EVENT_COLOURS))
    keys.append(("animation time (click the bar to seek)", "#1f77b4"))
    return "".join(
        f'<span class="key" data-kind="{html.escape(kind)}"><i style="background:{colour}"></i>'
        f"{html.escape(kind)}</span>"
        for kind, colour in keys
    )


_TIMELINE_JS = """
(function () {
  const info = JSON.parse(document.getElementById("contactdiff-replay").textContent);
  const colours = JSON.parse(document.getElementById("contactdiff-colours").textContent);
  const bar = document.getElementById("timeline"), cursor = document.getElementById("cursor");
  const span = Math.max(info.t - info.t0, 1e-12);
  for (const e of info.events) {
    const tick = document.createElement("div");
    tick.className = "tick";
    tick.style.left = (100 * (e.t - info.t0) / span) + "%";
    tick.style.background = colours[e.kind] || "#555";
    tick.title = e.t.toFixed(6) + " s: " + e.kind + " (" + e.contacts.join(", ") + ")";
    bar.appendChild(tick);
  }
  bar.addEventListener("click", (ev) => {
    const r = bar.getBoundingClientRect();
    const time = span * Math.min(1, Math.max(0, (ev.clientX - r.left) / r.width));
    viewer.animator.pause();
    viewer.animator.seek(time);
    viewer.animator.display_progress(time);
  });
  const clock = document.getElementById("clock");
  function follow() {
    const time = viewer.animator.time || 0;
    cursor.style.left = (100 * Math.min(time, span) / span) + "%";
    clock.textContent = "t = " + (info.t0 + time).toFixed(3) + " s";
    requestAnimationFrame(follow);
  }
  follow();
})();
"""

_TEMPLATE = """<!DOCTYPE html>
<html>
<head><meta charset="utf-8"><title>{title}</title>
<style>
body {{ margin: 0; font: 13px sans-serif; }}
#meshcat-pane {{ width: 100vw; height: 100vh; overflow: hidden; }}
#replay-panel {{ position: fixed; left: 12px; right: 280px; bottom: 10px; background: rgba(255,255,255,0.85);
  padding: 6px 10px; border-radius: 4px; }}
#timeline {{ position: relative; height: 18px; background: #ddd; cursor: pointer; margin-top: 4px; }}
#timeline .tick {{ position: absolute; top: 0; width: 2px; height: 18px; }}
#cursor {{ position: absolute; top: -3px; width: 2px; height: 24px; background: #1f77b4; }}
#replay-panel details {{ max-height: 30vh; overflow: auto; }}
#legend {{ margin-top: 3px; font-size: 12px; }}
#legend .key {{ margin-right: 12px; white-space: nowrap; }}
#legend .key i {{ display: inline-block; width: 3px; height: 12px; margin-right: 4px; vertical-align: -2px; }}
</style></head>
<body>
<div id="meshcat-pane"></div>
<div id="replay-panel"><b>{title}</b> <span id="clock"></span>
 <div id="timeline"><div id="cursor"></div></div>
 <div id="legend">{legend}</div>
 <details><summary>{n_events} events (time, kind, contacts)</summary><ol id="events">{events}</ol></details>
</div>
<script type="application/json" id="contactdiff-replay">{info}</script>
<script type="application/json" id="contactdiff-colours">{colours}</script>
<script>
{viewer_js}
</script>
<script>
var viewer = new MeshCat.Viewer(document.getElementById("meshcat-pane"));
{drawing}
</script>
<script>
{timeline_js}
</script>
</body>
</html>
"""
