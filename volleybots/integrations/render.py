"""``render_mode="rgb_array"`` for the Gymnasium env: the replay's still picture (court, net, the
ball's flight with its touches and faults, each drone's path in its team colour) of the episode so
far, with the drones where they are now, as an RGB array [H, W, 3] uint8.

The frame is drawn by ``volleybots.replay.still`` (matplotlib's headless Agg backend) from what the
``Trail`` keeps of one world each step, so a Gymnasium video (``RecordVideo``, SB3's video
recorder) shows what ``volleybots replay --still`` shows. Drawing a 3D figure takes tens of
milliseconds, so record videos of a few episodes, not of training.
"""

from __future__ import annotations

import numpy as np

from volleybots.replay.recorder import Episode, step_events
from volleybots.replay.still import check_plotting, still_frame
from volleybots.tasks import VolleyEnv
from volleybots.tasks.base import PARKED_BALL

RENDER_MODES = ("rgb_array",)


def check_render_mode(render_mode) -> str | None:
    """``render_mode`` if the Gymnasium env offers it (None: no rendering), else a ``ValueError``."""
    if render_mode is not None and render_mode not in RENDER_MODES:
        raise ValueError(f"render_mode must be None or one of {list(RENDER_MODES)}, got {render_mode!r}")
    if render_mode is not None:
        check_plotting()  # the extra's name now, not a traceback at the first frame
    return render_mode


class Trail:
    """What world ``index`` of ``env`` did since its episode began: drone and ball positions, and the
    steps of touches and faults (the replay's ``Episode``)."""

    def __init__(self, env: VolleyEnv, index: int = 0):
        self.env, self.i = env, index
        court = env.referee.cfg.court
        self.court = (float(court.length), float(court.width), float(court.net_height))
        self.teams = tuple(int(t) for t in env.teams)
        self.clear()

    def clear(self) -> None:
        self.pos, self.quat, self.ball, self.hits, self.faults = [], [], [], [], []

    def record(self, after_step: bool) -> None:
        """Keep the world's state now; ``after_step``: also the referee's events of the step just taken."""
        s = self.env.physics.state
        self.pos.append(s.pos[self.i].detach().cpu().numpy().copy())
        self.quat.append(s.quat[self.i].detach().cpu().numpy().copy())
        ball = s.ball_pos[self.i].detach().cpu().numpy().copy()
        parked = abs(ball[0] - PARKED_BALL[0]) < 1.0  # a task without a ball keeps it far away: not drawn
        self.ball.append(np.full(3, np.nan, np.float32) if parked else ball)
        if after_step:
            hits, _, faults = step_events(getattr(self.env, "last_events", None), self.i)
            step = len(self.ball) - 1
            self.hits += [step] if hits else []
            self.faults += [step] if faults else []

    def frame(self, title: str = "") -> np.ndarray:
        if not self.ball:
            raise RuntimeError("nothing to render yet: call reset() first")
        ep = Episode(
            teams=self.teams, court=self.court, pos=np.stack(self.pos), quat=np.stack(self.quat), ball=np.stack(self.ball),
            hits=list(self.hits), faults=list(self.faults), stats={},
        )
        return still_frame(ep, title=title)
