"""The approximate solution's projected Gauss-Seidel sweeps (`SlipDirections.fixed_point`)
stopped early at a cycle in round-off: the same iterate as the sweeps run to their cap.

On a face landing flat (four corners, rows of rank 6, `test_face_impact.face_problem`)
the sweeps often fall into a cycle of period 2 or 3 in the last bits and never meet
their stop test; `fixed_point` then ends at the cycle, on the iterate of the cap's
phase. The reference below is the documented iteration, written out and run to its
cap without that shortcut. Both evaluate the same operations in the same order on the
same machine, so they agree bit for bit whatever the BLAS kernel: the comparison is
exact (tolerance 0), which is what the shortcut claims.
"""

from __future__ import annotations

import numpy as np
import pytest
from test_face_impact import face_problem

from contactdiff.dynamics.friction_slip import _FP_CREEP, _FP_CREEP_AFTER, _FP_SWEEPS, project_cone
from contactdiff.dynamics.frictional_impact import _Impact
from contactdiff.dynamics.lcp_problem import ContactRows

ROWS = ContactRows.from_sizes([3, 3, 3, 3])


def sweeps_to_the_cap(prob) -> np.ndarray:
    """Projected Gauss-Seidel as `fixed_point`'s doc states it (its stop tests: a relative
    change of 1e-14, or a creep below `_FP_CREEP` after `_FP_CREEP_AFTER` sweeps), with no
    cycle shortcut."""
    lam = np.zeros(prob.m)
    blocks = [np.asarray(b) for b in prob.rows.contact_rows]
    for done in range(1, _FP_SWEEPS + 1):
        old = lam.copy()
        for k, r in enumerate(blocks):
            mu = float(prob.mu[k])
            dg = float(prob.G[r[:, None], r].diagonal().max())
            w = prob.u[r] + prob.G[r] @ lam
            w[0] += prob.e[k] * prob.u[prob.normal[k]] + mu * np.linalg.norm(w[1:])
            lam[r] = project_cone(lam[r] - w / dg, mu)
        change, size = np.abs(lam - old).max(), np.abs(lam).max()
        if change <= 1e-14 * max(size, 1e-300) or (done >= _FP_CREEP_AFTER and change <= _FP_CREEP * size):
            break
    return lam


@pytest.mark.parametrize("seed", range(12))
def test_fixed_point_equals_the_sweeps_run_to_their_cap(seed):
    rng = np.random.default_rng(seed)
    twist = np.r_[rng.uniform(-1.0, 1.0, 2), -rng.uniform(0.5, 2.0), rng.uniform(-3.0, 3.0, 3)]
    G, u, _ = face_problem((0.0524, 0.0524, 0.0524), 0.37, rng.uniform(0, np.pi), twist)
    e = np.full(4, 0.125)
    prob = _Impact(0.5 * (G + G.T), u, ROWS, e, np.full(4, 0.18), 1e-10)
    lam, up = prob.fixed_point()
    ref = sweeps_to_the_cap(prob)
    assert np.array_equal(lam, ref)
    assert np.array_equal(up, prob.u + prob.G @ ref)
