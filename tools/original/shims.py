"""Make the released code (jcoreyes/ecologicalrl) importable on today's Python, without editing its files.

Each adjustment is import-time only and changes nothing the released code computes:

1. ``PyQt5`` (imported by ``gym_minigrid/rendering.py`` for on-screen rendering, never used in training) is
   replaced by empty stand-in modules.
2. ``rlkit.core.humaninput_lifetime_rl_algorithm`` is imported by ``rlkit/torch/torch_rl_algorithm.py`` but was
   not released; a stand-in module defines the one (unused) class name it imports.
3. ``gym_minigrid/__init__.py`` and ``gym_minigrid/envs/__init__.py`` import modules that were not released
   (``getfood_medium``); the two packages are registered with their real folders but without running those
   ``__init__`` files, so ``deer.py``, ``factory.py`` and the rest import as they are. The top-level name
   ``gym_minigrid`` (the scripts', the validation pickles' and ``rl_algorithm.py``'s) is that same folder, as
   when the release's ``gym_minigrid`` was installed beside ``rlkit``: a module imported under both names is
   loaded twice, as it was there.
4. ``doodad`` (the EC2 launcher, imported at the top of ``rlkit/launchers/launcher_util.py`` to describe code
   mounts) is replaced by stand-in modules with the two names it imports; nothing is launched through it, as
   runs are started in this process.
5. The validation environments were pickled (2019-11, 2020-02) by an earlier version of the environment classes
   than the one released, which sets a few more attributes in ``__init__``, all bookkeeping for measurements
   (``reset_hitting``, ``hitting_time``, mixing-time and transition counters, ``grid_render``); the released
   ``reset`` reads ``reset_hitting`` and fails without it. Environments unpickled here get each attribute they
   lack, with the value the released ``__init__`` gives it by default (`PICKLE_DEFAULTS`).

6. ``FoodEnvBase.step`` appends a copy of the environment's whole observation-count dictionary every 120 steps
   (for a mixing-time measure) and trims that list only when the run asks for mixing times, which none of the
   released scripts run here does: in a 1.5 M-step non-episodic run the copies grow without bound (a hunting seed
   past 10 GB by 1 500 epochs, more than a 24 GB machine can hold for two seeds). After each step the list is
   trimmed to the entries the release ever reads (`trim_count_snapshots`): the last ``max_mixing_time_period + 1``,
   which is the release's own rule when mixing times are asked for. Nothing trained or measured changes.
7. The wall scripts (``env_shaping/env_vs_reward/wall/``) name their validation pickle under ``examples/``, the
   folder's name before the release renamed it ``experiments/`` (where every other script points, and where the
   named file is): such a path is read from ``experiments/`` (`released_path`).

Everything else the released code needs comes from the versions pinned in ``requirements.txt`` (gym 0.10.5,
the version the released environment file names; NumPy 1.x, which the validation pickles and gym 0.10.5 need).
"""

from __future__ import annotations

import importlib
import sys
import types
from pathlib import Path

ADJUSTMENTS = (
    "PyQt5 replaced by empty modules (on-screen rendering only)",
    "rlkit.core.humaninput_lifetime_rl_algorithm (not released) replaced by a module with its one unused class",
    "gym_minigrid and gym_minigrid.envs registered without their __init__ files (they import unreleased modules)",
    "doodad (the EC2 launcher) replaced by modules with its two imported names; runs start in-process",
    "environments unpickled from the validation files get the bookkeeping attributes the released __init__ "
    "sets and the older pickles lack, at their __init__ defaults",
    "the observation-count snapshots FoodEnvBase.step appends every 120 steps are trimmed to the last "
    "max_mixing_time_period + 1 (all the release reads; it trims so itself when mixing times are measured)",
    "a validation pickle named under examples/ (the folder's name before the release renamed it experiments/) is "
    "read from experiments/",
)
PICKLE_DEFAULTS = {
    "reset_hitting": lambda: True,
    "hitting_time": lambda: 0,
    "grid_render": lambda: None,
    "transition_count": dict,
    "obs_counts": list,
    "mixing_time_periods": list,
    "max_mixing_time_period": lambda: 0,
    "mixing_time_period_length": lambda: 120,
}
"""What the released ``__init__`` sets (``FoodEnvBase``, ``DeerEnv``, ``MiniGridAbsoluteEnv`` defaults) and the
validation pickles lack, as factories (so no two environments share a container)."""


