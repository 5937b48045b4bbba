"""``render_mode="rgb_array"`` for the Gymnasium, PettingZoo and vector envs: a video frame of one world's
episode so far (court, net, the ball's flight with its touches and faults, each drone's path in its team
colour, a ball marker where the ball is, and a header with the step and the score of a match or the
task's metric) as an RGB array [H, W, 3] uint8.

The frame is drawn by ``volleybots.replay.raster`` (Pillow, a fixed camera, the court drawn once) from
what the ``Trail`` keeps of one world each step: a few milliseconds a frame, where the replay's
matplotlib still took about 70 ms, so a video of training (SB3's ``VecVideoRecorder``) costs little.
``Trail.still`` still gives the replay's still picture (``volleybots replay --still``) of the same data.
"""

from __future__ import annotations

import numpy as np

from volleybots.replay.raster import View, draw_frame, score_text
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
    steps of touches and faults (the replay's ``Episode``); and, across episodes, the points each team
    won (a match's score) and the task's statistics of the step last recorded."""

    def __init__(self, env: VolleyEnv, index: int = 0):
        self.env, self.i = env, index
        court = env.referee.cfg.court
        self.court = (float(court.length), float(court.width), float(court.net_height))
        self.teams = tuple(int(t) for t in env.teams)
        self.competitive, self.metric = bool(env.competitive), env.metric
        self.points = [0, 0]  # rallies won by each team since the env was made (what the header shows)
        self.stats: dict = {}  # the task's statistics of the episode so far (its metric in the header)
        self._view = None  # the camera and the court's background: made at the first frame
        self.clear()

    def clear(self) -> None:
        """Forget the episode's paths (a new one begins); the score stays."""
        self.pos, self.quat, self.ball, self.hits, self.faults = [], [], [], [], []
        self.stats = {}

    def record(self, after_step: bool, stats: dict | None = None) -> None:
        """Keep the world's state now; ``after_step``: also the referee's events of the step just taken;
        ``stats``: the world's episode statistics after it (``spaces.episode_stats``)."""
        s = self.env.physics.state
        self.pos.append(s.pos[self.i].detach().cpu().numpy().copy())
        self.quat.append(s.quat[self.i].detach().cpu().numpy().copy())
        ball = s.ball_pos[self.i].detach().cpu().numpy().copy()
        parked = abs(ball[0] - PARKED_BALL[0]) < 1.0  # a task without a ball keeps it far away: not drawn
        self.ball.append(np.full(3, np.nan, np.float32) if parked else ball)
        if stats is not None:
            self.stats = dict(stats)
        if after_step:
            hits, _, faults = step_events(getattr(self.env, "last_events", None), self.i)
            step = len(self.ball) - 1
            self.hits += [step] if hits else []
            self.faults += [step] if faults else []

    def end(self, stats: dict) -> None:
        """The world's episode ended with ``stats``: a match's winner takes the point."""
        self.stats = dict(stats)
        winner = int(stats.get("winner", -1)) if self.competitive else -1
        if winner in (0, 1):
            self.points[winner] += 1

    def after_batched_step(self, stats: dict, ended: bool) -> None:
        """After a step of a vector env that resets a finished world within the step: an ended episode
        gives its point and the trail starts the next one (the world is already in it)."""
        if ended:
            self.end(stats)
            self.clear()
            self.record(after_step=False)
        else:
            self.record(after_step=True, stats=stats)

    def header(self, title: str) -> str:
        """The frame's header: the title, the step, and the score of a match or the task's metric so far."""
        text = f"{title}   step {max(len(self.ball) - 1, 0)}"
        if self.competitive:
            return f"{text}   {score_text(self.points)}   touches {len(self.hits)}"
        value = self.stats.get(self.metric)
        return text if value is None else f"{text}   {self.metric} {float(value):.3g}"

    def _episode(self) -> Episode:
        if not self.ball:
            raise RuntimeError("nothing to render yet: call reset() first")
        return Episode(
            teams=self.teams, court=self.court, pos=np.stack(self.pos), quat=np.stack(self.quat), ball=np.stack(self.ball),
            hits=list(self.hits), faults=list(self.faults), stats={},
        )

    def frame(self, title: str = "") -> np.ndarray:
        """The video frame of the episode so far ([H, W, 3] uint8; ``volleybots.replay.raster``)."""
        if not self.ball:
            raise RuntimeError("nothing to render yet: call reset() first")
        if self._view is None:
            self._view = View(self.court)
        return draw_frame(self._view, np.stack(self.pos), np.stack(self.ball), self.teams, self.hits, self.faults, self.header(title))

    def still(self, title: str = "") -> np.ndarray:
        """The replay's still picture of the episode so far (matplotlib: about 70 ms)."""
        return still_frame(self._episode(), title=title)
