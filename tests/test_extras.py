"""A missing optional extra: one exception type, raised by one helper, naming the extra.

Each place that imports an optional dependency is run with the module hidden
(``sys.modules[name] = None`` makes ``import name`` raise ImportError) and must
raise `MissingExtraError` whose message names an extra that pyproject.toml
declares and that lists the hidden module.
"""

from __future__ import annotations

import re
import sys
import tomllib
from pathlib import Path

import pytest

from contactdiff import MissingExtraError as TopLevel
from contactdiff.errors import ContactDiffError, MissingExtraError, require_extra
from contactdiff.replay import MissingExtraError as FromReplay

ROOT = Path(__file__).resolve().parents[1]
EXTRAS = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["optional-dependencies"]


def _extra_of(message: str) -> str:
    found = re.search(r"pip install 'contactdiff\[(\w[\w-]*)\]'", message)
    assert found, message
    return found.group(1)


def test_one_type_importable_from_its_old_home():
    assert FromReplay is MissingExtraError is TopLevel
    assert issubclass(MissingExtraError, ContactDiffError) and issubclass(MissingExtraError, ImportError)


def test_require_extra_returns_the_module_or_names_the_extra(monkeypatch):
    assert require_extra("json", "plot", "anything") is sys.modules["json"]
    monkeypatch.setitem(sys.modules, "matplotlib", None)
    expected = r"^plotting needs matplotlib \(.*\): pip install 'contactdiff\[plot\]'$"
    with pytest.raises(MissingExtraError, match=expected):
        require_extra("matplotlib", "plot", "plotting")


def _plotting():
    from contactdiff.plotting import _pyplot

    _pyplot()


def _plot_option():
    from contactdiff.cli_args import check_plot_path

    check_plot_path("out.png")


def _pandas():
    from contactdiff.sweeps.rows import SweepResult

    SweepResult([], ()).to_pandas()


def _dask_backend():
    from contactdiff.sweeps.engines import Engine

    Engine.of("dask", 2)


def _ray_backend():
    from contactdiff.sweeps.engines import Engine

    Engine.of("ray", 2)


def _mujoco():
    from contactdiff.bench.gradients_mujoco import mujoco

    mujoco()


def _mjx():
    from contactdiff.bench.gradients_mujoco import mjx_gradient

    mjx_gradient(None, None, None, 1, [0], [0])


def _replay():
    from contactdiff.replay import require_meshcat

    require_meshcat()


@pytest.mark.parametrize(
    "call, hidden",
    [
        (_plotting, "matplotlib"),
        (_plot_option, "matplotlib.figure"),
        (_pandas, "pandas"),
        (_dask_backend, "distributed"),
        (_ray_backend, "ray"),
        (_mujoco, "mujoco"),
        (_mjx, "jax"),
        (_replay, "meshcat"),
    ],
    ids=lambda x: getattr(x, "__name__", x),
)
def test_every_optional_import_raises_the_one_type_with_a_declared_extra(monkeypatch, call, hidden):
    monkeypatch.setitem(sys.modules, hidden, None)
    with pytest.raises(MissingExtraError) as info:
        call()
    message = str(info.value)
    assert hidden.split(".")[0] in message
    assert _extra_of(message) in EXTRAS
