"""The population loop: SP, FSP, PSRO-uniform and PSRO-Nash (OpenSpiel's psro_v2 shape).

Each iteration: the oracle trains a learner against the population's meta-strategy (an opponent
member drawn per episode) until its win rate converges or its update budget is spent; the learner
joins the population; the payoff table gains its row and column from games played; the meta-solver
recomputes the mixture. The methods differ only in the solver, the learner's start (FSP: the newest
learned member; PSRO: scratch) and SP's degenerate case: one learner playing both teams for the whole
budget, no frozen members.

Run dir (beside the usual config.yaml, metrics.csv, checkpoints/, summary.json)::

    population/member_<k>.pt   member k: a checkpoint (weights_only), or a record naming random/scripted
    population/payoffs.json    W/D/L and game counts per ordered pair, the zero-sum payoff matrix
    population/meta.jsonl      per iteration: the mixture, the oracle's updates / win rates, frames
    payoffs.png                the payoff matrix beside the final mixture

Determinism and resume: iteration ``i`` starts from a state that depends only on the seed, ``i`` and
what is on disk (its env, networks and samplers are seeded from ``seed`` and ``i``; FSP's learner is
loaded from a member file), its periodic checkpoints restore the rest, and games draw from their own
seeds. A run killed anywhere resumes (``train resume=DIR``) with the iteration in progress and ends
with the same population as an uninterrupted one on a CPU. Member files and payoff entries already
written are never rewritten.
"""

from __future__ import annotations

import json
import math
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import torch

from volleybots.algos.ppo import MAPPO
from volleybots.config import to_dict, validate
from volleybots.errors import ConfigError
from volleybots.play.pool import head_to_heads
from volleybots.play.seats import SelfPlay, Versus
from volleybots.files import write_atomic
from volleybots.policies import BUILTIN, Competitor, checkpoint_member, member_path, population_members, resolve_competitor
from volleybots.population.payoffs import PayoffTable, plot
from volleybots.population.solvers import SOLVERS
from volleybots.runs import CKPT_FORMAT, POPULATION_DIR, RunDir, check_writable, locked, read_checkpoint, read_metas, read_population
from volleybots.train import RESUME_KEYS as TRAIN_RESUME_KEYS
from volleybots.train import Trainer, resume_config
from volleybots.version import __version__

ITERATION_SEED = 1_000  # iteration i runs with seed + i * ITERATION_SEED
GAMES_SEED = 500_000  # payoff games of member k against j use seed + GAMES_SEED + 1000 k + j


@dataclass
class Convergence:
    """The oracle's stopping rule: the win rate over the last ``window`` batches has mean >= ``mean``
    and std <= ``std`` after ``min_updates`` updates, or ``max_updates`` updates are done."""

    min_updates: int
    max_updates: int
    window: int
    mean: float
    std: float
    updates: int = 0
    win_rates: list[float] = field(default_factory=list)

    def __call__(self, row: dict) -> bool:
        self.updates += 1
        w = row.get("win", math.nan)
        if w is not None and not math.isnan(w):
            self.win_rates.append(float(w))
        return self.updates >= self.max_updates or (self.updates >= self.min_updates and self.converged)

    @property
    def recent(self) -> np.ndarray:
        return np.asarray(self.win_rates[-self.window:], dtype=float)

    @property
    def converged(self) -> bool:
        r = self.recent
        return len(r) == self.window and r.mean() >= self.mean and r.std() <= self.std

    def summary(self) -> dict:
        r = self.recent
        return {
            "updates": self.updates,
            "converged": bool(self.converged),
            "win_mean": float(r.mean()) if len(r) else None,
            "win_std": float(r.std()) if len(r) else None,
        }

    def state_dict(self) -> dict:
        return {"updates": self.updates, "win_rates": list(self.win_rates)}

    def load_state_dict(self, state: dict) -> None:
        self.updates, self.win_rates = int(state["updates"]), [float(w) for w in state["win_rates"]]


