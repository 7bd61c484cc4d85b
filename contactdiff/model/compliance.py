"""Series-compliant feet: a small foot mass on a spring along the leg.

The paper's discussion of series-elastic and direct-drive legs suggests a design
lever for decoupling: if what touches the ground is a light mass connected to
the leg through a spring, an impact stops that mass and barely the rest of the
robot, so the landing order of two feet matters less. `add_compliant_feet`
builds that design from any robot or scene:

* each foot frame gets a new prismatic joint ``<foot>_spring``, a child of the
  joint that carried the foot (the knee of a quadruped), placed at the foot point;
* its axis is fixed in that lower-leg body: by default the *shank axis*, the
  line from the lower-leg joint to the foot (the direction a pogo-stick or
  telescopic foot spring works along); or a world direction given at the
  scene's reference pose;
* the joint carries a point mass ``foot_mass`` (kg) at the foot point, and the
  foot frame (same name, same orientation) moves onto it, so contacts, efforts
  and reports that name the foot keep working;
* a `JointSpring` (``stiffness`` N/m, ``damping`` N s/m, rest 0) acts on each
  new joint. Its coordinate is the foot's displacement along the axis (m);
  positive moves the foot away from the knee (extends the leg).

At the spring's rest (new coordinates 0) every frame, the foot included, is
where it was in the original model.

Where the foot mass comes from (``mass_from``):

* ``"leg"`` (default): it is taken out of the lower-leg body, as a point mass
  at the foot point. Total mass, centre of mass and, at the spring's rest, the
  mass matrix of the original coordinates are unchanged; only the compliance
  is new. A body cannot give away more than its mass distribution allows (its
  remaining pseudo-inertia must stay positive semi-definite: for solo12's
  shank about 20 g of its 38 g); a larger ``foot_mass`` is an error that says
  the limit.
* ``"added"``: the foot mass is added; total mass grows by ``foot_mass`` per foot.

Each spring coordinate follows the coordinates of its foot's joint (Pinocchio
keeps the coordinates of every subtree contiguous), so the layout of ``q`` and
``v`` changes; `compliant_state` carries a state of the original robot over
(joints matched by name, springs at rest).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import pinocchio as pin
from numpy.typing import ArrayLike

from ..errors import InvalidInputError, check_number, unknown_name
from .efforts import JointSpring, Spring, UserEffort
from .robot import Robot
from .scene import Scene

MASS_SOURCES = ("leg", "added")
AXES = ("shank",)
SPRING_SUFFIX = "_spring"


def add_compliant_feet(
    source: Robot | Scene,
    stiffness: float,
    foot_mass: float,
    damping: float = 0.0,
    *,
    mass_from: str = "leg",
    axis="shank",
    feet: Sequence[str] | None = None,
) -> Scene:
    """A scene whose feet sit on springs along the leg (see the module docstring).

    Args:
        source: a `Robot` (its feet, found automatically, get ground contacts as in
            `Scene.from_robot`) or a `Scene` (its contacts, efforts, gravity and
            initial state are kept; the new coordinates start at rest, zero velocity).
        stiffness: spring stiffness along the axis (N/m), > 0.
        foot_mass: mass moving with the foot (kg), > 0.
        damping: spring damping (N s/m), >= 0.
        mass_from: ``"leg"`` (taken from the lower-leg body) or ``"added"``.
        axis: ``"shank"`` (lower-leg joint to foot, fixed in the lower leg) or a
            3-vector: a world direction at the reference pose (the robot's
            ``q_ref``), e.g. ``(0, 0, -1)`` for a vertical spring; it is then fixed
            in the lower leg.
        feet: foot frames to make compliant; default the robot's feet (for a
            robot) or the scene's contact frames (for a scene).

    Returns:
        A `Scene` on the new robot with one `JointSpring` per foot added.

    Raises:
        InvalidInputError: bad numbers or options, a foot mass the lower leg cannot
            give, a zero spring axis, a scene with an effort other than
            `JointSpring` and `Spring` (a `UserEffort` is written for the original
            coordinates; a controller that finds its joints from the kinematic tree
            would drive the spring joints too).
        UnknownNameError: a foot frame that does not exist.
    """
    stiffness = check_number("add_compliant_feet", "stiffness", stiffness, minimum=0.0)
    foot_mass = check_number("add_compliant_feet", "foot_mass", foot_mass, minimum=0.0)
    damping = check_number("add_compliant_feet", "damping", damping, minimum=0.0)
    if stiffness <= 0 or foot_mass <= 0:
        raise InvalidInputError(
            f"add_compliant_feet: stiffness and foot_mass must be > 0, "
            f"got stiffness={stiffness!r} N/m, foot_mass={foot_mass!r} kg"
        )
    if mass_from not in MASS_SOURCES:
        raise InvalidInputError(
            f"add_compliant_feet: mass_from must be one of {', '.join(MASS_SOURCES)}; got {mass_from!r}"
        )
    if isinstance(source, Scene):
        scene, robot = source, source.robot
        for e in scene.effort_specs:
            if not isinstance(e, (JointSpring, Spring)):
                label = e.name if isinstance(e, UserEffort) else type(e).__name__
                raise InvalidInputError(
                    f"add_compliant_feet: scene {scene.name!r} has the effort {label!r}, which is not a "
                    "JointSpring or Spring: it may be written for the original coordinates, or pick its joints "
                    "from the kinematic tree and then drive the new spring joints too; transform the scene "
                    "without it and build the final scene on the returned robot yourself"
                )
        default_feet = list(dict.fromkeys(c.spec.frame for c in scene.contacts))
    elif isinstance(source, Robot):
        scene, robot = None, source
        default_feet = list(robot.feet)
        if not default_feet:
            raise InvalidInputError(
                f"add_compliant_feet: robot {robot.name!r} has no feet found automatically; pass feet=[...] frame names"
            )
    else:
        raise InvalidInputError(f"add_compliant_feet: source must be a Robot or a Scene, got {source!r}")
    feet = default_feet if feet is None else list(feet)
    if not feet or len(set(feet)) != len(feet):
        raise InvalidInputError(f"add_compliant_feet: feet must be distinct frame names, got {feet!r}")
    for foot in feet:
        robot.frame_id(foot)  # raises with the list of frames

    new_robot = _compliant_robot(robot, feet, foot_mass, mass_from, axis)
    springs = tuple(JointSpring(foot + SPRING_SUFFIX, stiffness, damping, 0.0) for foot in feet)
    if scene is None:
        base = Scene.from_robot(new_robot)
        return Scene(new_robot, base.contact_specs, springs, name=new_robot.name)
    q0, v0 = compliant_state(robot, new_robot, scene.q0, scene.v0)
    return Scene(
        new_robot, scene.contact_specs, scene.effort_specs + springs, None, q0, v0, f"{scene.name}+compliant feet"
    )


def _spring_axis(model: pin.Model, data: pin.Data, parent: int, X: pin.SE3, world_axis, foot: str) -> np.ndarray:
    """Unit axis of a foot's spring in the lower-leg joint frame."""
    if world_axis is None:
        direction = X.translation.copy()  # lower-leg joint -> foot, in the lower-leg frame
        if np.linalg.norm(direction) < 1e-9:
            raise InvalidInputError(
                f"add_compliant_feet: foot {foot!r} sits at its joint's origin, so the shank axis is "
                "undefined; give axis=(x, y, z)"
            )
    else:
        direction = data.oMi[parent].rotation.T @ world_axis  # world -> lower-leg frame at q_ref
    return direction / np.linalg.norm(direction)