class _Unused:
    """Stands for any Qt class: building or calling it does nothing (rendering is never reached)."""

    def __init__(self, *args, **kwargs) -> None:
        pass

    def __getattr__(self, name: str) -> _Unused:
        return _Unused()

    def __call__(self, *args, **kwargs) -> _Unused:
        return _Unused()


def _qt_attribute(name: str) -> type:
    if name.startswith("__"):
        raise AttributeError(name)
    return _Unused


def _package(name: str, folder: Path) -> types.ModuleType:
    module = types.ModuleType(name)
    module.__path__ = [str(folder)]
    sys.modules[name] = module
    return module


def check_checkout(checkout: Path) -> Path:
    """``checkout`` resolved, or a one-line exit if it holds no checkout of the release."""
    checkout = checkout.resolve()
    if not (checkout / "rlkit" / "envs" / "gym_minigrid" / "gym_minigrid" / "envs" / "deer.py").is_file():
        raise SystemExit(f"{checkout} is not a checkout of jcoreyes/ecologicalrl (no rlkit/envs/gym_minigrid); "
                         "pass --checkout PATH to one")
    return checkout


def released_path(path: str, checkout: Path) -> str:
    """``path`` itself, or, where it names a missing file under the checkout's ``examples/``, the same file under
    ``experiments/`` (adjustment 7).
    """
    old, new = checkout.resolve() / "examples", checkout.resolve() / "experiments"
    moved = Path(path)
    if moved.is_file() or not moved.is_relative_to(old):
        return path
    return str(new / moved.relative_to(old))


def install(checkout: Path) -> None:
    """Put the released checkout at ``checkout`` on the path with the adjustments above."""
    checkout = check_checkout(checkout)
    import torch  # noqa: F401  (before the Qt stand-ins, so torch's own imports never see them)

    sys.path.insert(0, str(checkout))
    for name in ("PyQt5", "PyQt5.QtCore", "PyQt5.QtGui", "PyQt5.QtWidgets"):
        module = types.ModuleType(name)
        module.__path__ = []
        module.__getattr__ = _qt_attribute
        sys.modules[name] = module
    missing = types.ModuleType("rlkit.core.humaninput_lifetime_rl_algorithm")
    missing.HumanInputLifetimeRLAlgorithm = type("HumanInputLifetimeRLAlgorithm", (), {})
    sys.modules[missing.__name__] = missing
    doodad = _package("doodad", checkout)
    doodad.mount = types.ModuleType("doodad.mount")
    doodad.mount.MountLocal = _Unused
    doodad.utils = types.ModuleType("doodad.utils")
    doodad.utils.REPO_DIR = str(checkout)
    sys.modules.update({"doodad.mount": doodad.mount, "doodad.utils": doodad.utils})
    importlib.import_module("rlkit.envs")
    base = checkout / "rlkit" / "envs" / "gym_minigrid"
    _package("rlkit.envs.gym_minigrid", base)
    sys.modules["gym_minigrid"] = _package("rlkit.envs.gym_minigrid.gym_minigrid", base / "gym_minigrid")
    sys.modules["gym_minigrid.envs"] = _package("rlkit.envs.gym_minigrid.gym_minigrid.envs",
                                                base / "gym_minigrid" / "envs")
    _complete_unpickled_envs()
    trim_count_snapshots()


def _complete_unpickled_envs() -> None:
    """Give every environment unpickled from then on the `PICKLE_DEFAULTS` attributes it lacks."""
    from rlkit.envs.gym_minigrid.gym_minigrid.envs.getfood_base import FoodEnvBase

    def __setstate__(self, state: dict) -> None:
        self.__dict__.update(state)
        for name, default in PICKLE_DEFAULTS.items():
            if name not in state:
                setattr(self, name, default())

    FoodEnvBase.__setstate__ = __setstate__


def trim_count_snapshots() -> None:
    """After each step keep only the observation-count snapshots the release reads (adjustment 6)."""
    from rlkit.envs.gym_minigrid.gym_minigrid.envs.getfood_base import FoodEnvBase

    original = FoodEnvBase.step

    def step(self, *args, **kwargs):
        result = original(self, *args, **kwargs)
        keep = getattr(self, "max_mixing_time_period", 0) + 1
        if len(self.obs_counts) > keep:
            del self.obs_counts[:-keep]
        return result

    FoodEnvBase.step = step
