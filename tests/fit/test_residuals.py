"""The manifold residual of a configuration: its values by hand, its derivative by finite differences."""

import numpy as np
import pinocchio as pin
import pytest

import contactdiff as cd
from contactdiff.errors import InvalidInputError
from contactdiff.fit.residuals import PoseResidual, ResidualWeights


def _random(model, rng):
    # unbounded coordinates (a free body's position: +-1.8e308) drawn in [-1, 1]
    lower = np.where(np.abs(model.lowerPositionLimit) < 10.0, model.lowerPositionLimit, -1.0)
    upper = np.where(np.abs(model.upperPositionLimit) < 10.0, model.upperPositionLimit, 1.0)
    q = lower + rng.random(model.nq) * (upper - lower)
    return pin.normalize(model, q)


@pytest.mark.parametrize("source", ["cube", "solo12"])
def test_residual_derivative_matches_central_differences(source):
    """Central differences along local steps q ⊕ hδ. The residual is smooth with second
    derivatives of order 1 (rad, m), so the FD error is ~h² = 1e-12 plus round-off
    eps/h ~ 1e-10: assert 1e-7."""
    scene = cd.cube_scene() if source == "cube" else cd.load_source(source)
    model = scene.model
    rng = np.random.default_rng(3)
    residual = PoseResidual(model, ResidualWeights(position=2.0, orientation=0.5, joint=3.0))
    for _ in range(3):
        q_sim, q_data = _random(model, rng), _random(model, rng)
        J = residual.jacobian(q_sim, q_data)
        h = 1e-6
        fd = np.column_stack(
            [
                (
                    residual.residual(pin.integrate(model, q_sim, h * e), q_data)
                    - residual.residual(pin.integrate(model, q_sim, -h * e), q_data)
                )
                / (2 * h)
                for e in np.eye(model.nv)
            ]
        )
        assert np.max(np.abs(J - fd)) < 1e-7


def test_free_body_rows_by_hand():
    """A cube displaced by (0.01, -0.02, 0.03) m and turned by 0.2 rad about its own x:
    position rows 2 x (0.01, -0.02, 0.03) (weight 2/m); orientation rows 0.5 x (0.2, 0, 0)."""
    model = cd.cube_scene().model
    q_data = np.array([0.1, 0.2, 0.05, 0.0, 0.0, 0.0, 1.0])
    turn = pin.Quaternion(pin.exp3(np.array([0.2, 0.0, 0.0])))
    q_sim = np.r_[q_data[:3] + [0.01, -0.02, 0.03], turn.coeffs()]
    r = PoseResidual(model, ResidualWeights(position=2.0, orientation=0.5)).residual(q_sim, q_data)
    assert r == pytest.approx([0.02, -0.04, 0.06, 0.1, 0.0, 0.0], abs=1e-15)


def test_bad_weights_are_named():
    with pytest.raises(InvalidInputError, match="orientation"):
        ResidualWeights(orientation=-1.0)
