"""The inertia of an MJCF mesh geom, computed as MuJoCo computes it, for bodies weighed by meshes.

A Menagerie body without ``<inertial>`` takes its mass and inertia from its geoms;
Pinocchio 4.1 does not integrate mesh geoms (it gives each one 1 kg). When the mesh
file is there, `equivalent_box` replaces such a geom by the box MuJoCo itself
weighs it as: MuJoCo reduces every mesh to its volume, centre of mass and
principal moments, and a geom's inertia is that of the box with the same mass and
moments, centred at the centre of mass and aligned with the principal axes.

MuJoCo's computation (``mjCMesh::Process``, ``inertia="legacy"``, its default, and
``"exact"``), repeated here:

1. vertices read as 32-bit floats (binary STL; OBJ ``v`` lines), in double from then on;
   ``v ← R(refquat)ᵀ (v − refpos)``, then scaled by ``scale`` per axis (a negative
   product of scales reverses each face's order);
2. ``c₀``: the faces' centroid weighted by area;
3. each face spans a pyramid with apex ``c₀``: volume ``(centre − c₀)·n area / 3`` (its
   absolute value for ``legacy``); the centre of mass ``c`` is the volume-weighted mean of
   the pyramids' centroids ``¾ centre + ¼ c₀``;
4. about ``c``, each face spans a tetrahedron with apex ``c``: volume
   ``V_f = centre·n area / 3`` (absolute for ``legacy``), ``V = Σ V_f``, and second moments
   ``P_ab = Σ V_f / 20 (2 Σ_i x_ia x_ib + Σ_{i≠j} x_ia x_jb)`` over its vertices ``x_i``;
   per unit density ``I = [[P_yy+P_zz, −P_xy, −P_xz], ...]``;
5. the geom's mass is its ``mass``, else ``density`` (default 1000 kg/m³) times ``V``, and
   its inertia ``mass · eig(I) / V`` about the principal axes.

``inertia="convex"`` (the convex hull) and ``"shell"`` are refused, and so are mesh
files other than binary STL and OBJ, and meshes given by vertices in the XML.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from xml.etree.ElementTree import Element

import numpy as np
import pinocchio as pin

from ..errors import ModelLoadError, UnsupportedModelError
from .mjcf_xml import numbers

MAX_STL_FACES = 200_000
"""MuJoCo's own limit on the faces of an STL file (a larger file is refused before it is read)."""

MAX_MESH_BYTES = 50_000_000
"""bytes: the largest mesh file read (an OBJ of MuJoCo's 200,000-face limit is ~15 MB)."""


@dataclass(frozen=True)
class MeshInertia:
    """A mesh's volume inertia per unit density, in its (transformed) mesh frame.

    Attributes:
        volume: m³.
        com: centre of mass (m), mesh frame.
        moments: principal moments per unit density (m⁵), ``moments[i]`` about ``axes[:, i]``.
        axes: rotation whose columns are the principal axes (mesh frame), ``det = +1``.
    """

    volume: float
    com: np.ndarray
    moments: np.ndarray
    axes: np.ndarray


def read_stl(path: Path) -> tuple[np.ndarray, np.ndarray]:
    """Vertices (``n × 3``, float32 values in float64) and faces (``m × 3``) of a binary STL file.

    Raises:
        ModelLoadError: not a binary STL file (MuJoCo reads no ASCII STL), or too many faces.
    """
    data = _read_bytes(path)
    count = int(np.frombuffer(data[80:84], dtype="<u4")[0]) if len(data) >= 84 else -1
    if not 1 <= count <= MAX_STL_FACES or len(data) != 84 + 50 * count:
        raise ModelLoadError(
            f"mesh file {str(path)!r} is not a binary STL file with 1 to {MAX_STL_FACES} "
            "faces (MuJoCo reads binary STL only)"
        )
    records = np.frombuffer(
        data, dtype=np.dtype([("normal", "<f4", 3), ("v", "<f4", (3, 3)), ("attr", "<u2")]), count=count, offset=84
    )
    return records["v"].reshape(-1, 3).astype(float), np.arange(3 * count).reshape(-1, 3)


