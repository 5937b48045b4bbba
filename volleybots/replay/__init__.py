"""Episodes as rerun recordings: court, net, drones (pose, racket, team colour), the ball with a trail,
the referee's hits and violations as events, per-step rewards and per-term returns as scalars, and a
hierarchical team's decisions (which drill each drone runs: ``decisions`` lines, ``drill/drone_<k>``).

``EpisodeRecorder`` (``recorder.py``) follows one env of a batch through ``volleybots.play.run_episodes``
(its ``on_step`` hook) until that env's first episode ends, then sends the episode as columns with a
default layout (``layout.py``: the court large, curves grouped per team, how it ended). ``record``
functions play one episode of a target to a ``.rrd`` file (or a viewer), optionally with a still
picture (``still.py``); training uses the same recorder for its periodic evaluations and
``write_curves`` (``curves.py``) for its curves.
"""

from __future__ import annotations

from pathlib import Path

from volleybots.replay.curves import write_curves
from volleybots.replay.recorder import TEAM_COLOURS, Episode, EpisodeRecorder, MatchLog
from volleybots.replay.sink import has_display, recording


def _title(env, ep: Episode, labels=None) -> str:
    name = type(env).__name__
    if labels:
        name += f": {labels[0]} (blue) against {labels[1]} (red)"
    return f"{name}: {len(ep.hits)} touches in {len(ep.ball)} control steps"


def record_episode(env, policy, out: Path | None, viewer: bool = False, still: Path | None = None) -> dict:
    """Play one episode in env 0 of ``env`` while recording it to ``out`` and/or a viewer, and draw
    it to the PNG ``still`` when given.

    Returns the episode's statistics (of env 0)."""
    from volleybots.play.episodes import run_episodes
    from volleybots.replay.still import check_plotting, draw_still

    if still is not None:
        check_plotting()
    with recording(out, viewer=viewer) as rec:
        recorder = EpisodeRecorder(rec, env, 0)
        res = run_episodes(env, policy, on_step=recorder)
        recorder.flush()
    stats = {k: float(v[0]) for k, v in res.items()}
    if still is not None:
        ep = recorder.episode()
        draw_still(ep, still, _title(env, ep))
    return stats


def record_match(env, policy, labels: tuple[str, str], out: Path | None, viewer: bool = False, still: Path | None = None) -> dict:
    """``record_episode`` for a match between two labelled teams (``policy``: ``TeamPolicies``),
    with the ``MatchLog`` of colours, touches and the ending fault."""
    from volleybots.play.episodes import run_episodes
    from volleybots.replay.still import check_plotting, draw_still

    if still is not None:
        check_plotting()
    with recording(out, viewer=viewer) as rec:
        recorder = EpisodeRecorder(rec, env, 0, labels=labels)
        hooks = (recorder, MatchLog(rec, env, labels, 0))
        res = run_episodes(env, policy, on_step=lambda *a: [h(*a) for h in hooks])
        recorder.flush()
    stats = {k: float(v[0]) for k, v in res.items()}
    if still is not None:
        ep = recorder.episode()
        draw_still(ep, still, _title(env, ep, labels))
    return stats


__all__ = [
    "TEAM_COLOURS", "Episode", "EpisodeRecorder", "MatchLog", "has_display", "record_episode", "record_match", "recording", "write_curves",
]
