"""Tasks: reset, observation, reward and metric per task over one shared env base."""

from volleybots.tasks.base import StepResult, VolleyEnv
from volleybots.tasks.single import BackAndForth, HitTheBall, Hover, SoloBump

TASKS: dict[str, type[VolleyEnv]] = {cls.name: cls for cls in (Hover, BackAndForth, HitTheBall, SoloBump)}

__all__ = ["TASKS", "StepResult", "VolleyEnv", "BackAndForth", "HitTheBall", "Hover", "SoloBump"]
