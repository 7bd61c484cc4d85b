"""Gait stability: the stride map, its Jacobian and the Floquet multipliers.

`stride` holds the stride map of a foot (the state just before one of its
touchdowns to the state just before the next, on the section of that foot's
guard, tangent space), the search for a periodic gait up to the ground's
neutral directions (x, y, yaw), the Floquet multipliers of a stride, and the
stroboscopic period map of a clock-driven scene.
"""
