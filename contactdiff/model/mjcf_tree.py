"""Rewrites of an MJCF body tree into the forms Pinocchio 4.1's parser reads as MuJoCo does.

Each rewrite leaves MuJoCo's reading of the model unchanged (tested against
MuJoCo itself in ``tests/model/test_mjcf_mujoco.py``):

* `orientations_as_quaternions`: ``axisangle``, ``euler`` (with the compiler's
  ``eulerseq`` and ``angle``), ``xyaxes`` and ``zaxis`` of bodies, inertials,
  geoms and sites become ``quat`` (Pinocchio mis-reads ``axisangle``);
* `flatten_frames`: a ``<frame>`` (MuJoCo 3's grouping of children under one
  placement) is replaced by its children, its placement composed into theirs
  (Pinocchio skips what a frame holds);
* `split_joints`: a body with several joints becomes a chain of bodies with one
  joint each, all at the body's placement, the body itself (inertia, geoms,
  children) at the end (Pinocchio merges them into one joint of another name).

Quaternions are MuJoCo's ``(w, x, y, z)``.
"""

from __future__ import annotations

from xml.etree.ElementTree import Element

import numpy as np

from .mjcf_xml import compiler_option, numbers

_ORIENTATION = ("quat", "axisangle", "euler", "xyaxes", "zaxis")
_ORIENTED = ("body", "inertial", "geom", "site", "frame")


