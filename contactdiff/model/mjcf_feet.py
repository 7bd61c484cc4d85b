"""Feet an MJCF model marks itself: sphere collision geoms on leaf bodies.

MuJoCo models give a legged robot's feet as collision spheres at the ends of
its legs (Menagerie's Go2: geoms ``FL``, ``FR``, ``RL``, ``RR`` of radius
0.022 m on the calf bodies). `sphere_feet` takes, for a floating base, every
sphere geom that collides (``contype`` or ``conaffinity`` non-zero) on a body
with no child body, adds an operational frame at its centre (named after the
geom) and keeps those whose lowest point at the reference pose lies within the
foot band of `contactdiff.model.feet` (``max(BAND_MIN, BAND_FRACTION × robot
height)`` above the robot's lowest point), so a hand's fingertip spheres are
not feet. Each foot is a round contact of the sphere's radius
(``FootChoice.radii``). Where no sphere qualifies, the rule of
`contactdiff.model.feet` applies.
"""

from __future__ import annotations

from dataclasses import dataclass
from xml.etree.ElementTree import Element

import numpy as np
import pinocchio as pin

from .feet import BAND_FRACTION, BAND_MIN, FootChoice, FootRule, LeftOut, up_direction
from .mjcf_xml import bodies, numbers


@dataclass(frozen=True)
class SphereGeom:
    """A collision sphere of an MJCF body (radius and centre in m, centre in the body frame)."""

    name: str
    body: str
    radius: float
    centre: tuple[float, float, float]


def collision_spheres(root: Element, leaves_only: bool = True) -> list[SphereGeom]:
    """The colliding sphere geoms of the (class-resolved) tree, on leaf bodies by default."""
    found = []
    for body, _ in bodies(root):
        if leaves_only and body.find("body") is not None:
            continue
        for k, geom in enumerate(body.findall("geom")):
            if geom.get("type", "sphere") != "sphere" or geom.get("fromto") is not None:
                continue
            contype = numbers(geom.get("contype"), (1.0,))[0]
            conaffinity = numbers(geom.get("conaffinity"), (1.0,))[0]
            if contype == 0 and conaffinity == 0:
                continue
            radius = numbers(geom.get("size"), (0.0,))[0]
            if radius <= 0:
                continue
            centre = numbers(geom.get("pos"), (0.0, 0.0, 0.0))
            name = geom.get("name") or f"{body.get('name')}_sphere{k}"
            x, y, z = (float(c) for c in centre[:3])
            found.append(SphereGeom(name, body.get("name", ""), float(radius), (x, y, z)))
    return found


def add_sphere_frames(model: pin.Model, spheres: list[SphereGeom]) -> dict[str, SphereGeom]:
    """Add an OP_FRAME at each sphere's centre (named after the geom, ``_sphere`` appended
    if the name is taken); returns ``{frame: sphere}``. Spheres of bodies Pinocchio has no
    frame for are skipped."""
    frames = {}
    for sphere in spheres:
        if not sphere.body or not model.existFrame(sphere.body):
            continue
        body_id = model.getFrameId(sphere.body)
        body = model.frames[body_id]
        name = sphere.name
        while model.existFrame(name):
            name += "_sphere"
        placement = body.placement * pin.SE3(np.eye(3), np.array(sphere.centre))
        model.addFrame(pin.Frame(name, body.parentJoint, body_id, placement, pin.FrameType.OP_FRAME), False)
        frames[name] = sphere
    return frames


def sphere_feet(model: pin.Model, root: Element, q_ref: np.ndarray) -> FootChoice | None:
    """Feet from the model's collision spheres on leaf bodies (module rule), adding their
    frames to ``model``; None when no sphere lies in the foot band (no frame added then)."""
    spheres = collision_spheres(root)
    if not spheres:
        return None
    trial = pin.Model(model)
    frames = add_sphere_frames(trial, spheres)
    if not frames:
        return None
    data = trial.createData()
    pin.framesForwardKinematics(trial, data, q_ref)
    up = up_direction(trial)
    heights = [float(up @ data.oMf[i].translation) for i, f in enumerate(trial.frames) if f.parentJoint != 0]
    lows = {name: float(up @ data.oMf[trial.getFrameId(name)].translation) - s.radius
            for name, s in frames.items()}
    bottom = min(heights + list(lows.values()))
    top = max(heights + [h + 2 * frames[n].radius for n, h in lows.items()])
    band = max(BAND_MIN, BAND_FRACTION * (top - bottom))
    feet = [n for n, h in lows.items() if h - bottom <= band]
    if not feet:
        return None
    left_out = tuple(LeftOut(n, h - bottom, f"{h - bottom:.3g} m up") for n, h in lows.items() if n not in feet)
    add_sphere_frames(model, [frames[n] for n in feet])
    return FootChoice(tuple(feet), FootRule.MJCF_SPHERES, band, {n: lows[n] - bottom for n in feet}, left_out,
                      radii={n: frames[n].radius for n in feet})