def _world_axis(axis):
    if isinstance(axis, str):
        if axis in AXES:
            return None
        raise unknown_name("spring axis", axis, list(AXES) + ["(a 3-vector)"])
    try:
        world_axis = np.asarray(axis, dtype=float).reshape(3)
    except (TypeError, ValueError):
        raise InvalidInputError(f"add_compliant_feet: axis must be 'shank' or 3 numbers, got {axis!r}") from None
    if not np.all(np.isfinite(world_axis)) or np.linalg.norm(world_axis) < 1e-12:
        raise InvalidInputError(f"add_compliant_feet: axis must be a finite non-zero 3-vector, got {axis!r}")
    return world_axis


def _compliant_robot(robot: Robot, feet: list[str], foot_mass: float, mass_from: str, axis) -> Robot:
    """Rebuild the model joint by joint, a spring joint right after each foot's joint.

    Pinocchio's algorithms need every subtree's coordinates contiguous, so the new
    joints cannot simply be appended at the end of the model.
    """
    old = robot.model
    world_axis = _world_axis(axis)
    data = old.createData()
    pin.framesForwardKinematics(old, data, robot.q_ref)
    on_joint: dict[int, list[tuple[str, int]]] = {}
    for foot in feet:
        fid = old.getFrameId(foot)
        on_joint.setdefault(old.frames[fid].parentJoint, []).append((foot, fid))
    new = pin.Model()
    new.name, new.gravity = old.name, old.gravity
    jmap, springs = {0: 0}, {}
    for j in range(1, old.njoints):
        jid = new.addJoint(jmap[old.parents[j]], old.joints[j], old.jointPlacements[j], old.names[j])
        jmap[j] = jid
        inertia = old.inertias[j]
        if mass_from == "leg":
            for foot, fid in on_joint.get(j, []):
                inertia = _remove_point_mass(
                    inertia, foot_mass, old.frames[fid].placement.translation, old.names[j], foot
                )
        new.appendBodyToJoint(jid, inertia, pin.SE3.Identity())
        for foot, fid in on_joint.get(j, []):
            name = foot + SPRING_SUFFIX
            if old.existJointName(name) or new.existJointName(name):
                raise InvalidInputError(f"add_compliant_feet: the model already has a joint {name!r}")
            X = old.frames[fid].placement
            direction = _spring_axis(old, data, j, X, world_axis, foot)
            # the spring joint keeps the foot frame's orientation: its axis is expressed in it
            sid = new.addJoint(
                jid,
                pin.JointModelPrismaticUnaligned(X.rotation.T @ direction),
                pin.SE3(X.rotation, X.translation),
                name,
            )
            new.appendBodyToJoint(sid, pin.Inertia(foot_mass, np.zeros(3), np.zeros((3, 3))), pin.SE3.Identity())
            springs[fid] = sid
    fmap = {0: 0}
    for fid in range(1, old.nframes):
        f = old.frames[fid]
        parent_frame = fmap[f.parentFrame]
        if fid in springs:  # the foot frame rides on its spring joint, same pose at rest
            parent_frame = new.addJointFrame(springs[fid], parent_frame)
            frame = pin.Frame(f.name, springs[fid], parent_frame, pin.SE3.Identity(), f.type, f.inertia)
        else:
            frame = pin.Frame(f.name, jmap[f.parentJoint], parent_frame, f.placement, f.type, f.inertia)
        fmap[fid] = new.addFrame(frame, False)  # inertias were appended to the joints already
    _copy_coordinate_data(old, new, jmap)
    q_ref = _map_configuration(old, new, jmap, robot.q_ref)
    return Robot(
        new,
        f"{robot.name}+compliant feet",
        "",
        robot.floating_base,
        q_ref,
        robot.feet,
        robot.actuated,
        objects=robot.objects,
    )


