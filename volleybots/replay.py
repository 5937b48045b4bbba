"""Episodes as rerun recordings: court, net, drones (pose, racket, team colour), the ball with a trail,
the referee's hits and violations as events, per-step rewards and per-term returns as scalars, and a
hierarchical team's decisions (which drill each drone runs: ``decisions`` lines, ``drill/drone_<k>``).

``EpisodeRecorder`` follows one env of a batch through ``volleybots.eval.run_episodes`` (its
``on_step`` hook) until that env's first episode ends. ``record`` plays one episode of a target to a
``.rrd`` file (or a viewer); training uses the same recorder for its periodic evaluations.
"""

from __future__ import annotations

import dataclasses
from collections import deque
from contextlib import contextmanager
from pathlib import Path

import numpy as np
import torch

TEAM_COLOURS = ((40, 110, 230), (225, 60, 50))  # team 0 (+x half) blue, team 1 (-x half) red
BALL_COLOUR = (250, 210, 40)
HIT_EVENTS = ("racket_hit",)
# referee events that are not faults: "hit" repeats racket/body hits, the rest are bookkeeping
INFO_EVENTS = ("ball_crossed",)
SKIP_EVENTS = ("hit", "landed_side", "last_hitter")
TRAIL = 60  # ball trail length in control steps


