"""Where the packaged config tree lives, whether installed from a wheel, editable, or run from a checkout."""

from __future__ import annotations

from functools import lru_cache
from pathlib import Path


@lru_cache(maxsize=1)
def conf_dir() -> Path:
    # A wheel ships the top-level conf/ as the package volleybots.conf (pyproject's package-dir);
    # a checkout or an editable install finds it beside the package.
    here = Path(__file__).resolve().parent
    for cand in (here / "conf", here.parent / "conf"):
        if (cand / "env").is_dir():
            return cand
    try:
        from importlib.resources import files

        cand = Path(str(files("volleybots.conf")))
        if (cand / "env").is_dir():
            return cand
    except (ModuleNotFoundError, TypeError):
        pass
    raise FileNotFoundError("volleybots config tree (conf/) not found next to the package")
