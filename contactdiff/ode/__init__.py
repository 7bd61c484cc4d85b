"""Error-controlled ODE steppers with dense output, free of the contact model.

The explicit Runge–Kutta pairs (`explicit_rk`, `tableaus`) and Radau IIA (`radau`) on
the `stepper` base, the factory (`steppers`), their dense output (`dense`), the
configuration spaces they step on (`lie`), the flow Jacobian's linear algebra
(`variational`), guard crossings over a step (`events`), the choice of stepper
(`method_choice`) and the watches of a run's step sizes (`step_collapse`,
`step_budget`).
"""