class EpisodeRecorder:
    def __init__(self, rec, env, env_index: int = 0, prefix: str = ""):
        self.rec, self.env, self.i = rec, env, env_index
        self.prefix = prefix.rstrip("/") + "/" if prefix else ""
        self.step = 0
        self.done = False
        self.trail: deque = deque(maxlen=TRAIL)
        self._static()

    def _p(self, path: str) -> str:
        return self.prefix + path

    def _static(self) -> None:
        import rerun as rr

        env, rec = self.env, self.rec
        court = env.referee.cfg.court
        lx, ly, h = court.length / 2, court.width / 2, court.net_height
        rec.log(
            self._p("world/court"),
            rr.LineStrips3D(
                [[(-lx, -ly, 0), (lx, -ly, 0), (lx, ly, 0), (-lx, ly, 0), (-lx, -ly, 0)], [(0, -ly, 0), (0, ly, 0)]],
                colors=[(230, 230, 230)],
            ),
            static=True,
        )
        rec.log(
            self._p("world/net"),
            rr.Boxes3D(centers=[(0, 0, h / 2)], half_sizes=[(0.01, ly, h / 2)], colors=[(200, 200, 200, 90)], fill_mode="solid"),
            static=True,
        )
        d = env.params.drone
        for k, team in enumerate(env.teams):
            colour = TEAM_COLOURS[team % len(TEAM_COLOURS)]
            rec.log(self._p(f"world/drone_{k}/body"), rr.Boxes3D(half_sizes=[d.body_half_extents], colors=[colour]), static=True)
            rec.log(
                self._p(f"world/drone_{k}/racket"),
                rr.Cylinders3D(lengths=[0.01], radii=[d.racket_radius], centers=[(0, 0, d.racket_offset)], colors=[colour]),
                static=True,
            )

    def __call__(self, env, td, nxt) -> None:
        """The ``on_step`` hook of ``run_episodes``: log the state after this step."""
        import rerun as rr

        if self.done:
            return
        rec, i = self.rec, self.i
        rec.set_time("step", sequence=self.step)
        s = env.physics.state
        pos = s.pos[i].detach().cpu().numpy()
        quat = s.quat[i].detach().cpu().numpy()
        for k in range(pos.shape[0]):
            w, x, y, z = quat[k]
            rec.log(self._p(f"world/drone_{k}"), rr.Transform3D(translation=pos[k], quaternion=[x, y, z, w]))
        ball = s.ball_pos[i].detach().cpu().numpy()
        self.trail.append(ball.copy())
        rec.log(self._p("world/ball"), rr.Points3D([ball], radii=[env.params.ball.radius], colors=[BALL_COLOUR]))
        if len(self.trail) > 1:
            rec.log(self._p("world/ball_trail"), rr.LineStrips3D([np.stack(self.trail)], colors=[BALL_COLOUR]))
        self._events(env, ball)
        self._decisions(td)
        reward = nxt["agents", "reward"][i].reshape(-1).detach().cpu()
        for k, r in enumerate(reward.tolist()):
            rec.log(self._p(f"reward/drone_{k}"), rr.Scalars(r))
        for key in nxt["stats"].keys():
            rec.log(self._p(f"episode/{key}"), rr.Scalars(float(nxt["stats", key][i])))
        self.step += 1
        if bool(nxt["done"][i]):
            why = "terminated" if bool(nxt["terminated"][i]) else "truncated"
            rec.log(self._p("events"), rr.TextLog(f"step {self.step}: episode {why}", level="INFO"))
            self.done = True

    def _decisions(self, td) -> None:
        """A hierarchical team's high level (``("agents", "drill")``, codes of
        ``scripted.hierarchical.DRILL_LABELS``): each drone's drill as a scalar, and a line whenever
        one changes."""
        import rerun as rr

        if ("agents", "drill") not in td.keys(include_nested=True):
            return
        from volleybots.scripted.hierarchical import DRILL_LABELS

        codes = td.get(("agents", "drill"))[self.i].reshape(-1).tolist()
        last = getattr(self, "_last_drills", None)
        for k, c in enumerate(codes):
            if c == 0:  # a drone no high level drives
                continue
            self.rec.log(self._p(f"drill/drone_{k}"), rr.Scalars(float(c)))
            if last is None or last[k] != c:
                self.rec.log(self._p("decisions"), rr.TextLog(f"step {self.step}: drone {k} -> {DRILL_LABELS[c]}", level="INFO"))
        self._last_drills = codes

    def _events(self, env, ball) -> None:
        import rerun as rr

        ev = getattr(env, "last_events", None)
        if ev is None:
            return
        hits, faults = [], []
        for f in dataclasses.fields(ev):
            val = getattr(ev, f.name)
            if f.name in SKIP_EVENTS or not isinstance(val, torch.Tensor) or val.dtype != torch.bool:
                continue
            row = val[self.i]
            who = [f"drone {k}" for k in torch.nonzero(row).flatten().tolist()] if row.dim() else (["ball"] if bool(row) else [])
            for w in who:
                msg = f"step {self.step}: {w} {f.name}"
                if f.name in HIT_EVENTS:
                    hits.append(msg)
                elif f.name in INFO_EVENTS:
                    self.rec.log(self._p("events"), rr.TextLog(msg, level="INFO"))
                else:
                    faults.append(msg)
        for msg in hits:
            self.rec.log(self._p("events"), rr.TextLog(msg, level="INFO"))
        for msg in faults:
            self.rec.log(self._p("events"), rr.TextLog(msg, level="WARN"))
        if hits:
            self.rec.log(self._p("world/hits"), rr.Points3D([ball], radii=[0.15], colors=[(60, 220, 90)]))
        if faults:
            self.rec.log(self._p("world/violations"), rr.Points3D([ball], radii=[0.2], colors=[(240, 40, 40)]))


