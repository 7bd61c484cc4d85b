"""The board's height from samples at rest: a closed-form stage before a fit.

A body at rest on a flat floor touches it with its lowest contact points (a
cube's four corners of a face). Over the resting samples of the recordings, the
floor height ``b`` that best puts those points on the floor minimises

    Σ_k Σ_{c ∈ S_k} (h_c(q_k) − b)²,    h_c(q) = n_c · p_c(q) − r_c,

(``p_c`` the contact point in the world frame, ``n_c`` its contact's normal,
``r_c`` its radius: the height of its lowest point along the normal; ``S_k`` the
supporting points of sample ``k``, those within ``support`` of the lowest): a
linear least-squares problem whose solution is the mean of the supporting
heights. Taking every supporting point, not only the lowest, cancels the
first-order effect of orientation noise on a flat face (its corners go up and
down in pairs), where the lowest point alone is biased down by it.

Fitting the floor height with windows through impacts finds where the impacts
want it, which a rigid model with one floor cannot share with the rest of a
trajectory (docs/results/cube-fit.md); fixing it here from the rest and holding
it in the fit keeps the resting part of every rollout on the data's board.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ..errors import InvalidInputError, check_count
from ..model.kinematics import Kinematics
from .recordings import Recording

REST_SAMPLES = 20
"""Samples at each recording's end taken to be at rest by default (0.14 s at the cube data's 148 Hz)."""

REST_SUPPORT = 0.003
"""m: contact points within this of a sample's lowest one support it (three times the cube data's
~1 mm noise; a cube's face corners are within ~1 mm of each other at rest, its other corners a
whole edge higher)."""


@dataclass(frozen=True)
class RestHeight:
    """The floor height fitted on resting samples (`rest_height`).

    Attributes:
        offset: the floor's height along the contacts' normal (m): the contacts' ``offset``
            that puts the supporting points on it in the least-squares sense.
        standard_error: the standard error (m) of the recordings' means, ``std / sqrt(recordings)``
            (each recording an independent measurement: its samples share its noise and its
            resting face); with one recording, of its points, ``std / sqrt(points)``.
        points: supporting contact points used (over all samples and recordings).
        per_recording: each recording's own mean supporting height (m), by name.
    """

    offset: float
    standard_error: float
    points: int
    per_recording: dict[str, float]


def rest_height(
    scene,
    recordings: Sequence[Recording],
    *,
    group: str | None = None,
    samples: int = REST_SAMPLES,
    support: float = REST_SUPPORT,
) -> RestHeight:
    """The floor height (contact offset) that puts the resting body's supporting contact
    points on the floor, least squares over the last ``samples`` samples of every recording
    (module doc). The recordings must end at rest; the scene's own offsets do not matter.

    Args:
        scene: the `Scene` whose contacts touch the floor (ground contacts: ``against`` None).
        recordings: `Recording` s of that scene that end at rest.
        group: only the contacts of this group (``Contact.group``); None: every ground contact.
        samples: samples at each recording's end taken to be at rest (>= 1).
        support: m, >= 0: points within this of a sample's lowest point support it.

    Returns:
        The `RestHeight`.

    Raises:
        InvalidInputError: no recording, a recording shorter than ``samples``, a bad ``samples``
            or ``support``, or no ground contact (of ``group``).
    """
    recordings = list(recordings)
    if not recordings or not all(isinstance(r, Recording) for r in recordings):
        raise InvalidInputError("rest_height: recordings must be a non-empty list of contactdiff.fit.Recording")
    samples = check_count("rest_height", "samples", samples, minimum=1)
    if not (isinstance(support, (int, float)) and math.isfinite(support) and support >= 0.0):
        raise InvalidInputError(f"rest_height: support must be a length >= 0 (m), got {support!r}")
    contacts = [c for c in scene.contacts if c.against_fid is None and (group is None or c.spec.group == group)]
    if not contacts:
        groups = sorted({c.spec.group for c in scene.contacts if c.spec.group is not None})
        raise InvalidInputError(
            f"rest_height: no ground contact in group {group!r}; groups of the scene: {', '.join(groups) or 'none'}"
        )
    kin = Kinematics(scene.model)
    zero = np.zeros(scene.model.nv)
    heights, per_recording = [], {}
    for rec in recordings:
        if len(rec.t) < samples:
            raise InvalidInputError(
                f"rest_height: recording {rec.name!r} has {len(rec.t)} samples, fewer than the {samples} asked for"
            )
        own = []
        for q in rec.q[-samples:]:
            kin.update(q, zero)
            h = np.array([c.gap(kin) + c.offset for c in contacts])  # n·p − r: the gap at offset 0
            own.append(h[h <= h.min() + support])
        own_points = np.concatenate(own)
        per_recording[rec.name] = float(own_points.mean())
        heights.append(own_points)
    points = np.concatenate(heights)
    spread = np.array(list(per_recording.values())) if len(recordings) > 1 else points
    error = float(spread.std(ddof=1)) / math.sqrt(len(spread)) if len(spread) > 1 else 0.0
    return RestHeight(float(points.mean()), error, len(points), per_recording)


__all__ = ["REST_SAMPLES", "REST_SUPPORT", "RestHeight", "rest_height"]
