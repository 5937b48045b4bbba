"""Follow one env of a batch through an episode and send it to rerun as columns.

``EpisodeRecorder`` is the ``on_step`` hook of ``volleybots.play.run_episodes``. Each step it only
copies the state of its env into arrays; when the episode ends (or on ``flush()``) it sends every
entity as one ``send_columns`` call over the ``step`` timeline, then the default layout
(``volleybots.replay.layout``) and a summary document. Logging value by value made a chunk per entity
per batcher tick, whose headers outweighed the data about ten to one.

``MatchLog`` adds a match's sparse lines (who plays which colour, touches, the point and its fault).
"""

from __future__ import annotations

import dataclasses
from collections import deque

import numpy as np
import torch

from volleybots.keys import DONE, DRILL, REWARD, STATS, TERMINATED, stat
from volleybots.replay.style import BALL_COLOUR, FAULT_COLOUR, HIT_COLOUR, TEAM_COLOURS, TEAM_NAMES  # noqa: F401 - re-exported

HIT_EVENTS = ("racket_hit",)
# referee events that are not faults: "hit" repeats racket/body hits, the rest are bookkeeping
INFO_EVENTS = ("ball_crossed",)
SKIP_EVENTS = ("hit", "landed_side", "last_hitter")
TRAIL = 60  # ball trail length in control steps


def step_events(ev, i: int) -> tuple[list[str], list[str], list[str]]:
    """The referee's events ``ev`` of one step in env ``i`` as (touches, other notes, faults), each a
    list of ``"<who> <event>"`` (who: ``drone k`` or ``ball``); empty lists without events."""
    hits, infos, faults = [], [], []
    if ev is None:
        return hits, infos, faults
    for f in dataclasses.fields(ev):
        val = getattr(ev, f.name)
        if f.name in SKIP_EVENTS or not isinstance(val, torch.Tensor) or val.dtype != torch.bool:
            continue
        row = val[i]
        who = [f"drone {k}" for k in torch.nonzero(row).flatten().tolist()] if row.dim() else (["ball"] if bool(row) else [])
        kept = hits if f.name in HIT_EVENTS else infos if f.name in INFO_EVENTS else faults
        kept += [f"{w} {f.name}" for w in who]
    return hits, infos, faults


@dataclasses.dataclass
class Episode:
    """One recorded episode as arrays over its control steps: what the rrd holds and the still draws."""

    teams: tuple[int, ...]
    court: tuple[float, float, float]  # length, width, net height (m)
    pos: np.ndarray  # [T, D, 3] drone positions
    quat: np.ndarray  # [T, D, 4] drone attitudes, w x y z
    ball: np.ndarray  # [T, 3]
    hits: list[int]  # steps at which a racket touched the ball
    faults: list[int]  # steps at which the referee called a fault
    stats: dict[str, float]  # the episode's statistics at its last step


