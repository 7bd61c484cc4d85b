"""Frictional impacts of the measured cube (edge 0.1048 m, 0.37 kg, 8.1e-4 kg m²) taken
from simulated tosses where the solver's search once missed the law's solution.

Each problem is the impact's Delassus matrix ``G`` and pre-impact row velocities ``u-``
(rows: normal z, tangents x, y of each closed corner, world axes), as the simulator
formed them, to full precision. The tests check the law's conditions from ``G``, ``u-``
and the impulses alone (`impact_law.check_law`), never the solver's own residual; the
tolerances are those of `impact_law` (the solver accepts a scaled residual of 1e-9).
"""

from __future__ import annotations

import numpy as np
from impact_law import REL, approaching_e, check_law

from contactdiff.dynamics.frictional_impact import ContactState, solve_frictional_impact
from contactdiff.dynamics.lcp_problem import ContactRows

OPEN, STICK, SLIDE = ContactState.OPEN, ContactState.STICK, ContactState.SLIDE

# One corner landing alone at 0.62 m/s while slipping at 0.53 m/s (μ 0.5, e 0.3).
CORNER_G = np.array(
    [
        [8.351311035826853, 3.9737245323722123, 3.121883258488642],
        [3.9737245323722123, 9.379388403149205, -2.7440504708622466],
        [3.121883258488642, -2.7440504708622466, 10.716371632095006],
    ]
)
CORNER_U = np.array([-0.6236263199812911, -0.2402241322437491, 0.4730026599821071])


def test_a_corner_slip_root_found_twice_keeps_the_accurate_copy():
    """One spatial slider: its slip angle has one root on the circle, which the scan
    brackets twice (a sign change at the root, and a wrap jump of the angle form whose
    Newton run walks 2π over to the same root and stops after its few iterations short of
    round-off, ~1e-8 rad, so the law's check rejects it). The more accurate copy must
    then be tried: the solve returns the sliding corner, and every condition of the law
    holds.

    The sticking alternative is outside the cone here (its tangential impulse needs
    |Λ_T| / Λ_N = 0.81 > μ: ``G_ee z = -b`` over the three rows, derived below), so the
    corner must slide."""
    rows = ContactRows.from_sizes([3])
    mu, e = 0.5, 0.3
    b = CORNER_U * np.array([1.0 + e, 1.0, 1.0])  # (1 + e) u-_N, u-_T
    stick = np.linalg.solve(CORNER_G, -b)  # every row an equality: w_N = 0, u+_T = 0
    assert np.linalg.norm(stick[1:]) > mu * stick[0]
    out = solve_frictional_impact(CORNER_G, CORNER_U, rows, e, mu)
    assert out.states == (SLIDE,)
    check_law(out, CORNER_G, CORNER_U, rows, approaching_e(CORNER_U, rows, [e]), np.array([mu]))


