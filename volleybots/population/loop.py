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
import time
from contextlib import contextmanager
from pathlib import Path

import torch

from volleybots.algos.population import ZOO, ZOO_STARTS, population_of
from volleybots.config import to_dict, validate
from volleybots.config.spelling import respell
from volleybots.errors import ConfigError
from volleybots.files import sha256, write_atomic
from volleybots.play.pool import payoff_row
from volleybots.play.seats import SelfPlay, Versus
from volleybots.policies import BUILTIN, Competitor, checkpoint_member, member_path, population_members, resolve_competitor, single_policy
from volleybots.policies.store import policy_checkpoint
from volleybots.population.clone import CLONE, clone_member, make_clone, needs_clone
from volleybots.population.convergence import Convergence
from volleybots.population.final import evaluate_mixture, log_final_eval
from volleybots.population.hierarchical import seed_member
from volleybots.population.opponents import member_label, oracle_opponent, population_competitor
from volleybots.population.oracle import BestResponse, HighLevelResponse, Presentation, Start
from volleybots.population.stage_one import TRAIN, drills_spec, train_drills
from volleybots.ratings.payoffs import PayoffTable, payoff_reserve, plot
from volleybots.ratings.solvers import SOLVERS
from volleybots.replay import write_curves
from volleybots.runs import CKPT_FORMAT, POPULATION_DIR, RunDir, check_writable, locked, read_checkpoint, read_metas, read_population
from volleybots.train import RESUME_KEYS as TRAIN_RESUME_KEYS
from volleybots.train import resume_config, write_summary
from volleybots.train.progress import hms, note
from volleybots.train.wandb import WandbLogger

# the learner keys that shape its networks: a learner fine-tuned from the zoo start takes that policy's
NETWORK_KEYS = ("hidden", "activation", "obs_norm", "value_norm", "centralised_critic", "init_log_std")
ITERATION_SEED = 1_000  # iteration i runs with seed + i * ITERATION_SEED
GAMES_SEED = 500_000  # payoff games of member k against j use seed + GAMES_SEED + 1000 k + j
SPLIT = ("clone", "drills", "oracle_training", "payoff_games", "evaluations")  # the parts of a run's wall time it reports


def hierarchical(m) -> bool:
    """Whether the population node ``m`` has hierarchical members (saved configs before population.members: flat)."""
    return m.get("members", "flat") == "hierarchical"


