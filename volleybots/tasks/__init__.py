"""Tasks: reset, observation, reward and metric per task over one shared env base."""

from volleybots.tasks.base import StepResult, VolleyEnv
from volleybots.tasks.coop import BumpAndPass, SetAndSpikeEasy, SetAndSpikeHard
from volleybots.tasks.drills import Attack, Pass, Serve, Set
from volleybots.tasks.match import OneVsOne, SixVsSix, ThreeVsThree
from volleybots.tasks.receive import Receive
from volleybots.tasks.single import BackAndForth, HitTheBall, Hover, SoloBump

TASKS: dict[str, type[VolleyEnv]] = {
    cls.name: cls
    for cls in (
        Hover, BackAndForth, HitTheBall, SoloBump,
        BumpAndPass, SetAndSpikeEasy, SetAndSpikeHard, OneVsOne, ThreeVsThree, SixVsSix,
        Serve, Pass, Set, Attack, Receive,
    )
}

__all__ = [
    "TASKS", "StepResult", "VolleyEnv", "BackAndForth", "HitTheBall", "Hover", "SoloBump",
    "BumpAndPass", "SetAndSpikeEasy", "SetAndSpikeHard", "OneVsOne", "ThreeVsThree", "SixVsSix",
    "Serve", "Pass", "Set", "Attack", "Receive",
]