class EpisodeRecorder:
    """The ``on_step`` hook that keeps env ``env_index``'s episode and sends it as columns when it
    ends (``flush`` sends what was kept earlier); ``labels`` name a match's teams in the summary."""

    def __init__(self, rec, env, env_index: int = 0, prefix: str = "", labels: tuple[str, str] | None = None):
        self.rec, self.env, self.i, self.labels = rec, env, env_index, labels
        self.prefix = prefix.rstrip("/") + "/" if prefix else ""
        self.teams = tuple(int(t) for t in env.teams)
        self.step = 0
        self.done = self.sent = False
        self.why = ""  # "terminated" or "truncated" once the episode ends
        self.trail: deque = deque(maxlen=TRAIL)
        self.pos, self.quat, self.ball, self.strips, self.rewards = [], [], [], [], []
        self.stats: dict[str, list[float]] = {}
        self.texts: dict[str, list[tuple[int, str, str]]] = {"events": [], "decisions": []}
        self.marks: dict[str, list[tuple[int, np.ndarray]]] = {"world/hits": [], "world/violations": []}
        self.drills: dict[int, list[tuple[int, float]]] = {}
        self._last_drills = None
        self._static()

    def _p(self, path: str) -> str:
        return self.prefix + path

    def _static(self) -> None:
        import rerun as rr

        env, rec = self.env, self.rec
        court = env.referee.cfg.court
        self.court = (float(court.length), float(court.width), float(court.net_height))
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
        for k, team in enumerate(self.teams):
            colour = TEAM_COLOURS[team % len(TEAM_COLOURS)]
            rec.log(self._p(f"world/drone_{k}/body"), rr.Boxes3D(half_sizes=[d.body_half_extents], colors=[colour]), static=True)
            rec.log(
                self._p(f"world/drone_{k}/racket"),
                rr.Cylinders3D(lengths=[0.01], radii=[d.racket_radius], centers=[(0, 0, d.racket_offset)], colors=[colour]),
                static=True,
            )

    def __call__(self, env, td, nxt) -> None:
        """The ``on_step`` hook of ``run_episodes``: keep the state after this step."""
        if self.done:
            return
        i = self.i
        s = env.physics.state
        self.pos.append(s.pos[i].detach().cpu().numpy().copy())
        self.quat.append(s.quat[i].detach().cpu().numpy().copy())
        ball = s.ball_pos[i].detach().cpu().numpy().copy()
        self.ball.append(ball)
        self.trail.append(ball)
        self.strips.append(np.stack(self.trail))
        self._events(env, ball)
        self._decisions(td)
        self.rewards.append(nxt[REWARD][i].reshape(-1).detach().cpu().numpy().astype(np.float64))
        for key in nxt[STATS].keys():
            self.stats.setdefault(key, []).append(float(nxt[stat(key)][i]))
        self.step += 1
        if bool(nxt[DONE][i]):
            why = "terminated" if bool(nxt[TERMINATED][i]) else "truncated"
            self.texts["events"].append((self.step - 1, f"step {self.step}: episode {why}", "INFO"))
            self.why = why
            self.done = True
            self.flush()

    def _decisions(self, td) -> None:
        """A hierarchical team's high level (``("agents", "drill")``, codes of
        ``scripted.hierarchical.DRILL_LABELS``): each drone's drill as a scalar, and a line whenever
        one changes."""
        if td is None or DRILL not in td.keys(include_nested=True):
            return
        from volleybots.scripted.hierarchical import DRILL_LABELS

        codes = td.get(DRILL)[self.i].reshape(-1).tolist()
        last = self._last_drills
        for k, c in enumerate(codes):
            if c == 0:  # a drone no high level drives
                continue
            self.drills.setdefault(k, []).append((self.step, float(c)))
            if last is None or last[k] != c:
                self.texts["decisions"].append((self.step, f"step {self.step}: drone {k} -> {DRILL_LABELS[c]}", "INFO"))
        self._last_drills = codes

    def _events(self, env, ball) -> None:
        hits, infos, faults = step_events(getattr(env, "last_events", None), self.i)
        self.texts["events"] += [(self.step, f"step {self.step}: {m}", "INFO") for m in infos]
        self.texts["events"] += [(self.step, f"step {self.step}: {m}", "INFO") for m in hits]
        self.texts["events"] += [(self.step, f"step {self.step}: {m}", "WARN") for m in faults]
        if hits:
            self.marks["world/hits"].append((self.step, ball))
        if faults:
            self.marks["world/violations"].append((self.step, ball))

    # ----------------------------------------------------------------------------- the columns
    def episode(self) -> Episode:
        """What was kept so far, as arrays (the still's input)."""
        return Episode(
            teams=self.teams, court=self.court, pos=np.stack(self.pos), quat=np.stack(self.quat), ball=np.stack(self.ball),
            hits=[s for s, _ in self.marks["world/hits"]], faults=[s for s, _ in self.marks["world/violations"]],
            stats={k: v[-1] for k, v in self.stats.items()},
        )

    def _send(self, path: str, steps, columns) -> None:
        import rerun as rr

        self.rec.send_columns(self._p(path), indexes=[rr.TimeColumn("step", sequence=np.asarray(steps, dtype=np.int64))], columns=columns)

    def flush(self) -> None:
        """Send what was kept as columns, with the layout and the summary; once (later calls do nothing)."""
        import rerun as rr

        from volleybots.replay.layout import episode_blueprint

        if self.sent or not self.pos:
            return
        self.sent = True
        steps = np.arange(len(self.pos))
        pos, quat = np.stack(self.pos), np.stack(self.quat)
        for k in range(pos.shape[1]):
            xyzw = quat[:, k][:, [1, 2, 3, 0]]
            self._send(f"world/drone_{k}", steps, rr.Transform3D.columns(translation=pos[:, k], quaternion=xyzw))
        self._send("world/ball", steps, rr.Points3D.columns(positions=np.stack(self.ball)))
        self.rec.log(self._p("world/ball"), rr.Points3D.from_fields(radii=[self.env.params.ball.radius], colors=[BALL_COLOUR]), static=True)
        self.rec.log(self._p("world/ball_trail"), rr.LineStrips3D.from_fields(colors=[BALL_COLOUR]), static=True)
        self._send("world/ball_trail", steps[1:], rr.LineStrips3D.columns(strips=self.strips[1:]))
        for path, marks in self.marks.items():
            if marks:
                colour, radius = (HIT_COLOUR, 0.15) if path == "world/hits" else (FAULT_COLOUR, 0.2)
                self.rec.log(self._p(path), rr.Points3D.from_fields(radii=[radius], colors=[colour]), static=True)
                self._send(path, [s for s, _ in marks], rr.Points3D.columns(positions=np.stack([b for _, b in marks])))
        rewards = np.stack(self.rewards)
        for k in range(rewards.shape[1]):
            self._send(f"reward/drone_{k}", steps, rr.Scalars.columns(scalars=rewards[:, k]))
        for key, values in self.stats.items():
            self._send(f"episode/{key}", steps, rr.Scalars.columns(scalars=np.asarray(values)))
        for k, pairs in self.drills.items():
            self._send(f"drill/drone_{k}", [s for s, _ in pairs], rr.Scalars.columns(scalars=[c for _, c in pairs]))
        for path, lines in self.texts.items():
            if lines:
                columns = rr.TextLog.columns(text=[t for _, t, _ in lines], level=[lv for _, _, lv in lines])
                self._send(path, [s for s, _, _ in lines], columns)
        two_teams = len(set(self.teams)) > 1
        if two_teams:
            self._score(steps)
        self.rec.log(self._p("summary"), rr.TextDocument(self.summary(), media_type="text/markdown"), static=True)
        self.rec.send_blueprint(episode_blueprint(self.teams, list(self.stats), bool(self.drills), self.prefix))

    def _score(self, steps) -> None:
        """A match's touches per team over the rally and its point (1 to the winner at the last step)."""
        import rerun as rr

        winner = int(self.stats.get("winner", [-1])[-1])
        for t in (0, 1):
            touches = self.stats.get(f"hits_team{t}")
            if touches is not None:
                self._send(f"score/touches_team{t}", steps, rr.Scalars.columns(scalars=np.asarray(touches)))
            points = np.zeros(len(steps))
            points[-1] = float(self.done and winner == t)
            self._send(f"score/points_team{t}", steps, rr.Scalars.columns(scalars=points))

    def summary(self) -> str:
        """The episode in a few markdown lines: how it ended, the score and fault of a match, the figures."""
        from volleybots.rules import Referee

        last = {k: v[-1] for k, v in self.stats.items()}
        env = self.env
        lines = [f"## {type(env).__name__}: {len(self.teams)} drone{'s' if len(self.teams) > 1 else ''}", ""]
        state = f"ended ({self.why})" if self.done else "still running when the recording stopped"
        lines.append(f"- after **{self.step}** control steps the episode {state}")
        if len(set(self.teams)) > 1 and "winner" in last:
            names = [f"{self.labels[t]} ({TEAM_NAMES[t]})" if self.labels else f"team {t} ({TEAM_NAMES[t]})" for t in (0, 1)]
            winner, reason = int(last["winner"]), int(last.get("reason", -1))
            if winner < 0:
                lines.append(f"- **no point**: a draw; score {names[0]} 0 - 0 {names[1]}")
            else:
                fault = Referee.FAULTS[reason] if 0 <= reason < len(Referee.FAULTS) else "unknown"
                lines.append(f"- **point to {names[winner]}**: {names[1 - winner]} faulted (**{fault}**)")
                lines.append(f"- score {names[0]} **{int(winner == 0)} - {int(winner == 1)}** {names[1]}")
            lines.append(f"- touches: {names[0]} {last.get('hits_team0', 0):.0f}, {names[1]} {last.get('hits_team1', 0):.0f}")
        faults = [t for _, t, lv in self.texts["events"] if lv == "WARN"]
        lines.append(f"- ending fault: {faults[-1].split(': ', 1)[1]}" if faults else "- no fault called")
        metric = getattr(env, "metric", None)
        for key in dict.fromkeys([metric, "return", "episode_len"]):
            if key in last:
                lines.append(f"- {key}: {last[key]:.4g}")
        return "\n".join(lines)