class PopulationLoop:
    def __init__(self, cfg, run: RunDir):
        self.cfg, self.run, self.m = cfg, run, cfg.algo
        self.dir = run.path / POPULATION_DIR
        self.meta_path = self.dir / "meta.jsonl"
        self.payoffs_path = self.dir / "payoffs.json"

    # ---------------------------------------------------------------------------- disk state
    def metas(self) -> list[dict]:
        return read_metas(self.run.path)

    def _append_meta(self, line: dict) -> None:
        write_atomic(self.meta_path, "".join(json.dumps(m) + "\n" for m in [*self.metas(), line]))

    @staticmethod
    def _label(path: Path) -> str:
        state = read_checkpoint(path)
        return state.get("label", path.stem)

    def _save_member(self, k: int, state: dict) -> None:
        write_atomic(member_path(self.run.path, k), lambda f: torch.save(state, f), "a population member")

    # ---------------------------------------------------------------------------- the loop
    def fit(self) -> dict:
        self.dir.mkdir(parents=True, exist_ok=True)
        t0 = time.perf_counter()
        wall0 = self.metas()[-1]["wall_time"] if self.metas() else 0.0
        wall = lambda: wall0 + time.perf_counter() - t0  # noqa: E731
        seeds = list(self.m.seed_members)
        if seeds and not self.metas():
            self._seed_population(seeds)
            self._solve_and_record(0, frames=0, updates=0, wall=wall(), oracle=None)
        while True:
            metas = self.metas()
            i = 1 + sum(1 for m in metas if m["iteration"] >= 1)
            frames = metas[-1]["frames"] if metas else 0
            updates = metas[-1]["updates"] if metas else 0
            if i > self.m.iterations or frames >= self.cfg.total_frames or (self.cfg.time_limit and wall() >= self.cfg.time_limit):
                break
            k = len(seeds) + i - 1
            if not member_path(self.run.path, k).is_file():
                self._oracle(i, k, frames, updates, wall())
            member = read_checkpoint(member_path(self.run.path, k))
            self._play_payoffs()
            self._solve_and_record(i, int(member["frames"]), int(member["iteration"]), wall(), member["oracle"])
        return self._finish(wall())

    def _seed_population(self, seeds: list[str]) -> None:
        """Members 0..s-1: built-in players as records, trained policies as copies of their checkpoint
        (so the run dir holds everything an evaluation needs)."""
        for k, spec in enumerate(seeds):
            path = member_path(self.run.path, k)
            if path.is_file():
                continue
            comp = resolve_competitor(spec)
            if len(comp.members) != 1:
                raise ConfigError(f"algo.seed_members entry {spec!r} is a population; name single policies")
            src = comp.members[0].source
            if src["kind"] in BUILTIN:  # a record naming it (a hierarchical team also its drills' checkpoints)
                record = {"format": CKPT_FORMAT, "builtin": src["kind"], "label": src["kind"], "frames": 0}
                if src.get("drills"):
                    record["drills"] = dict(src["drills"])
                self._save_member(k, record)
            else:
                write_atomic(path, Path(src["path"]).read_bytes(), "a population member")
        self._play_payoffs()

    def _population(self, mixture) -> Competitor:
        """The opponent: the members with positive weight in the mixture (the others are never drawn)."""
        paths = population_members(self.run.path)
        keep = [j for j, w in enumerate(mixture) if w > 0]
        weights = np.asarray([mixture[j] for j in keep], dtype=float)
        return Competitor("population", [checkpoint_member(paths[j], self._label(paths[j])) for j in keep], list(weights / weights.sum()))

    def _play_payoffs(self) -> None:
        """Add a row and column to the payoff table for every member it lacks, from games played."""
        table = PayoffTable.load(self.payoffs_path)
        paths = population_members(self.run.path)
        for k in range(len(table), len(paths)):
            new = checkpoint_member(paths[k])
            seed = self.cfg.seed + GAMES_SEED + 1000 * k
            matches = [(Competitor("new", [new]), Competitor("old", [checkpoint_member(paths[j])]), self.m.payoff_games, seed + j) for j in range(k)]
            results = head_to_heads(self.cfg, matches, self.m.payoff_pool)
            table.add_member(self._label(paths[k]), results)
            table.save(self.payoffs_path)

    def _solve_and_record(self, i: int, frames: int, updates: int, wall: float, oracle: dict | None) -> None:
        table = PayoffTable.load(self.payoffs_path)
        mixture = SOLVERS[self.m.solver](table.matrix())
        self._append_meta({
            "iteration": i, "members": table.labels, "solver": self.m.solver, "mixture": [float(x) for x in mixture],
            "frames": frames, "updates": updates, "wall_time": wall, "oracle": oracle,
        })
        plot(table, mixture, self.run.path / "payoffs.png", f"{self.m.name} on {self.cfg.task.name}: iteration {i}")

    # ---------------------------------------------------------------------------- the oracle
    def _iteration_cfg(self, i: int, frames: int):
        """The config iteration ``i`` trains with: its own seed, and a budget of ``max_updates`` batches
        (SP: the run's whole budget)."""
        data = to_dict(self.cfg)
        data["seed"] = self.cfg.seed + i * ITERATION_SEED
        if not self.m.self_play:
            per_batch = self.cfg.env.num_envs * self.m.steps_per_batch
            data["total_frames"] = min(self.cfg.total_frames, frames + self.m.max_updates * per_batch)
        return validate(data)

    def _oracle(self, i: int, k: int, frames: int, updates: int, wall: float) -> None:
        """Train iteration ``i``'s learner (resuming its checkpoint if one exists) and save it as member ``k``."""
        cfg, m = self._iteration_cfg(i, frames), self.m
        yardstick = resolve_competitor(m.eval_opponent)
        if m.self_play:
            seat = SelfPlay(yardstick)
            stop = None
        else:
            seat = Versus(self._population(self.metas()[-1]["mixture"]), m.opponent_deterministic, cfg.seed, yardstick)
            stop = Convergence(m.min_updates, m.max_updates, m.win_window, m.win_mean, m.win_std)
        extra = lambda: {"population": {"iteration": i, "oracle": stop.state_dict() if stop else None}}  # noqa: E731
        ckpt = self._checkpoint_of(i)
        tr = Trainer(cfg, self.run, checkpoint=ckpt, seat=seat, learner_cls=MAPPO, extra_state=extra)
        if ckpt is not None:
            if stop is not None:
                stop.load_state_dict(tr.checkpoint_state["population"]["oracle"])
        else:
            tr.start_at(frames, updates, wall)
            learned = [p for p in population_members(self.run.path)[: k] if "algo" in read_checkpoint(p)]
            if m.learner_init == "last" and learned:
                tr.algo.load_state_dict(read_checkpoint(learned[-1], device=tr.env.device)["algo"])
        tr.train_loop(stop=stop, row_extra={"pop_iteration": i})
        state = tr.state()
        label = "sp" if m.self_play else f"br{i}"
        state.update(label=label, oracle=(stop.summary() if stop else {"updates": tr.iteration - updates, "converged": None}))
        self._save_member(k, state)

    def _checkpoint_of(self, i: int) -> Path | None:
        """The newest periodic checkpoint written during iteration ``i`` (None: it starts afresh)."""
        for path in reversed(self.run.periodic_checkpoints()):
            pop = read_checkpoint(path).get("population") or {}
            if pop.get("iteration") == i:
                return path
        return None

    # ---------------------------------------------------------------------------- the end
    def _finish(self, wall: float) -> dict:
        metas = self.metas()
        last = metas[-1] if metas else {}
        paths = population_members(self.run.path)
        learned = [p for p in paths if "algo" in read_checkpoint(p)]
        if learned:
            self.run.ckpt_dir.mkdir(exist_ok=True)
            write_atomic(self.run.final_path, learned[-1].read_bytes(), "the final checkpoint")
        frames = int(last.get("frames", 0))
        summary = {
            "task": self.cfg.task.name,
            "algo": self.m.name,
            "action_space": self.cfg.env.action_space,
            "num_envs": self.cfg.env.num_envs,
            "seed": self.cfg.seed,
            "frames": frames,
            "iterations": sum(1 for m in metas if m["iteration"] >= 1),
            "wall_time_s": wall,
            "frames_per_s": frames / max(wall, 1e-9),
            "metric": "win",
            "population": {"members": last.get("members", []), "mixture": last.get("mixture", []), "solver": self.m.solver},
            "oracles": [m["oracle"] for m in metas if m["iteration"] >= 1],
            "version": __version__,
        }
        self.run.write_summary(summary)
        return summary