def quat_multiply(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Hamilton product ``a b`` of ``(w, x, y, z)`` quaternions."""
    w1, v1, w2, v2 = a[0], a[1:], b[0], b[1:]
    return np.concatenate([[w1 * w2 - v1 @ v2], w1 * v2 + w2 * v1 + np.cross(v1, v2)])


def quat_rotate(q: np.ndarray, x: np.ndarray) -> np.ndarray:
    """``R(q) x`` for a unit quaternion ``q``."""
    return quat_multiply(quat_multiply(q, np.concatenate([[0.0], x])), q * [1, -1, -1, -1])[1:]


def _axis_angle(axis: np.ndarray, angle: float) -> np.ndarray:
    axis = np.asarray(axis, dtype=float)
    return np.concatenate([[np.cos(angle / 2)], np.sin(angle / 2) * axis / np.linalg.norm(axis)])


def _matrix_quat(R: np.ndarray) -> np.ndarray:
    """Unit quaternion of a rotation matrix (Shepperd's method: the largest of four divisors)."""
    t = np.trace(R)
    candidates = [t, R[0, 0], R[1, 1], R[2, 2]]
    k = int(np.argmax(candidates))
    if k == 0:
        s = 2 * np.sqrt(1 + t)
        q = np.array([s / 4, (R[2, 1] - R[1, 2]) / s, (R[0, 2] - R[2, 0]) / s, (R[1, 0] - R[0, 1]) / s])
    else:
        i, j, m = k - 1, k % 3, (k + 1) % 3
        s = 2 * np.sqrt(1 + R[i, i] - R[j, j] - R[m, m])
        q = np.zeros(4)
        q[0] = (R[m, j] - R[j, m]) / s
        q[1 + i] = s / 4
        q[1 + j] = (R[j, i] + R[i, j]) / s
        q[1 + m] = (R[m, i] + R[i, m]) / s
    q = np.asarray(q, dtype=float)
    return q / np.linalg.norm(q)


def orientation(element: Element, degrees: bool, sequence: str) -> np.ndarray | None:
    """The element's orientation as a unit quaternion (MuJoCo's reading of ``quat``,
    ``axisangle``, ``euler``, ``xyaxes`` or ``zaxis``), None when it gives none."""
    unit = np.pi / 180 if degrees else 1.0
    if element.get("quat") is not None:
        q = np.array(numbers(element.get("quat")), dtype=float)
        return q / np.linalg.norm(q)
    if element.get("axisangle") is not None:
        x = numbers(element.get("axisangle"))
        return _axis_angle(np.array(x[:3]), x[3] * unit)
    if element.get("euler") is not None:
        q = np.array([1.0, 0.0, 0.0, 0.0])
        for letter, angle in zip(sequence, numbers(element.get("euler"))):
            step = _axis_angle(np.eye(3)["xyz".index(letter.lower())], angle * unit)
            q = quat_multiply(q, step) if letter.islower() else quat_multiply(step, q)
        return q
    if element.get("xyaxes") is not None:
        v = np.array(numbers(element.get("xyaxes")), dtype=float)
        x = v[:3] / np.linalg.norm(v[:3])
        y = v[3:] - x * (x @ v[3:])
        y /= np.linalg.norm(y)
        return _matrix_quat(np.column_stack([x, y, np.cross(x, y)]))
    if element.get("zaxis") is not None:
        z = np.array(numbers(element.get("zaxis")), dtype=float)
        z /= np.linalg.norm(z)
        axis = np.cross([0.0, 0.0, 1.0], z)
        if np.linalg.norm(axis) < 1e-14:  # along ±z: identity, or a half turn about x
            return np.array([1.0, 0.0, 0.0, 0.0]) if z[2] > 0 else np.array([0.0, 1.0, 0.0, 0.0])
        return _axis_angle(axis, np.arctan2(np.linalg.norm(axis), z[2]))
    return None


def _text(values) -> str:
    return " ".join(repr(float(x)) for x in values)


def _set_quat(element: Element, q: np.ndarray) -> None:
    for key in _ORIENTATION:
        element.attrib.pop(key, None)
    element.set("quat", _text(q))


def orientations_as_quaternions(root: Element) -> int:
    """Write every orientation of the body tree as ``quat``; returns how many were rewritten."""
    degrees = compiler_option(root, "angle", "degree") == "degree"
    sequence = compiler_option(root, "eulerseq", "xyz")
    count = 0
    for world in root.findall("worldbody"):
        for element in world.iter():
            if element.tag not in _ORIENTED or element.get("quat") is not None:
                continue
            q = orientation(element, degrees, sequence)
            if q is not None:
                _set_quat(element, q)
                count += 1
    return count


def _placement(element: Element) -> tuple[np.ndarray, np.ndarray]:
    pos = np.array(numbers(element.get("pos"), (0.0, 0.0, 0.0)), dtype=float)
    q = numbers(element.get("quat"), (1.0, 0.0, 0.0, 0.0))
    return pos, np.array(q, dtype=float) / np.linalg.norm(q)


def flatten_frames(root: Element) -> int:
    """Replace each ``<frame>`` by its children, its placement composed into theirs
    (run after `orientations_as_quaternions`); returns how many frames were removed."""
    count = 0
    for parent in [e for e in root.iter() if any(c.tag == "frame" for c in e)]:
        children = []
        for child in list(parent):
            if child.tag != "frame":
                children.append(child)
                continue
            count += flatten_frames(child)  # nested frames first: their children are in place
            pos, q = _placement(child)
            for grandchild in list(child):
                _compose(grandchild, pos, q)  # classes are already inline (a frame's childclass too)
                children.append(grandchild)
            count += 1
        parent[:] = children
    return count


def _compose(element: Element, pos: np.ndarray, q: np.ndarray) -> None:
    """Give ``element`` (placed in a frame at ``pos``, ``q``) its placement in the frame's parent."""
    if element.get("fromto") is not None:
        ends = np.array(numbers(element.get("fromto")), dtype=float).reshape(2, 3)
        element.set("fromto", _text(np.concatenate([pos + quat_rotate(q, e) for e in ends])))
        return
    own_pos, own_q = _placement(element)
    element.set("pos", _text(pos + quat_rotate(q, own_pos)))
    element.set("quat", _text(quat_multiply(q, own_q)))


def split_joints(root: Element, taken: set[str]) -> list[str]:
    """Give each body with several hinge, slide or ball joints a chain of bodies with one
    joint each (see the module notes); returns the bodies split. ``taken``: names in use."""
    split = []
    for world in root.findall("worldbody"):
        for body in list(world.iter("body")):
            joints = [e for e in body if e.tag == "joint" and e.get("type", "hinge") != "free"]
            if len(joints) < 2:
                continue
            outer = Element("body", {k: v for k, v in body.attrib.items() if k in ("pos", "quat", "name")})
            for key in ("pos", "quat"):
                body.attrib.pop(key, None)
            name = body.get("name", "body")
            holder, current = None, outer
            for k, joint in enumerate(joints[:-1]):
                current.set("name", _unique(f"{name}_{joint.get('name') or k}", taken))
                current.append(joint)
                body.remove(joint)
                if holder is not None:
                    holder.append(current)
                holder, current = current, Element("body")
            parent = _parent(world, body)
            index = list(parent).index(body)
            parent.remove(body)
            assert holder is not None  # the loop ran (two joints or more)
            holder.append(body)
            parent.insert(index, outer)
            split.append(name)
    return split


def _unique(name: str, taken: set[str]) -> str:
    while name in taken:
        name += "_"
    taken.add(name)
    return name


def _parent(world: Element, element: Element) -> Element:
    for candidate in world.iter():
        if element in list(candidate):
            return candidate
    raise ValueError("element not in the tree")
