"""Hydra launchers for ``volleybots train -m`` sweeps: which plugin runs the jobs, and where.

``hydra/launcher=NAME`` on the command line picks one. The plugins are Hydra's own (hydra-joblib-
launcher, hydra-submitit-launcher, hydra-ray-launcher), installed by the ``cluster`` extra; a sweep
that names one that is not installed stops before anything runs, with the one line that says how to
install it (Hydra's own message would only list the launchers it found).
"""

from __future__ import annotations

import importlib.util

from volleybots.errors import ConfigError
from volleybots.overrides import override_key, split_arg

EXTRA = "cluster"  # pip install 'volleybots[cluster]' installs every plugin below

# hydra/launcher option -> (the plugin package that provides it, where its jobs run)
LAUNCHERS = {
    "basic": (None, "one job after another in this process (Hydra's default)"),
    "joblib": ("hydra_plugins.hydra_joblib_launcher", "parallel processes on this machine (joblib)"),
    "submitit_local": ("hydra_plugins.hydra_submitit_launcher", "one process per job on this machine (submitit's local executor)"),
    "submitit_slurm": ("hydra_plugins.hydra_submitit_launcher", "one SLURM job per sweep job (submitit)"),
    "ray": ("hydra_plugins.hydra_ray_launcher", "tasks on a Ray cluster, or on a local Ray instance it starts"),
}


def installed(name: str) -> bool:
    """Whether the plugin that provides launcher ``name`` can be imported here."""
    module = LAUNCHERS[name][0]
    if module is None:
        return True
    try:
        return importlib.util.find_spec(module) is not None
    except ModuleNotFoundError:
        # hydra-core ships no ``hydra_plugins`` package: on an install without any plugin, looking up
        # a plugin module fails on its missing parent instead of returning None
        return False


def check_launcher(overrides: list[str]) -> None:
    """Raise ``ConfigError`` for a ``hydra/launcher=`` override whose plugin is not installed.

    A name this module does not know is left to Hydra, which lists the launchers it has."""
    for o in overrides:
        value = split_arg(o)[1]
        if override_key(o) == "hydra/launcher" and value in LAUNCHERS and not installed(value):
            package = LAUNCHERS[value][0].rpartition(".")[2].replace("_", "-")
            raise ConfigError(f"hydra/launcher={value} needs the {package} plugin: pip install 'volleybots[{EXTRA}]'")
