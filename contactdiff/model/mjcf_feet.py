"""Feet an MJCF model marks itself: sphere collision geoms on leaf bodies.

MuJoCo models give a legged robot's feet as collision spheres at the ends of
its legs (Menagerie's Go2: geoms ``FL``, ``FR``, ``RL``, ``RR`` of radius
0.022 m on the calf bodies). `sphere_feet` takes, for a floating base, every
sphere geom that collides (``contype`` or ``conaffinity`` non-zero) on a body
with no child body, adds an operational frame at its centre and keeps those
whose lowest point at the reference pose lies within the foot band of
`contactdiff.model.feet` (``max(BAND_MIN, BAND_FRACTION × robot height)`` above
the robot's lowest point), so a hand's fingertip spheres are not feet. Each foot
is a round contact of the sphere's radius (``FootChoice.radii``). Where no
sphere qualifies, the rule of `contactdiff.model.feet` applies.

**Names.** A sphere's frame is named after its geom. An unnamed geom's frame is
named after its body (the body's own frame already has the body's name):
``<body>_sphere`` when it is the body's only unnamed colliding sphere (ANYmal's
``LF_SHANK_sphere``), else ``<body>_sphere1``, ``<body>_sphere2``, ... in the
order of the file (Unitree G1's four spheres under each ``ankle_roll_link``).

**One foot, several points.** Spheres on one leaf body are one foot, touching
at several points: each is a contact of its own, and ``FootChoice.limbs`` maps
the body to its sphere frames, so that `contactdiff.check_decoupling` measures
couplings between limbs, not between two points of one rigid foot.
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
        geoms = [g for g in body.findall("geom") if _colliding_sphere(g)]
        unnamed = [g for g in geoms if not g.get("name")]
        for geom in geoms:
            name = geom.get("name")
            if not name:  # named after the body (module notes), indexed when it has several
                name = f"{body.get('name')}_sphere" + (f"{unnamed.index(geom) + 1}" if len(unnamed) > 1 else "")
            centre = numbers(geom.get("pos"), (0.0, 0.0, 0.0))
            x, y, z = (float(c) for c in centre[:3])
            found.append(SphereGeom(name, body.get("name", ""), float(numbers(geom.get("size"), (0.0,))[0]), (x, y, z)))
    return found


def _colliding_sphere(geom: Element) -> bool:
    """A sphere geom (not given by ``fromto``) of positive radius with ``contype`` or
    ``conaffinity`` non-zero."""
    if geom.get("type", "sphere") != "sphere" or geom.get("fromto") is not None:
        return False
    contype = numbers(geom.get("contype"), (1.0,))[0]
    conaffinity = numbers(geom.get("conaffinity"), (1.0,))[0]
    return (contype != 0 or conaffinity != 0) and numbers(geom.get("size"), (0.0,))[0] > 0


def sphere_limbs(frames: dict[str, SphereGeom], feet) -> dict[str, tuple[str, ...]]:
    """``{body: its feet}`` for the bodies that carry several of ``feet`` (sphere frames of
    ``frames``): one foot touching at several points (module notes)."""
    by_body: dict[str, list[str]] = {}
    for foot in feet:
        if foot in frames:
            by_body.setdefault(frames[foot].body, []).append(foot)
    return {body: tuple(names) for body, names in by_body.items() if len(names) > 1}


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
    lows = {name: float(up @ data.oMf[trial.getFrameId(name)].translation) - s.radius for name, s in frames.items()}
    bottom = min(heights + list(lows.values()))
    top = max(heights + [h + 2 * frames[n].radius for n, h in lows.items()])
    band = max(BAND_MIN, BAND_FRACTION * (top - bottom))
    feet = [n for n, h in lows.items() if h - bottom <= band]
    if not feet:
        return None
    left_out = tuple(LeftOut(n, h - bottom, f"{h - bottom:.3g} m up") for n, h in lows.items() if n not in feet)
    add_sphere_frames(model, [frames[n] for n in feet])
    return FootChoice(
        tuple(feet),
        FootRule.MJCF_SPHERES,
        band,
        {n: lows[n] - bottom for n in feet},
        left_out,
        radii={n: frames[n].radius for n in feet},
        limbs=sphere_limbs(frames, feet),
    )
