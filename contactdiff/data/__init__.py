"""Data the package ships: measured cube tosses (`contactdiff.data.cube_tosses`)."""

from .cube_tosses import NOMINAL, CubeParameters, Toss, cube_scene, load_tosses

__all__ = ["CubeParameters", "NOMINAL", "Toss", "cube_scene", "load_tosses"]
