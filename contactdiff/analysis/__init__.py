"""Analyses of scenes against the paper's assumptions, and of gaits.

The decoupling checker, measuring how far a scene is from orthogonal contacts
and limbs decoupled through the body (`decoupling`); the order gap, how much a
simultaneous touchdown depends on which foot lands first (`order_gap`); and
gait stability (`gait`).
"""