_Q_FIELDS = ("lowerPositionLimit", "upperPositionLimit")
_V_FIELDS = (
    "armature",
    "rotorInertia",
    "rotorGearRatio",
    "friction",
    "damping",
    "effortLimit",
    "lowerEffortLimit",
    "upperEffortLimit",
    "velocityLimit",
    "lowerVelocityLimit",
    "upperVelocityLimit",
    "lowerDryFrictionLimit",
    "upperDryFrictionLimit",
)


def _copy_coordinate_data(old: pin.Model, new: pin.Model, jmap: dict) -> None:
    """Per-coordinate vectors (limits, armature, ...) of the original joints, by joint."""
    for fields, idx, size in ((_Q_FIELDS, "idx_qs", "nqs"), (_V_FIELDS, "idx_vs", "nvs")):
        for name in fields:
            if not hasattr(old, name):
                continue
            src, dst = np.array(getattr(old, name)), np.array(getattr(new, name))
            if src.shape != (getattr(old, "nq" if idx == "idx_qs" else "nv"),):
                continue
            for j, k in jmap.items():
                if j == 0:
                    continue
                a, b, n = getattr(old, idx)[j], getattr(new, idx)[k], getattr(old, size)[j]
                dst[b : b + n] = src[a : a + n]
            setattr(new, name, dst)
    for entry in old.referenceConfigurations:
        new.referenceConfigurations[entry.key()] = _map_configuration(old, new, jmap, entry.data())


