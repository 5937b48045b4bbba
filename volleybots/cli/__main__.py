"""``python -m volleybots.cli``: the same command line as ``volleybots``."""

from volleybots.cli import app

app()
