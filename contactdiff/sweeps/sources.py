"""Where each worker gets the sweep's scene: a name or file it loads, or a function it calls.

Pinocchio objects do not pickle (a `Scene` holds constraint models that cannot
travel to another process), so a sweep sends workers a `SceneSource` and each
worker builds the scene itself, once per process: `SceneSource.build` keeps the
scenes it built (keyed by the source, a scene file's modification time and
size, and the factory's arguments), and each point then derives its own
variant (`contactdiff.sweeps.quantities.apply`) without touching the kept one.
"""

from __future__ import annotations

import functools
import json
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path

from ..errors import InvalidInputError
from ..model.scene import Scene
from .callables import import_callable, is_reference, keyword_names, reference, required_names

SCENE_CACHE_SIZE = 8
"""Scenes a worker process keeps (distinct sources and factory arguments)."""


@dataclass(frozen=True, eq=False)
class SceneSource:
    """A scene as a worker can rebuild it.

    Attributes:
        label: the source as given: a scene name, a TOML path (made absolute), a
            robot name, or ``module:function`` of a factory.
        factory: the function that builds the scene from keyword arguments (the
            sweep's ``arg:<name>`` quantities), or None for a name or file loaded
            with `contactdiff.scenes.scene_file.load_source`.
    """

    label: str
    factory: Callable | None = None

    @classmethod
    def of(cls, scene) -> SceneSource:
        """The source of what `sweep` takes as its scene: a scene name, a TOML path, a
        robot name (its feet get ground contacts), ``"module:function"`` or a callable
        returning a `Scene`.

        Raises:
            InvalidInputError: a `Scene` object (it cannot be sent to worker
                processes), or anything else that is not a source.
        """
        if isinstance(scene, SceneSource):
            return scene
        if isinstance(scene, Scene):
            raise InvalidInputError(
                f"sweep: scene {scene.name!r} is a Scene object, which cannot be sent to worker processes "
                "(Pinocchio objects do not pickle); give its name or TOML file, or a function that builds it "
                "(a callable or 'module:function')"
            )
        if callable(scene):
            return cls(reference(scene), scene)
        if isinstance(scene, Path) or (isinstance(scene, str) and scene.endswith(".toml")):
            return cls(str(Path(scene).resolve()))
        if isinstance(scene, str) and scene:
            if is_reference(scene) and not Path(scene).exists():
                return cls(scene, import_callable(scene, "scene factory"))
            return cls(scene)
        raise InvalidInputError(
            f"sweep: scene must be a scene name, a TOML path, a robot name, 'module:function' "
            f"or a callable returning a Scene; got {scene!r}"
        )

    def argument_names(self) -> tuple[str, ...] | None:
        """The factory's keyword arguments (None: any, it takes ``**kwargs``); () for a name or file."""
        return () if self.factory is None else keyword_names(self.factory)

    def check_arguments(self, names) -> None:
        """Refuse a sweep that leaves out an argument the factory needs (no default).

        Raises:
            InvalidInputError: naming the missing ``arg:<name>`` quantities.
        """
        if self.factory is None:
            return
        missing = [n for n in required_names(self.factory) if f"arg:{n}" not in names]
        if missing:
            raise InvalidInputError(
                f"sweep: scene factory {self.label} needs "
                + ", ".join(f"arg:{n}" for n in missing)
                + "; sweep it or fix it (fixed=, --set)"
            )

    def build(self, args: Mapping | None = None) -> Scene:
        """The scene for the factory arguments ``args``, built once per process and kept.

        The kept scene is shared by every point of this process with these
        arguments: callers derive variants (`Scene.with_parameters`,
        `Scene.with_state`) and never change it.

        Raises:
            InvalidInputError: the factory does not return a `Scene`; and whatever
                loading or the factory raises.
        """
        items = tuple((args or {}).items())
        return _built(
            self.label,
            _stamp(self.label) if self.factory is None else None,
            json.dumps(items, sort_keys=True),
            _Builder(self, items),
        )


class _Builder:
    """The build call, not part of the cache key (`_built` is keyed by its other arguments)."""

    def __init__(self, source: SceneSource, items: tuple):
        self.source, self.items = source, items

    def __hash__(self) -> int:
        return 0

    def __eq__(self, other) -> bool:
        return isinstance(other, _Builder)

    def __call__(self) -> Scene:
        source = self.source
        if source.factory is None:
            from ..scenes.scene_file import load_source

            return load_source(source.label)
        scene = source.factory(**dict(self.items))
        if not isinstance(scene, Scene):
            raise InvalidInputError(f"sweep: scene factory {source.label} returned {type(scene).__name__}, not a Scene")
        return scene


@functools.lru_cache(maxsize=SCENE_CACHE_SIZE)
def _built(label: str, stamp, args: str, builder: _Builder) -> Scene:
    return builder()


def _stamp(label: str):
    """A scene file's modification time and size (an edited file is loaded again); None otherwise."""
    path = Path(label)
    if path.suffix != ".toml":
        from ..model.robot_files import ROBOTS_DIR

        path = ROBOTS_DIR / f"{label}.toml"
    try:
        status = path.stat()
    except OSError:
        return None
    return status.st_mtime_ns, status.st_size


__all__ = ["SceneSource", "SCENE_CACHE_SIZE"]
