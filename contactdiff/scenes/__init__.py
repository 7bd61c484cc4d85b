"""Where scenes come from: scene files (TOML) and the project's scene names, and
any command-line SOURCE as a scene (`scene_file`). Above `contactdiff.model` and
`contactdiff.control`: a scene file may build their efforts."""
