"""Controllers and the scenes they drive, for floating-base quadrupeds.

The legs of a quadruped found from its kinematic tree (`legs`), a clock-driven
trot controller applying PD torques around a periodic joint-space reference
with a scheduled feed-forward load (`trot_controller`), and trot scenes of the
example-robot-data quadrupeds on flat ground (`trot_scenes`).
"""
