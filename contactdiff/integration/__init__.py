"""Event-driven integration: the hybrid loop, its steppers and what it returns.

The hybrid loop that flows in a contact mode, locates the earliest event and
resets (`hybrid`, with its options in `options`); error-controlled steppers
with dense output (explicit Runge–Kutta pairs in `explicit_rk` and `tableaus`,
Radau IIA in `radau`, the base class in `stepper`, the factory in `steppers`)
over vector spaces or Pinocchio's Lie groups (`lie`); the choice of stepper for
``method="auto"`` (`method_choice`); guards, event location and grouping
(`guards`, `events`, `dense`); the vector field of a mode (`mode_field`);
projection onto a mode's constraint manifold (`projection`); saltation matrices
(`sensitivity`); and the resulting `Trajectory` (`trajectory`).
"""