class MatchLog:
    """Beside ``EpisodeRecorder`` in a match: who plays which colour, the touches per team as they
    happen, and at the end the point (winner) with the fault that ended the rally."""

    def __init__(self, rec, env, labels: tuple[str, str], env_index: int = 0):
        import rerun as rr

        self.rec, self.i, self.labels = rec, env_index, labels
        self.names = [f"{labels[t]} ({'blue' if t == 0 else 'red'}, team {t}, {'+x' if t == 0 else '-x'})" for t in (0, 1)]
        self.done = False
        self.hits = [0, 0]
        rec.log("match", rr.TextLog(f"{self.names[0]} against {self.names[1]}", level="INFO"), static=True)

    def __call__(self, env, td, nxt) -> None:
        import rerun as rr

        if self.done:
            return
        from volleybots.rules import Referee

        i = self.i
        hits = [int(nxt["stats", f"hits_team{t}"][i]) for t in (0, 1)]
        if hits != self.hits:
            self.hits = hits
            self.rec.log("match", rr.TextLog(f"touches: {self.labels[0]} {hits[0]}, {self.labels[1]} {hits[1]}", level="INFO"))
        for t in (0, 1):
            self.rec.log(f"score/touches_team{t}", rr.Scalars(float(hits[t])))
        if bool(nxt["done"][i]):
            self.done = True
            winner, reason = int(nxt["stats", "winner"][i]), int(nxt["stats", "reason"][i])
            if winner < 0:
                msg = "no point: a draw (crash, teammates too close, a double fault or the time limit)"
            else:
                msg = f"point to {self.names[winner]}: {self.labels[1 - winner]} faulted ({Referee.FAULTS[reason]}); score {self.labels[0]} {int(winner == 0)} - {int(winner == 1)} {self.labels[1]}"
            self.rec.log("match", rr.TextLog(msg, level="WARN" if winner < 0 else "INFO"))


def has_display() -> bool:
    import os

    return bool(os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))


@contextmanager
def recording(out: Path | None, app_id: str = "volleybots", viewer: bool = False):
    """A rerun ``RecordingStream`` to the file ``out`` and/or a viewer. The file is written as
    ``<out>.<pid>.part`` (two processes never share one) and moved into place when the recording is
    complete; it is removed if the recording fails, and a failed write (a full disk) is one line."""
    import os

    import rerun as rr

    from volleybots.errors import ConfigError

    rec = rr.RecordingStream(app_id)
    tmp = None if out is None else Path(out).with_name(f"{Path(out).name}.{os.getpid()}.part")
    if viewer:
        rec.spawn(connect=tmp is None)
        if tmp is not None:
            rec.set_sinks(rr.FileSink(str(tmp)), rr.GrpcSink())  # both the viewer and the file
    elif tmp is not None:
        rec.save(tmp)
    try:
        yield rec
    except BaseException:
        rec.disconnect()
        if tmp is not None:
            tmp.unlink(missing_ok=True)
        raise
    try:
        rec.flush()
        rec.disconnect()
        if tmp is not None:
            if not tmp.is_file() or tmp.stat().st_size == 0:
                raise OSError(5, "the recording was not written (is the disk full?)")
            tmp.replace(out)
    except OSError as e:
        if tmp is not None:
            tmp.unlink(missing_ok=True)
        raise ConfigError(f"cannot write the recording {str(out)!r}: {e.strerror or e}; free space or choose another --out") from None


def record_episode(env, policy, out: Path | None, viewer: bool = False) -> dict:
    """Play one episode in env 0 of ``env`` while recording it to ``out`` and/or a viewer.

    Returns the episode's statistics (of env 0)."""
    from volleybots.play.episodes import run_episodes

    with recording(out, viewer=viewer) as rec:
        res = run_episodes(env, policy, on_step=EpisodeRecorder(rec, env, 0))
    return {k: float(v[0]) for k, v in res.items()}


def record_match(env, policy, labels: tuple[str, str], out: Path | None, viewer: bool = False) -> dict:
    """``record_episode`` for a match between two labelled teams (``policy``: ``TeamPolicies``),
    with the ``MatchLog`` of colours, touches and the ending fault."""
    from volleybots.play.episodes import run_episodes

    with recording(out, viewer=viewer) as rec:
        hooks = (EpisodeRecorder(rec, env, 0), MatchLog(rec, env, labels, 0))
        res = run_episodes(env, policy, on_step=lambda *a: [h(*a) for h in hooks])
    return {k: float(v[0]) for k, v in res.items()}


__all__ = ["EpisodeRecorder", "MatchLog", "has_display", "record_episode", "record_match", "recording"]
