"""The methods a benchmark sweeps, and the colour each is drawn in."""

METHODS = ("ours-DOP853", "ours-Radau", "solve_ivp-DOP853", "time-stepping")
"""Our two steppers, SciPy's solve_ivp with event functions, impulse-based time stepping."""
COLORS = {
    "ours-DOP853": "tab:blue",
    "ours-Radau": "tab:green",
    "solve_ivp-DOP853": "tab:orange",
    "time-stepping": "tab:red",
}
"""One matplotlib colour per method, the same in every figure."""
