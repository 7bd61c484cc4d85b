"""Event-driven integration: the hybrid loop, its events, resets, saltation and results.

The hybrid loop that flows in a contact mode, locates the earliest event and
resets (`hybrid`, with its options in `options`), on the contact-free steppers of
`contactdiff.ode` (`steppers` keeps their former import path); guards over a mode
(`guards`, locating their crossings with `contactdiff.ode.crossings`); what the loop
does at an event (`event_resets`, `friction_events`, `held`, `resting`); the vector
field of a mode (`mode_field`); projection onto a mode's constraint manifold
(`projection`); a run at rest (`rest`); saltation matrices (`sensitivity`) and the
parameter blocks at events (`parameter_jumps`); and the resulting `Trajectory`
(`trajectory`) with its samples (`samples`).
"""