def read_obj(path: Path) -> tuple[np.ndarray, np.ndarray]:
    """Vertices and faces of an OBJ file (``v`` and ``f`` lines; polygons split into fans).

    Raises:
        ModelLoadError: a malformed ``v`` or ``f`` line, or a face naming a missing vertex.
    """
    vertices, faces = [], []
    for number, line in enumerate(_read_bytes(path).decode("utf-8", "replace").splitlines(), 1):
        parts = line.split()
        try:
            if parts[:1] == ["v"]:
                vertices.append([float(x) for x in parts[1:4]])
            elif parts[:1] == ["f"]:
                ids = [int(p.split("/")[0]) for p in parts[1:]]
                ids = [i - 1 if i > 0 else len(vertices) + i for i in ids]
                faces += [[ids[0], ids[k], ids[k + 1]] for k in range(1, len(ids) - 1)]
        except ValueError:
            raise ModelLoadError(f"mesh file {str(path)!r} line {number} is malformed: {line.strip()[:80]!r}") from None
    faces_array = np.array(faces, dtype=int).reshape(-1, 3)
    if len(vertices) < 4 or not len(faces) or faces_array.min() < 0 or faces_array.max() >= len(vertices):
        raise ModelLoadError(
            f"mesh file {str(path)!r} has {len(vertices)} vertices and {len(faces)} faces, "
            "or a face names a vertex it does not have"
        )
    return np.array(vertices, dtype=np.float32).astype(float), faces_array


def _read_bytes(path: Path) -> bytes:
    size = path.stat().st_size
    if size > MAX_MESH_BYTES:
        raise ModelLoadError(f"mesh file {str(path)!r} has {size} bytes, more than the {MAX_MESH_BYTES} read")
    return path.read_bytes()


def mesh_inertia(mesh: Element, path: Path) -> MeshInertia:
    """The inertia of the ``<mesh>`` element ``mesh`` read from ``path`` (module notes).

    Raises:
        UnsupportedModelError: an ``inertia`` mode other than ``legacy``/``exact``, or a
            file type other than STL and OBJ.
        ModelLoadError: an unreadable file, or a mesh without volume.
    """
    mode = mesh.get("inertia", "legacy")
    if mode not in ("legacy", "exact"):
        raise UnsupportedModelError(
            f"<mesh> {path.name!r} has inertia={mode!r}; the mesh inertias computed here "
            "are 'legacy' and 'exact': give the body an <inertial>"
        )
    kind = path.suffix.lower()
    if kind not in (".stl", ".obj"):
        raise UnsupportedModelError(
            f"<mesh> file {path.name!r}: the mesh files read here are .stl and .obj; give the body an <inertial>"
        )
    vertices, faces = read_stl(path) if kind == ".stl" else read_obj(path)
    vertices = _transformed(vertices, mesh)
    scale = numbers(mesh.get("scale"), (1.0, 1.0, 1.0))
    if np.prod(scale) < 0:
        faces = faces[:, [0, 2, 1]]
    return _inertia(vertices[faces], mode == "legacy", path)


def _transformed(vertices: np.ndarray, mesh: Element) -> np.ndarray:
    """``R(refquat)ᵀ (v − refpos)``, scaled (MuJoCo's ``ApplyTransformations``)."""
    refpos = np.array(numbers(mesh.get("refpos"), (0.0, 0.0, 0.0)))
    quat = np.array(numbers(mesh.get("refquat"), (1.0, 0.0, 0.0, 0.0)))
    R = _matrix(quat / np.linalg.norm(quat))
    return ((vertices - refpos) @ R) * np.array(numbers(mesh.get("scale"), (1.0, 1.0, 1.0)))