class PopulationLoop:
    """Grows the population of ``cfg`` in ``run``; ``oracle`` trains each best response (default: the
    learner ``algo=`` names, ``BestResponse.of(cfg)``; hierarchical members: ``HighLevelResponse``)."""

    def __init__(self, cfg, run: RunDir, oracle=None):
        self.cfg, self.run, self.m = cfg, run, population_of(cfg)  # the loop's keys (population.*)
        self.dir = run.path / POPULATION_DIR
        self.meta_path = self.dir / "meta.jsonl"
        self.payoffs_path = self.dir / "payoffs.json"
        self.wandb = None
        self.dropped: dict | None = None  # the oracle the budget cut before min_updates, if one was
        self.hierarchical = hierarchical(self.m)
        self.oracle = oracle or (HighLevelResponse(cfg) if self.hierarchical else BestResponse.of(cfg))

    # ---------------------------------------------------------------------------- disk state
    def metas(self) -> list[dict]:
        return read_metas(self.run.path)

    def _append_meta(self, line: dict) -> None:
        write_atomic(self.meta_path, "".join(json.dumps(m) + "\n" for m in [*self.metas(), line]))

    def _save_member(self, k: int, state: dict) -> None:
        write_atomic(member_path(self.run.path, k), lambda f: torch.save(state, f), "a population member")

    # ---------------------------------------------------------------------------- the loop
    def fit(self) -> dict:
        self.dir.mkdir(parents=True, exist_ok=True)
        t0 = time.perf_counter()
        metas = self.metas()
        wall0 = metas[-1]["wall_time"] if metas else 0.0
        self._wall = wall = lambda: wall0 + time.perf_counter() - t0  # noqa: E731
        # where the wall time goes, summed over the run (a resumed run continues its last record)
        done = (metas[-1].get("wall_time_split") or {}) if metas else {}
        self.split = {k: float(done.get(k, 0.0)) for k in SPLIT}
        if self.cfg.logger == "wandb":  # one W&B run over all iterations, continued by a resume
            self.wandb = WandbLogger(self.cfg, self.run.path, resume=bool(metas or self.run.periodic_checkpoints()))
        seeds = list(self.m.seed_members)
        self.clone = None
        if needs_clone(self.m):
            with self._timed("clone"):  # once per run, then reused (a resume finds it made)
                self.clone = make_clone(self.cfg, self.run.path)
        if self.hierarchical and self.m.drills == TRAIN:
            with self._timed("drills"):  # stage I, once per run (a resume finds the team file made)
                train_drills(self.cfg, self.run.path, note(self.cfg.progress))
        if seeds and not self.metas():
            with self._timed("payoff_games"):
                self._seed_population(seeds)
            self._solve_and_record(0, frames=0, updates=0, wall=wall(), oracle=None)
        while True:
            metas = self.metas()
            i = 1 + sum(1 for m in metas if m["iteration"] >= 1)
            frames = metas[-1]["frames"] if metas else 0
            updates = metas[-1]["updates"] if metas else 0
            k = len(seeds) + i - 1
            # the new member's payoff games must end by the time limit too, so its oracle stops that much earlier
            out_of_time = self.cfg.time_limit and wall() + self._reserve(k) >= self.cfg.time_limit
            spent = frames >= self.cfg.total_frames and not self.hierarchical  # a hierarchical run's budget is its games
            if i > self.m.iterations or spent or out_of_time or self._planned(i, frames) < i:
                break
            if not member_path(self.run.path, k).is_file():
                with self._timed("oracle_training"):
                    evals = self._oracle(i, k, frames, updates, wall())
                self.split["oracle_training"] -= evals  # the oracle's periodic evaluations are counted apart
                self.split["evaluations"] += evals
                if not member_path(self.run.path, k).is_file():  # cut short and dropped: the run ends here
                    break
            member = read_checkpoint(member_path(self.run.path, k))
            with self._timed("payoff_games"):
                self._play_payoffs()
            self._solve_and_record(i, int(member["frames"]), int(member["iteration"]), wall(), member["oracle"])
        return self._finish()

    @contextmanager
    def _timed(self, part: str):
        t = time.perf_counter()
        try:
            yield
        finally:
            self.split[part] += time.perf_counter() - t

    def _seed_population(self, seeds: list[str]) -> None:
        """Members 0..s-1: built-in players as records, trained policies as copies of their checkpoint
        (so the run dir holds everything an evaluation needs)."""
        for k, spec in enumerate(seeds):
            path = member_path(self.run.path, k)
            if path.is_file():
                continue
            if str(spec) == CLONE:
                clone_member(self.clone, path)
                continue
            spec = drills_spec(self.run.path, spec)  # train: the drills stage I made
            src = single_policy(spec, "population.seed_members entry").members[0].source
            if src["kind"] == "hierarchical" and self.hierarchical:  # its files copied: the run dir holds its members
                self._save_member(k, seed_member(self.run.path, spec, k))
            elif src["kind"] in BUILTIN:  # a record naming it (a hierarchical team also its drills' checkpoints)
                record = {"format": CKPT_FORMAT, "builtin": src["kind"], "label": src["kind"], "frames": 0}
                if src.get("drills"):
                    record["drills"] = dict(src["drills"])
                self._save_member(k, record)
            else:
                write_atomic(path, Path(src["path"]).read_bytes(), "a population member")
        self._play_payoffs()

    def _play_payoffs(self) -> None:
        """Add a row and column to the payoff table for every member it lacks, from games played."""
        table = PayoffTable.load(self.payoffs_path)
        paths = population_members(self.run.path)
        for k in range(len(table), len(paths)):
            new = Competitor("new", [checkpoint_member(paths[k])])
            olds = [Competitor("old", [checkpoint_member(paths[j])]) for j in range(k)]
            seed = self.cfg.seed + GAMES_SEED + 1000 * k
            results = payoff_row(self.cfg, new, olds, self.m.payoff_games, seed, self.m.payoff_pool)
            table.add_member(member_label(paths[k]), results)
            table.save(self.payoffs_path)

    def _solve_and_record(self, i: int, frames: int, updates: int, wall: float, oracle: dict | None) -> None:
        table = PayoffTable.load(self.payoffs_path)
        mixture = SOLVERS[self.m.solver](table.matrix())
        # each member's sha256, recorded when it joins and carried on: a member file replaced later (by
        # another run's policy under the same label) is refused where the population is read
        metas = self.metas()
        known = list((metas[-1].get("sha256") or []) if metas else [])[: len(table)]
        known += [sha256(member_path(self.run.path, k)) for k in range(len(known), len(table))]
        self._append_meta({
            "iteration": i, "members": table.labels, "sha256": known, "solver": self.m.solver, "mixture": [float(x) for x in mixture],
            "frames": frames, "updates": updates, "wall_time": wall, "oracle": oracle, "wall_time_split": dict(self.split),
        })
        plot(table, mixture, self.run.path / "payoffs.png", f"{self.m.name} on {self.cfg.task.name}: iteration {i}")

    # ---------------------------------------------------------------------------- the oracle
    def _iteration_cfg(self, i: int, frames: int, reserve: float = 0.0):
        """The config iteration ``i`` trains with: its own seed, a budget of ``max_updates`` batches (SP:
        the run's whole budget), ``init=`` the clone for ``learner_init=bc``, the fine-tuning recipe
        (``actor_freeze_updates``, ``anchor_coeff``) only for a learner that starts from a policy, and
        a time limit ``reserve`` seconds before the run's (its payoff games come after it)."""
        data = to_dict(self.cfg)
        data["seed"] = self.cfg.seed + i * ITERATION_SEED
        if self.cfg.time_limit and reserve:
            data["time_limit"] = self.cfg.time_limit - reserve
        if hierarchical(self.m):  # a high level's oracle takes its seed and time limit alone (HighLevelResponse)
            return validate(data)
        if self.m.learner_init == CLONE:
            data["init"] = str(self.clone)
        elif self.m.learner_init == ZOO:  # every learner fine-tuned from the task's zoo start, in its networks' shape
            data["init"] = ZOO_STARTS[self.cfg.task.name]
            saved = read_checkpoint(policy_checkpoint(data["init"], "population.start=zoo")).get("config", {}).get("algo", {})
            data["algo"].update({k: saved[k] for k in NETWORK_KEYS if k in saved})
        elif data.get("init") is None:  # a learner from scratch has no policy to warm up for or hold to
            data["algo"].update(actor_freeze_updates=0, anchor_coeff=0.0)
        if not self.m.self_play:
            per_batch = self.cfg.env.num_envs * self.cfg.algo.steps_per_batch
            data["total_frames"] = min(self.cfg.total_frames, frames + self.m.max_updates * per_batch)
        return validate(data)

    def _planned(self, i: int, frames: int) -> int:
        """The iterations the run will have trained once the frames left are spent, counting from
        iteration ``i`` about to start with ``frames`` spent: every oracle may take ``max_updates``
        batches, and one that the frames left cannot give ``min_updates`` is not started (the
        criterion could not judge it, so it would not join). Self-play: its one iteration."""
        if self.m.self_play or self.hierarchical:
            return self.m.iterations
        per_batch = self.cfg.env.num_envs * self.cfg.algo.steps_per_batch
        full, rest = divmod(max(self.cfg.total_frames - frames, 0), self.m.max_updates * per_batch)
        return min(self.m.iterations, i - 1 + full + (rest >= self.m.min_updates * per_batch))

    def _reserve(self, k: int) -> float:
        """Seconds member ``k``'s payoff games will take (0 without a time limit to keep)."""
        return payoff_reserve(self.split["payoff_games"], k) if self.cfg.time_limit else 0.0

    def _oracle(self, i: int, k: int, frames: int, updates: int, wall: float) -> float:
        """Train iteration ``i``'s response as member ``k`` through the oracle (resuming its checkpoint if one
        exists), early enough for its payoff games to end by the time limit; returns its periodic
        evaluations' seconds. The loop chooses the opponent (``population/opponents.py``), the stop rule
        and the start; the oracle trains."""
        m = self.m
        cfg = self._iteration_cfg(i, frames, self._reserve(k))
        yardstick = resolve_competitor(m.eval_opponent)
        if m.self_play:  # one learner on both teams for the whole budget: no frozen opponent, no stop rule
            seat, stop = SelfPlay(yardstick), None
        else:
            opponent = oracle_opponent(self.run.path, self.metas()[-1]["mixture"], m)
            seat = Versus(opponent, m.opponent_deterministic, cfg.seed, yardstick)
            stop = Convergence(m.min_updates, m.max_updates, m.win_window, m.win_mean, m.win_std)
        members = tuple(population_members(self.run.path)[:k])
        start = Start(frames, updates, wall, members, warm=m.learner_init == "last", resume=self._checkpoint_of(i), iteration=i)
        show = Presentation(self.wandb, self._note(i, stop), {"pop_iteration": i})
        member = self.oracle(cfg, self.run, seat, stop, start, "sp" if m.self_play else f"br{i}", show)
        if member.kept:
            self._save_member(k, member.state)
        else:
            # the run's budget ended the oracle before the criterion could judge it: a policy a few updates
            # from its start is no response to the mixture, so it does not join; its last periodic
            # checkpoint (if one was written) lets a resume with more budget carry it on
            self.dropped = {"iteration": i, "updates": stop.updates, "frames": int(member.state["frames"]) - frames}
        return member.eval_wall

    def _note(self, i: int, stop):
        """The progress line's note: the iteration, the oracle's updates and the whole run's ETA (the
        frames left at the oracle's rate; payoff games and evaluations come on top)."""
        cfg = self.cfg
        planned = self._planned(i, self.metas()[-1]["frames"] if self.metas() else 0)

        def note(frames: int, fps: float) -> str:
            upd = f", oracle update {stop.updates}/{self.m.max_updates}" if stop is not None else ""
            left = (cfg.total_frames - frames) / max(fps, 1e-9)
            if cfg.time_limit:
                left = min(left, cfg.time_limit - self._wall())
            return f"iteration {i}/{planned}{upd}, run ETA {hms(left)}"

        return note

    def _checkpoint_of(self, i: int) -> Path | None:
        """The newest periodic checkpoint written during iteration ``i`` (None: it starts afresh)."""
        for path in reversed(self.run.periodic_checkpoints()):
            pop = read_checkpoint(path).get("population") or {}
            if pop.get("iteration") == i:
                return path
        return None

    # ---------------------------------------------------------------------------- the end
    def _finish(self) -> dict:
        metas = self.metas()
        last = metas[-1] if metas else {}
        paths = population_members(self.run.path)
        learned = [p for p in paths if "algo" in read_checkpoint(p)]
        if learned:
            self.run.ckpt_dir.mkdir(exist_ok=True)
            write_atomic(self.run.final_path, learned[-1].read_bytes(), "the final checkpoint")
        frames = int(last.get("frames", 0))
        final_eval = None
        if last.get("mixture"):
            with self._timed("evaluations"):
                final_eval = evaluate_mixture(self.cfg, population_competitor(self.run.path, last["mixture"]), self.m.eval_opponent)
            log_final_eval(self.run, final_eval, frames, int(last.get("updates", 0)), self._wall())
        if self.run.metrics_path.is_file():
            write_curves(self.run.metrics_path, self.run.curves_path)
        wall = self._wall()
        split = {**{k: round(v, 3) for k, v in self.split.items()}, "other": round(max(wall - sum(self.split.values()), 0.0), 3)}
        extra = {
            "wall_time_split": split,  # seconds; other: solving, plots, files, and time lost to a kill before a resume
            "population": {"members": last.get("members", []), "mixture": last.get("mixture", []), "solver": self.m.solver},
            "oracles": [m["oracle"] for m in metas if m["iteration"] >= 1],
            # an oracle the budget cut before min_updates: its frames were spent, but it is not a member
            **({"dropped_oracle": self.dropped} if self.dropped else {}),
        }
        iterations = sum(1 for m in metas if m["iteration"] >= 1)
        return write_summary(self.run, self.cfg, self.m.name, (frames, iterations, wall), "win", final_eval, extra, self.wandb)


