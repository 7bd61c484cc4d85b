"""Contact dynamics: the flow in a contact mode, impacts and the choice of mode.

Accelerations, contact forces and their derivatives in any contact mode
(`mode`, with Pinocchio's constraint dynamics for modes of sticking point
contacts in `constraint_dynamics`), impacts by Newton restitution with
complementarity and the choice of the next mode (`impacts`), and the contact
complementarity problem they both solve, in pure numpy/scipy (`complementarity`,
its data and validation in `lcp_problem`).
"""