def _inertia(triangles: np.ndarray, legacy: bool, path: Path) -> MeshInertia:
    """Steps 2-4 of the module notes on ``triangles`` (``m × 3 × 3``: face, vertex, axis)."""
    cross = np.cross(triangles[:, 1] - triangles[:, 0], triangles[:, 2] - triangles[:, 0])
    double_area = np.linalg.norm(cross, axis=1)
    area = double_area / 2
    normal = np.divide(cross, double_area[:, None], out=np.zeros_like(cross), where=double_area[:, None] > 0)
    centre = triangles.mean(axis=1)
    if area.sum() < 1e-15:  # MuJoCo's mjMINVAL
        raise ModelLoadError(f"mesh file {str(path)!r} has no surface area")
    apex = (area[:, None] * centre).sum(axis=0) / area.sum()
    pyramids = np.einsum("ij,ij->i", centre - apex, normal) * area / 3
    pyramids = np.abs(pyramids) if legacy else pyramids
    if pyramids.sum() < 1e-15:
        raise ModelLoadError(
            f"mesh file {str(path)!r} has no volume ({pyramids.sum():.3g} m³; misoriented faces make it negative)"
        )
    com = (pyramids[:, None] * (0.75 * centre + 0.25 * apex)).sum(axis=0) / pyramids.sum()
    x = triangles - com
    volumes = np.einsum("ij,ij->i", centre - com, normal) * area / 3
    volumes = np.abs(volumes) if legacy else volumes
    s = x.sum(axis=1)  # 2 Σ x_a x_b + Σ_{i≠j} x_ia x_jb = Σ x_a x_b + (Σ x_a)(Σ x_b)
    P = np.einsum("f,fia,fib->ab", volumes, x, x) + np.einsum("f,fa,fb->ab", volumes, s, s)
    P /= 20
    inertia = np.trace(P) * np.eye(3) - P
    moments, axes = np.linalg.eigh(inertia)
    if np.linalg.det(axes) < 0:
        axes[:, 2] = -axes[:, 2]
    return MeshInertia(float(volumes.sum()), com, moments, axes)


def equivalent_box(geom: Element, inertia: MeshInertia) -> dict[str, str]:
    """The attributes of the box geom that weighs as MuJoCo weighs the mesh geom ``geom``
    (its ``pos``/``quat`` in the body, with no orientation but ``quat``): ``type``, ``size``
    (half sizes, m), ``pos``, ``quat`` (``w x y z``) and ``mass`` (kg).

    A box of mass ``m`` and half sizes ``s`` has moments ``m (s_j² + s_k²) / 3``; with
    ``s_i² = 3 (e_j + e_k − e_i) / (2 V)`` (``e`` the moments per unit density) they are
    ``m e_i / V``, MuJoCo's (its ``boxsz``).
    """
    e, volume = inertia.moments, inertia.volume
    mass = numbers(geom.get("mass"), (-1.0,))[0]
    if mass < 0:
        mass = numbers(geom.get("density"), (1000.0,))[0] * volume
    half = np.sqrt(np.maximum(3 * (e.sum() - 2 * e) / (2 * volume), 0.0))
    pos = np.array(numbers(geom.get("pos"), (0.0, 0.0, 0.0)))
    quat = np.array(numbers(geom.get("quat"), (1.0, 0.0, 0.0, 0.0)))
    quat = quat / np.linalg.norm(quat)
    R_geom = _matrix(quat)
    centre = pos + R_geom @ inertia.com
    frame = R_geom @ inertia.axes
    return {
        "type": "box",
        "size": _text(half),
        "pos": _text(centre),
        "quat": _text(_quaternion(frame)),
        "mass": repr(float(mass)),
    }


def _matrix(q: np.ndarray) -> np.ndarray:
    """The rotation of a unit quaternion ``(w, x, y, z)``."""
    return pin.Quaternion(*(float(c) for c in q)).toRotationMatrix()


def _quaternion(R: np.ndarray) -> np.ndarray:
    """``(w, x, y, z)`` of a rotation matrix."""
    x, y, z, w = pin.Quaternion(R).coeffs()
    return np.array([w, x, y, z])


def _text(values: np.ndarray) -> str:
    return " ".join(repr(float(x)) for x in values)
