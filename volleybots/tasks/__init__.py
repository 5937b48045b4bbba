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



def plays_as(task: str) -> str:
    """The task whose players a policy of ``task`` is (a drill that shares a match's observation and
    actions per drone, like ``receive`` with ``1v1``, names it as ``policy_task``): policies trained on
    either play the other's (``init=``, cross-play)."""
    cls = TASKS.get(task)
    return getattr(cls, "policy_task", "") or task


__all__ = [
    "plays_as", "TASKS", "StepResult", "VolleyEnv", "BackAndForth", "HitTheBall", "Hover", "SoloBump",
    "BumpAndPass", "SetAndSpikeEasy", "SetAndSpikeHard", "OneVsOne", "ThreeVsThree", "SixVsSix",
    "Serve", "Pass", "Set", "Attack", "Receive",
]