class MatchLog:
    """Beside ``EpisodeRecorder`` in a match: who plays which colour, the touches per team as they
    change, and at the end the point (winner) with the fault that ended the rally. A handful of lines
    a rally, so they are logged as they happen; the recorder sends the dense score columns."""

    def __init__(self, rec, env, labels: tuple[str, str], env_index: int = 0):
        import rerun as rr

        self.rec, self.i, self.labels = rec, env_index, labels
        self.names = [f"{labels[t]} ({TEAM_NAMES[t]}, team {t}, {'+x' if t == 0 else '-x'})" for t in (0, 1)]
        self.done = False
        self.hits = [0, 0]
        self.step = 0
        rec.log("match", rr.TextLog(f"{self.names[0]} against {self.names[1]}", level="INFO"), static=True)

    def __call__(self, env, td, nxt) -> None:
        import rerun as rr

        if self.done:
            return
        from volleybots.rules import Referee

        i = self.i
        # the recorder's columns carry their own steps, these lines take the stream's time (a stand-in
        # stream without timelines takes them untimed)
        if hasattr(self.rec, "set_time"):
            self.rec.set_time("step", sequence=self.step)
        self.step += 1
        hits = [int(nxt[stat(f"hits_team{t}")][i]) for t in (0, 1)]
        if hits != self.hits:
            self.hits = hits
            self.rec.log("match", rr.TextLog(f"touches: {self.labels[0]} {hits[0]}, {self.labels[1]} {hits[1]}", level="INFO"))
        if bool(nxt[DONE][i]):
            self.done = True
            winner, reason = int(nxt[stat("winner")][i]), int(nxt[stat("reason")][i])
            if winner < 0:
                msg = "no point: a draw (crash, teammates too close, a double fault or the time limit)"
            else:
                msg = (
                    f"point to {self.names[winner]}: {self.labels[1 - winner]} faulted ({Referee.FAULTS[reason]}); "
                    f"score {self.labels[0]} {int(winner == 0)} - {int(winner == 1)} {self.labels[1]}"
                )
            self.rec.log("match", rr.TextLog(msg, level="WARN" if winner < 0 else "INFO"))
