"""Robots of the Coulomb friction tests (`coulomb_models`), loaded once per session."""

from __future__ import annotations

import pytest
from coulomb_models import BALL_URDF, BLOCK2_URDF, BLOCK3_URDF, load


@pytest.fixture(scope="session")
def block3(tmp_path_factory):
    """A point mass on prismatic x, y, z."""
    return load(tmp_path_factory, "block3", BLOCK3_URDF)


@pytest.fixture(scope="session")
def block2(tmp_path_factory):
    """A point mass on prismatic x, z (planar)."""
    return load(tmp_path_factory, "block2", BLOCK2_URDF)


@pytest.fixture(scope="session")
def ball(tmp_path_factory):
    """A free-flying solid sphere."""
    return load(tmp_path_factory, "ball", BALL_URDF, floating_base=True)
