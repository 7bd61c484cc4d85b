"""Contact dynamics: the flow in a contact mode, impacts and the choice of mode.

Accelerations, contact forces and their derivatives in any contact mode
(`mode`; its records in `mode_solution`, its force solves in `mode_forces`, its
derivatives in `mode_derivatives`; Pinocchio's constraint dynamics for modes of
sticking point contacts in `constraint_dynamics`), impacts by Newton restitution
with complementarity and the choice of the next mode (`impacts`), the contact
complementarity problem they both solve, in pure numpy/scipy (`complementarity`,
its data and validation in `lcp_problem`), and the impact law with a finite
friction coefficient (`frictional_impact`; one candidate in `impact_candidate`,
its slip directions in `friction_slip`, `slip_map` and `slip_lowrank`).
"""
