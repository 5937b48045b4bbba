"""Scripted model-based players: batched flight control, ball intercept planning and task policies.

``make_scripted_policy(env_or_task, action_space)`` returns a policy ``td -> td`` that reads
``("agents", "observation")`` and writes ``("agents", "action")`` like a learned one. The pieces are
reusable: ``control`` (position/attitude cascade to PRT or CTBR actions), ``ballistics`` (flight
prediction, launch and racket solutions), ``plan`` (strike planner, trajectories, guidance).
"""

from volleybots.scripted import bump_and_pass, drills, match, receive, set_and_spike, set_and_spike_hard  # noqa: F401  (register the multi-drone players and drills)
from volleybots.scripted.ballistics import (
    ball_at,
    bounce,
    crossing,
    launch_for_apex,
    launch_for_range,
    racket_for,
    time_to_height,
)
from volleybots.scripted.control import DroneController, DroneObs, Gains
from volleybots.scripted.plan import (
    Strike,
    StrikePlanner,
    goto_accel,
    off_centre,
    quintic,
)
from volleybots.scripted.policies import (
    SCRIPTED_POLICIES,
    BackAndForthPolicy,
    HitTheBallPolicy,
    HoverPolicy,
    ScriptedPolicy,
    SoloBumpPolicy,
    make_scripted_policy,
)

__all__ = [
    "SCRIPTED_POLICIES", "BackAndForthPolicy", "DroneController", "DroneObs", "Gains", "HitTheBallPolicy",
    "HoverPolicy", "ScriptedPolicy", "SoloBumpPolicy", "Strike", "StrikePlanner", "ball_at", "bounce", "crossing",
    "goto_accel", "launch_for_apex", "launch_for_range", "make_scripted_policy", "off_centre", "quintic",
    "racket_for", "time_to_height",
]
