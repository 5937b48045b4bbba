"""The ``volleybots`` command line: train, eval, replay, list, bench, report.

Bad input (an unknown name, key, verb or option, a wrong type or an out-of-range value, an algorithm
that cannot act in the chosen action space, a missing or mismatched checkpoint, an output file that
exists or cannot be written, a run directory in use) prints one line naming the bad value and the
allowed ones, exits with code 2 and writes nothing. docs/usage.md lists the guarantees.

Modules: ``app`` (the Typer app and its error handling), ``train``, ``evaluate`` (eval verbs and
replay), ``tools`` (list, bench, report); importing this package registers every verb on ``app``.
"""

from volleybots.cli import train  # noqa: F401, I001 - registers the verbs, in the order --help lists them
from volleybots.cli import evaluate  # noqa: F401
from volleybots.cli import tools  # noqa: F401
from volleybots.cli.app import app

__all__ = ["app"]

if __name__ == "__main__":
    app()