def start(cfg, run_dir) -> dict:
    """A new population run of the validated config ``cfg`` in ``run_dir``."""
    run = RunDir(run_dir)
    run.create(cfg)
    return PopulationLoop(cfg, run).fit()


RESUME_KEYS = (*TRAIN_RESUME_KEYS, "algo.iterations")  # a population run may also be given more iterations


def resume(run_dir, overrides=()) -> dict:
    """Continue a population run (``train resume=DIR``, overrides within ``RESUME_KEYS``).

    Everything is checked before anything is written: the config and overrides, that the run dir is
    writable, that its member files and meta-strategies read back, and that something is left to do;
    then the run's lock is taken (a second resume is refused) and the config written."""
    from volleybots.policies.targets import check_references

    run = RunDir(run_dir)
    cfg = resume_config(run_dir, overrides, RESUME_KEYS)
    check_writable(run.path, "the run directory")
    check_references(cfg)
    loop = PopulationLoop(cfg, run)
    metas = loop.metas()  # a damaged meta.jsonl line is one line naming it
    if metas:  # every member meta.jsonl lists is there and reads back; a member written after it is completed below
        read_population(run.path, f"run {str(run_dir)!r}", quiet=True)
    for path in population_members(run.path):
        read_checkpoint(path)  # a damaged member is one line naming it
    done = sum(1 for m in metas if m["iteration"] >= 1)
    frames = metas[-1]["frames"] if metas else 0
    if cfg.algo.self_play and done >= 1:
        raise ConfigError(
            f"run {str(run_dir)!r} has finished: self-play trains one learner for the run's whole budget ({frames} frames), and its "
            f"member is final; neither total_frames nor algo.iterations continues it. Start a new run from its policy: "
            f"volleybots train task={cfg.task.name} algo=sp init={run_dir} total_frames=N"
        )
    if done >= cfg.algo.iterations or frames >= cfg.total_frames:
        raise ConfigError(
            f"run {str(run_dir)!r} has finished ({done} iteration(s), {frames} frames); raise "
            + " and ".join(x for x, spent in ((f"algo.iterations (now {cfg.algo.iterations})", done >= cfg.algo.iterations),
                                              (f"total_frames (now {cfg.total_frames})", frames >= cfg.total_frames)) if spent)
            + " to continue it"
        )
    with locked(run.path):
        run.write_config(cfg)
        return loop.fit()