def _map_configuration(old: pin.Model, new: pin.Model, jmap: dict, q: np.ndarray) -> np.ndarray:
    out = pin.neutral(new)
    for j, k in jmap.items():
        if j:
            a, b, n = old.idx_qs[j], new.idx_qs[k], old.nqs[j]
            out[b : b + n] = q[a : a + n]
    return out


def compliant_state(
    robot: Robot, compliant: Robot, q: ArrayLike, v: ArrayLike | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """A state ``(q, v)`` of ``robot`` as a state of ``compliant``: every joint of
    ``robot`` keeps its value (matched by name), the springs are at rest and still.

    Args:
        robot: the original robot.
        compliant: a robot built from it (e.g. ``add_compliant_feet(...).robot``).
        q: configuration of ``robot`` (nq,).
        v: velocity of ``robot`` (nv,), tangent space; default zero.

    Returns:
        ``(q, v)`` of ``compliant``.
    """
    old, new = robot.model, compliant.model
    q = np.asarray(q, dtype=float)
    v = np.zeros(old.nv) if v is None else np.asarray(v, dtype=float)
    if q.shape != (old.nq,) or v.shape != (old.nv,):
        raise InvalidInputError(
            f"compliant_state: q must have shape ({old.nq},) and v ({old.nv},); got {q.shape} and {v.shape}"
        )
    q_out, v_out = pin.neutral(new), np.zeros(new.nv)
    for j in range(1, old.njoints):
        name = old.names[j]
        if not new.existJointName(name):
            raise unknown_name(f"joint of robot {compliant.name!r}", name, list(new.names)[1:])
        k = new.getJointId(name)
        q_out[new.idx_qs[k] : new.idx_qs[k] + old.nqs[j]] = q[old.idx_qs[j] : old.idx_qs[j] + old.nqs[j]]
        v_out[new.idx_vs[k] : new.idx_vs[k] + old.nvs[j]] = v[old.idx_vs[j] : old.idx_vs[j] + old.nvs[j]]
    return q_out, v_out


def _remove_point_mass(inertia: pin.Inertia, mass: float, point: np.ndarray, body: str, foot: str) -> pin.Inertia:
    """``inertia`` minus a point mass at ``point`` (body frame), if what remains is physical.

    A rigid body's pseudo-inertia ``J = ∫ [r; 1][r; 1]^T dm`` is positive semi-definite;
    removing a point mass ``m`` at ``p`` leaves ``J - m [p; 1][p; 1]^T``, which stays
    so exactly when ``m <= 1 / ([p; 1]^T J^-1 [p; 1])`` (with the pseudo-inverse, and
    ``[p; 1]`` in the range of ``J``, when ``J`` is singular: e.g. a point-mass body).
    """
    J = inertia.toPseudoInertia().toMatrix()
    h = np.append(point, 1.0)
    # J may be singular (a point-mass body): then h must lie in its range (pseudo-inverse)
    J_pinv = np.linalg.pinv(J, rcond=1e-12, hermitian=True)
    in_range = np.linalg.norm(J @ (J_pinv @ h) - h) <= 1e-9 * max(1.0, float(np.linalg.norm(h)))
    limit = 1.0 / float(h @ J_pinv @ h) if in_range and inertia.mass > 0 else 0.0
    if mass > limit * (1 - 1e-12):
        raise InvalidInputError(
            f"add_compliant_feet: the body of joint {body!r} ({inertia.mass:.4g} kg) cannot give a "
            f"{mass:.4g} kg point mass at foot {foot!r}: at most {limit:.4g} kg leaves it physical; "
            "use a smaller foot_mass or mass_from='added'"
        )
    return inertia - pin.Inertia(mass, np.asarray(point, dtype=float), np.zeros((3, 3)))
