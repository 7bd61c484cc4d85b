"""The project's own robot models (URDF) and scene files (TOML), shipped as
``contactdiff.robots`` (see pyproject.toml)."""
