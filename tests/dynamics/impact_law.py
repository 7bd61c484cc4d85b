"""The conditions of the frictional impact law (`contactdiff.dynamics.frictional_impact`)
checked from ``G``, ``u-`` and the returned impulses alone, never the solver's own
residual: shared by the tests of the solver and of measured impacts.

Tolerance: the solver accepts a scaled residual of 1e-9, so checks use ``REL = 1e-8``
relative to each case's impulse and velocity scales.
"""

from __future__ import annotations

import numpy as np

from contactdiff.dynamics.frictional_impact import ContactState, FrictionalImpact

OPEN, STICK = ContactState.OPEN, ContactState.STICK
REL = 1e-8


def check_law(out: FrictionalImpact, G, u, rows, e, mu):
    """Every condition of the law, from G, u- and the impulses only."""
    lam = out.impulses
    up = u + G @ lam
    xs = max(np.abs(lam).max(), 1e-300)
    b = u.copy()
    b[list(rows.normal)] = (1 + e) * u[list(rows.normal)]
    vs = np.abs(b).max() + np.abs(G).max() * np.abs(lam).max()
    np.testing.assert_allclose(out.u_plus, up, atol=1e-12 * vs)
    for k, (n, t) in enumerate(zip(rows.normal, rows.tangential)):
        t = list(t)
        lam_n, lam_t, ut = lam[n], lam[t], up[t]
        w_n = up[n] + e[k] * u[n]
        assert lam_n >= 0.0, f"contact {k} pulls: {lam_n}"  # never pulls (clipped exactly)
        assert w_n >= -REL * vs, f"contact {k} penetrates: w_n = {w_n}"
        assert abs(lam_n * w_n) <= REL * xs * vs  # complementarity
        if out.states[k] is OPEN:
            assert np.all(lam[[n, *t]] == 0.0)
            continue
        assert abs(w_n) <= REL * vs
        if not t:
            continue
        assert np.linalg.norm(lam_t) <= mu[k] * lam_n * (1 + 1e-12) + 1e-300  # in the cone
        if out.states[k] is STICK:
            assert np.abs(ut).max() <= REL * vs
        elif mu[k] > 0:
            s = out.slide_directions[k]
            assert abs(np.linalg.norm(s) - 1) < 1e-12
            np.testing.assert_allclose(lam_t, -mu[k] * lam_n * s, atol=1e-12 * xs)
            # the slide direction is the post-impact slip's (opposite the friction impulse)
            np.testing.assert_allclose(ut, np.linalg.norm(ut) * s, atol=REL * vs)


def approaching_e(u, rows, e):
    e = np.array(e, dtype=float)
    return np.where(u[list(rows.normal)] < 0, e, 0.0)