# A face of the cube with one edge (corners 0, 1) landing at 11.9 mm/s and the opposite
# edge (corners 2, 3) resting (normal speed ~1e-17 m/s) while slipping at 5 and 0.9 mm/s
# (μ 0.5, e 0.3): twelve rows of rank 6.
FACE_G = np.array(
    [
        [
            9.482357023690358,
            1.1343799605022777,
            -4.657793303835428,
            2.702702702702708,
            1.1343799605022764,
            -4.6577933038354296,
            2.7027027027026973,
            1.1343799605022755,
            -4.657793303835426,
            -4.0769516182849515,
            1.134379960502274,
            -4.657793303835428,
        ],
        [
            1.1343799605022777,
            12.492572530296293,
            1.5586952177416868,
            -4.657793303835424,
            7.6512250809382145,
            -6.400042667099765,
            4.657793303835422,
            4.533834645454842,
            6.400042667099764,
            -1.134379960502279,
            -0.3075128039032358,
            -1.5586952177416882,
        ],
        [
            -4.657793303835428,
            1.5586952177416868,
            6.47214151708442,
            -1.1343799605022817,
            0.37961165388789064,
            4.533834645454845,
            1.1343799605022804,
            -0.37961165388788887,
            7.651225080938216,
            4.657793303835426,
            -1.5586952177416848,
            5.71291820930864,
        ],
        [
            2.702702702702708,
            -4.657793303835424,
            -1.1343799605022817,
            9.482357023690358,
            -4.657793303835424,
            -1.1343799605022826,
            -4.07695161828495,
            -4.657793303835424,
            -1.1343799605022817,
            2.7027027027026995,
            -4.657793303835425,
            -1.1343799605022822,
        ],
        [
            1.1343799605022764,
            7.6512250809382145,
            0.37961165388789064,
            -4.657793303835424,
            6.472141517084418,
            -1.558695217741687,
            4.6577933038354224,
            5.712918209308637,
            1.558695217741688,
            -1.1343799605022777,
            4.53383464545484,
            -0.3796116538878901,
        ],
        [
            -4.6577933038354296,
            -6.400042667099765,
            4.533834645454845,
            -1.1343799605022826,
            -1.558695217741687,
            12.492572530296298,
            1.1343799605022815,
            1.5586952177416875,
            -0.307512803903233,
            4.657793303835428,
            6.400042667099766,
            7.651225080938221,
        ],
        [
            2.7027027027026973,
            4.657793303835422,
            1.1343799605022804,
            -4.07695161828495,
            4.6577933038354224,
            1.1343799605022815,
            9.482357023690351,
            4.6577933038354224,
            1.1343799605022804,
            2.7027027027027053,
            4.6577933038354224,
            1.1343799605022808,
        ],
        [
            1.1343799605022755,
            4.533834645454842,
            -0.37961165388788887,
            -4.657793303835424,
            5.712918209308637,
            1.5586952177416875,
            4.6577933038354224,
            6.4721415170844185,
            -1.558695217741685,
            -1.1343799605022769,
            7.651225080938214,
            0.3796116538878913,
        ],
        [
            -4.657793303835426,
            6.400042667099764,
            7.651225080938216,
            -1.1343799605022817,
            1.558695217741688,
            -0.307512803903233,
            1.1343799605022804,
            -1.558695217741685,
            12.492572530296293,
            4.657793303835426,
            -6.400042667099761,
            4.533834645454842,
        ],
        [
            -4.0769516182849515,
            -1.134379960502279,
            4.657793303835426,
            2.7027027027026995,
            -1.1343799605022777,
            4.657793303835428,
            2.7027027027027053,
            -1.1343799605022769,
            4.657793303835426,
            9.482357023690357,
            -1.1343799605022755,
            4.657793303835428,
        ],
        [
            1.134379960502274,
            -0.3075128039032358,
            -1.5586952177416848,
            -4.657793303835425,
            4.53383464545484,
            6.400042667099766,
            4.6577933038354224,
            7.651225080938214,
            -6.400042667099761,
            -1.1343799605022755,
            12.49257253029629,
            1.5586952177416897,
        ],
        [
            -4.657793303835428,
            -1.5586952177416882,
            5.71291820930864,
            -1.1343799605022822,
            -0.3796116538878901,
            7.651225080938221,
            1.1343799605022808,
            0.3796116538878913,
            4.533834645454842,
            4.657793303835428,
            1.5586952177416897,
            6.472141517084423,
        ],
    ]
)
FACE_U = np.array(
    [
        -0.011863952278928806,
        0.006232915423651712,
        0.0021629991778869674,
        -0.011863952278928818,
        0.004049613356219147,
        -0.0014261522019488647,
        -3.539435330218337e-18,
        0.0026437640438158804,
        0.004346301245319533,
        -1.3751468107396463e-17,
        0.0004604619763833146,
        0.000757149865483701,
    ]
)


def test_an_edge_landing_beside_a_resting_edge_resolves():
    """The landing edge's two corners would both stick, but the compatible split of their
    impulses (`contactdiff.dynamics.redundant`) leaves one corner's cone, so that corner
    slides with its impulse on the cone's edge and a slip that vanishes: a root of the
    cross form ``s × u+_T`` only, located to the accuracy of the angle (its slip is then
    ~1e-14 m/s, above 1e-14 of the velocity scale: such a root was discarded as not a
    zero of the slip). The solve must find it, and the law holds; the landing edge cannot
    slip after the impact (``check_law``'s sticking condition, or a sliding one with
    ``u+_T`` along ``s`` and of the size of round-off, both to ``REL`` of the velocity scale)."""
    rows = ContactRows.from_sizes([3, 3, 3, 3])
    mu, e = 0.5, 0.3
    out = solve_frictional_impact(FACE_G, FACE_U, rows, e, mu)
    check_law(out, FACE_G, FACE_U, rows, approaching_e(FACE_U, rows, [e] * 4), np.full(4, mu))
    lam = out.impulses
    vscale = np.abs(FACE_U).max() + np.abs(FACE_G).max() * np.abs(lam).max()
    assert out.states[0] is not OPEN and out.states[1] is not OPEN  # the landing edge bounces
    np.testing.assert_allclose(out.u_plus[[1, 2, 4, 5]], 0.0, atol=REL * vscale)
