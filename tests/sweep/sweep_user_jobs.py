"""User jobs for the sweep tests, imported by name (``sweep_user_jobs:...``) in worker processes."""

from __future__ import annotations

import math
import os

import contactdiff as cd

NOT_A_FUNCTION = 3


def fall_time(scene, point):
    """The ball's first touchdown time, and the point it was given."""
    traj = cd.simulate(scene, point["t_final"])
    return {"first_event": traj.events[0].t, "given": sorted(point), "nan": math.nan}


def not_a_dict(scene, point):
    return [1, 2]


def clashing(scene, point):
    return {"error": 1}


def process_id(scene, point):
    return {"pid": os.getpid()}


def ball_not_in(pid):
    """A scene factory that refuses to run in process ``pid``."""
    if os.getpid() == pid:
        raise RuntimeError("built in the process that started the sweep")
    return cd.load_scene("ball")


def break_folder(scene, point):
    """At the point ``q:z`` = 2, replace the folder ``job:folder`` by a regular file: the
    results file and the plot in it can no longer be written (as root too)."""
    import shutil
    from pathlib import Path

    if point["q:z"] == 2:
        shutil.rmtree(point["job:folder"])
        Path(point["job:folder"]).write_text("not a folder any more\n")
    return {"height": point["q:z"]}