def start(cfg, run_dir) -> dict:
    """A new population run of the validated config ``cfg`` in ``run_dir``."""
    run = RunDir(run_dir)
    with run.new_run(cfg):
        return PopulationLoop(cfg, run).fit()


RESUME_KEYS = (*TRAIN_RESUME_KEYS, "population.iterations", "population.payoff_pool", "population.oracle_pool")  # pools change no result


def resume(run_dir, overrides=(), check=None) -> dict:
    """Continue a population run (``train resume=DIR``, overrides within ``RESUME_KEYS``).

    Everything is checked before anything is written: the config and overrides, that the run dir is
    writable, that its member files and meta-strategies read back, and that something is left to do;
    then the run's lock is taken (a second resume is refused) and the config written."""
    from volleybots.policies.targets import check_references

    run = RunDir(run_dir)
    cfg = resume_config(run_dir, respell(overrides, population=True)[0], RESUME_KEYS)  # algo.iterations= as before
    check_writable(run.path, "the run directory")
    run.check_contained()
    check_references(cfg)
    if check is not None:
        check(cfg)
    loop = PopulationLoop(cfg, run)
    metas = loop.metas()  # a damaged meta.jsonl line is one line naming it
    if metas:  # every member meta.jsonl lists is there and reads back; a member written after it is completed below
        read_population(run.path, f"run {str(run_dir)!r}", quiet=True)
    for path in population_members(run.path):
        read_checkpoint(path)  # a damaged member is one line naming it
    PayoffTable.load(loop.payoffs_path)  # as are a damaged payoffs.json and metrics.csv: before any file changes
    run.check_metrics()
    done = sum(1 for m in metas if m["iteration"] >= 1)
    frames = metas[-1]["frames"] if metas else 0
    if cfg.population.self_play and done >= 1:
        raise ConfigError(
            f"run {str(run_dir)!r} has finished: self-play trains one learner for the run's whole budget ({frames} frames), and its "
            f"member is final; neither total_frames nor population.iterations continues it. Start a new run from its policy: "
            f"volleybots train task={cfg.task.name} population=sp init={run_dir} total_frames=N"
        )
    iterations = cfg.population.iterations
    if done >= iterations or frames >= cfg.total_frames:
        raise ConfigError(
            f"run {str(run_dir)!r} has finished ({done} iteration(s), {frames} frames); raise "
            + " and ".join(x for x, spent in ((f"population.iterations (now {iterations})", done >= iterations),
                                              (f"total_frames (now {cfg.total_frames})", frames >= cfg.total_frames)) if spent)
            + " to continue it"
        )
    with locked(run.path):
        run.write_config(cfg)
        return loop.fit()
