"""The run loop every algorithm shares: collect, update, log, checkpoint, evaluate.

A batch is ``algo.steps_per_batch`` steps of every env (auto-reset as episodes end), stacked into a
[num_envs, steps] tensordict in TorchRL's layout (``("next", ...)`` holds the observation before any
reset, so a truncated episode's last value can be bootstrapped).

Checkpoints are written at batch boundaries and all envs start fresh episodes right after one (the
cut episodes count as truncated, hence bootstrapped). The run's state is then exactly the networks,
optimiser, normalisers, counters and random generators, and a run resumed from a checkpoint repeats
the uninterrupted one bit for bit on a CPU.

Seats (``volleybots.play.seats``) say whom the learner plays for. The one caller that drives the loop
itself, the best response (``population/oracle.py``, for population oracles and exploitability's
responses), uses its public surface: ``start_at`` (the counters a new iteration continues from),
``train_loop(stop=..., row_extra=...)``, ``state()`` (what a checkpoint holds), ``checkpoint_state``
(what it was restored from) and ``finish``. ``write_summary`` is the one writer of summary.json.

``init=RUN_OR_CHECKPOINT`` starts a new run from another run's networks (``volleybots.train.init``).
"""

from __future__ import annotations

import math
import sys
import time
from pathlib import Path

import torch

from volleybots.config import make_env, to_dict
from volleybots.play.episodes import collect, finished_stats, run_episodes, summarize
from volleybots.play.seats import default_seat
from volleybots.replay import write_curves
from volleybots.runs import CKPT_FORMAT, MetricsLog, RunDir, load_algo_state, read_checkpoint, wall_at
from volleybots.train.init import apply_init
from volleybots.train.progress import Progress
from volleybots.train.wandb import WandbLogger
from volleybots.version import __version__

# keys a resumed run may change: how long it goes on and how it reports, not what it learns
RESUME_KEYS = ("total_frames", "time_limit", "progress", "threads", "logger", "wandb", "checkpoint", "evaluation", "env.device")
EVAL_SEED_OFFSET = 10_000  # periodic evaluations play the same episodes every time, unlike training's


# ------------------------------------------------------------------------------------------ trainer
class Trainer:
    """The run loop over one learner. ``seat`` says whom it plays for (default: every drone);
    ``learner_cls`` overrides the registry's class (a population method's learner); ``extra_state``
    adds the caller's own counters to every checkpoint (the population loop's oracle); ``logger`` is
    the caller's W&B run (which the caller ends), else the trainer opens its own with ``logger=wandb``;
    ``label`` starts its progress lines."""

    def __init__(self, cfg, run: RunDir, checkpoint: Path | None = None, seat=None, learner_cls=None, extra_state=None, logger=None,
                 label: str = "train"):
        from volleybots.algos import ALGOS

        self.cfg, self.run = cfg, run
        self.label = label  # what its progress lines start with (a population's clone says "clone")
        self.wandb, self._owns_wandb = logger, logger is None
        torch.manual_seed(cfg.seed)
        self.seat = seat or default_seat(cfg)
        self.extra_state = extra_state or (lambda: {})
        self.env = make_env(cfg)
        algo_cls = learner_cls or ALGOS[cfg.algo.name]
        spec = self.seat.spec(self.env)
        self.algo = algo_cls(cfg.algo, spec, seed=cfg.seed)
        if hasattr(self.algo, "attach"):
            self.algo.attach(self.env)  # an algorithm that acts with the env itself (bc's scripted teacher)
        self.frames = self.iteration = 0
        self.wall_offset = 0.0
        self.evals: list[dict] = []
        self.checkpoint_state: dict = {}
        self.init_info: dict | None = None
        if checkpoint is not None:
            self.checkpoint_state = read_checkpoint(checkpoint, device=self.env.device)
            self._restore(self.checkpoint_state)
        elif cfg.get("init") is not None:
            self.init_info = apply_init(self.algo, cfg, spec)
        self.frames_per_batch = self.env.num_envs * self.algo.steps_per_batch
        self.metric = self.env.metric
        self._eval_env = None
        self.eval_wall = 0.0  # seconds spent in evaluations (a population run's wall-time split counts them apart)

    # ---------------------------------------------------------------------- checkpoint state
    def _rng_state(self) -> dict:
        state = {"torch": torch.get_rng_state()}
        if getattr(self.env, "rng", None) is not None:
            state["env"] = self.env.rng.get_state()
        if torch.cuda.is_available():
            state["cuda"] = torch.cuda.get_rng_state_all()
        return state

    def state(self) -> dict:
        """Everything a checkpoint holds: a run restored from it repeats the uninterrupted one. Nothing of
        the machine's: no wall time (metrics.csv and summary.json hold it) and the paths inside the run
        written relative to it, so two identical runs in two folders write files of equal bytes."""
        return {
            "format": CKPT_FORMAT,
            "version": __version__,
            "config": _inside(to_dict(self.cfg), self.run.path),
            "task": self.cfg.task.name,
            "action_space": self.cfg.env.action_space,
            "obs_dim": int(self.env.obs_dim),
            "n_agents": int(self.algo.n_agents),
            "frames": int(self.frames),
            "iteration": int(self.iteration),
            "evals": self.evals,
            "algo": self.algo.state_dict(),
            "rng": self._rng_state(),
            "seat": self.seat.state_dict(),
            "init": _inside(self.init_info, self.run.path),
            **self.extra_state(),
        }

    def _restore(self, state: dict) -> None:
        load_algo_state(self.algo, state, f"the checkpoint of run {str(self.run.path)!r}", self.cfg)
        self.frames, self.iteration = int(state["frames"]), int(state["iteration"])
        # older checkpoints hold their wall time; newer ones leave it to the run's metrics.csv
        self.wall_offset = float(state["wall_time"]) if "wall_time" in state else wall_at(self.run.metrics_path, self.frames)
        self.evals = list(state.get("evals", []))
        self.init_info = state.get("init")
        rng = state["rng"]
        torch.set_rng_state(rng["torch"])
        if "env" in rng:
            self.env.rng.set_state(rng["env"])
        if "cuda" in rng and torch.cuda.is_available():
            torch.cuda.set_rng_state_all(rng["cuda"])
        self.seat.load_state_dict(state.get("seat", {}))

    def start_at(self, frames: int, iteration: int, wall_time: float) -> None:
        """Continue the counters of an earlier stage (a population's next oracle starts where the
        previous one stopped, so metrics.csv and the frame budget run on across iterations)."""
        self.frames, self.iteration, self.wall_offset = int(frames), int(iteration), float(wall_time)

    def _wall(self) -> float:
        return self.wall_offset + time.perf_counter() - self._t0

    # ---------------------------------------------------------------------------- evaluation
    def evaluate(self) -> dict:
        cfg = self.cfg
        if self._eval_env is None:
            self._eval_env = make_env(cfg, num_envs=cfg.evaluation.episodes, seed=cfg.seed + EVAL_SEED_OFFSET)
        env = self._eval_env
        env.set_seed(cfg.seed + EVAL_SEED_OFFSET)
        policy = self.seat.eval_policy(env, self.algo.policy(deterministic=True))
        # its own random numbers (a random yardstick's): training's stream is left as it was, so a
        # resumed run, which skips the evaluation at its checkpoint, repeats the uninterrupted one
        with torch.random.fork_rng(devices=[]):
            torch.manual_seed(cfg.seed + EVAL_SEED_OFFSET)
            if cfg.evaluation.record:
                from volleybots.replay import EpisodeRecorder, recording

                with recording(self.run.path / f"eval_{self.frames:012d}.rrd", "volleybots_eval") as rec:
                    res = run_episodes(env, policy, on_step=EpisodeRecorder(rec, env, 0))
            else:
                res = run_episodes(env, policy)
        summary = summarize(res, self.metric)
        summary["frames"] = int(self.frames)
        self.evals.append(summary)
        return summary

    # -------------------------------------------------------------------------------- the loop
    def fit(self, stop=None) -> dict:
        """Train to ``total_frames`` (or until ``stop(row)`` says so, as in ``train_loop``), then evaluate,
        write final.pt and summary.json (with ``stop.summary()`` as ``stop`` where the stop has one)."""
        self.train_loop(stop=stop)
        summary = getattr(stop, "summary", None)
        return self.finish({"stop": summary()} if summary else None)

    def train_loop(self, stop=None, row_extra=None, note=None) -> None:
        """Collect and update until ``total_frames`` (or ``time_limit``), or until ``stop(row)`` says so
        after a batch; ``row_extra`` adds columns to every metrics row; ``note(frames, fps)`` adds the
        caller's words to the progress line.

        ``time_limit`` is kept by not starting a batch that would end past it, judged by the last
        batch's duration (batches of a minute or more would otherwise overshoot by one)."""
        cfg, run = self.cfg, self.run
        resumed = self.frames > 0
        self.metrics = MetricsLog(run.metrics_path, keep_until_frames=self.frames if resumed else None)
        if self.wandb is None and cfg.logger == "wandb":
            self.wandb = WandbLogger(cfg, run.path, resumed)
        wandb = self.wandb
        self._t0 = time.perf_counter()
        policy = self.seat.policy(self.env, self.algo.policy())
        td = self.env.reset()
        ck_every, ev_every = cfg.checkpoint.every, cfg.evaluation.every
        next_ck = _next_multiple(self.frames, ck_every)
        next_ev = _next_multiple(self.frames, ev_every)
        last: dict = {}
        last_dt = 0.0
        # the loop trains whole batches: the frames it reaches, so that the counter ends at 100 %, not past it
        planned = self.frames + -(-(cfg.total_frames - self.frames) // self.frames_per_batch) * self.frames_per_batch
        with Progress(cfg.progress, max(planned, self.frames), self.frames, cfg.time_limit, label=self.label) as bar:
            while self.frames < cfg.total_frames and not (cfg.time_limit and self._wall() + last_dt > cfg.time_limit):
                t_batch = time.perf_counter()
                batch, td = collect(self.env, policy, td, self.algo.steps_per_batch)
                self.frames += self.frames_per_batch
                self.iteration += 1
                stats = finished_stats(batch, self.seat.team)
                losses = self.algo.update(self.seat.view(self.env, batch))
                dt = last_dt = time.perf_counter() - t_batch  # also the next batch's estimate for time_limit
                row = {
                    "phase": "train", "frames": self.frames, "iteration": self.iteration, "wall_time": self._wall(),
                    "fps": self.frames_per_batch / dt,
                }
                row.update(row_extra or {})
                row.update(stats)
                row.update(losses)
                row.update({f"eval_{self.metric}": None, f"eval_{self.metric}_std": None, "eval_return": None})
                self.metrics.write(row)
                if wandb:
                    wandb.log(row)
                if not math.isnan(stats.get(self.metric, math.nan)):
                    last = stats
                # the caller's counters see this batch before a checkpoint records them
                stopping = stop is not None and stop(row)
                extra = note(self.frames, row["fps"]) if note else ""
                bar(self.frames, row["fps"], self.metric, last.get(self.metric), row["wall_time"], extra)
                if stopping:
                    break
                if ck_every and self.frames >= next_ck and self.frames < cfg.total_frames:
                    run.save_checkpoint(self.state(), keep=cfg.checkpoint.keep)
                    td = self.env.reset()  # see the module docstring: a checkpoint is a clean cut
                    next_ck = _next_multiple(self.frames, ck_every)
                    write_curves(run.metrics_path, run.curves_path)
                if ev_every and self.frames >= next_ev and self.frames < cfg.total_frames:
                    self._evaluate_and_log(wandb)
                    next_ev = _next_multiple(self.frames, ev_every)
        self.last_train = last

    def finish(self, summary_extra=None) -> dict:
        """The final evaluation, final.pt and summary.json (what ``fit`` ends with)."""
        cfg, run, wandb = self.cfg, self.run, self.wandb
        last = getattr(self, "last_train", {})
        final_eval = self._evaluate_and_log(wandb)
        final = run.save_checkpoint(self.state(), final=True)
        write_curves(run.metrics_path, run.curves_path)
        extra = {
            "last_train_episodes": last,
            "checkpoints": [str(p.relative_to(run.path)) for p in [*run.periodic_checkpoints(), final]],
            **({"best_eval": self._best_eval()} if run.best_path.is_file() else {}),
            **({"init": self.init_info} if self.init_info else {}),
            **(summary_extra or {}),
        }
        wall = self._wall()
        return write_summary(run, cfg, cfg.algo.name, (self.frames, self.iteration, wall), self.metric, final_eval, extra,
                             wandb if self._owns_wandb else None)

    def _evaluate_and_log(self, wandb) -> dict:
        t = time.perf_counter()
        ev = self.evaluate()
        self.eval_wall += time.perf_counter() - t
        self._log_eval(ev, wandb)
        if self.cfg.checkpoint.best and self._best() is ev:  # a new best: it beats every earlier one
            self.run.save_checkpoint(self.state(), best=True)
        return ev

    def _score(self, ev: dict) -> float:
        """The evaluation's metric, signed so that larger is better (NaN, no finished episode: worst)."""
        value = float(ev["stats"][self.metric]["mean"])
        return -math.inf if math.isnan(value) else value if self.env.metric_higher_is_better else -value

    def _best(self) -> dict:
        """The best evaluation so far, what best.pt holds (ties: the earliest, as ``max`` keeps the first)."""
        return max(self.evals, key=self._score)

    def _best_eval(self) -> dict:
        best = self._best()
        return {"frames": int(best["frames"]), self.metric: float(best["stats"][self.metric]["mean"])}

    def _log_eval(self, ev: dict, wandb) -> None:
        m = ev["stats"][self.metric]
        row = {
            "phase": "eval",
            "frames": self.frames,
            "iteration": self.iteration,
            "wall_time": self._wall(),
            f"eval_{self.metric}": m["mean"],
            f"eval_{self.metric}_std": m["std"],
            "eval_return": ev["stats"]["return"]["mean"],
        }
        self.metrics.write(row)
        if wandb:
            wandb.log(row)


def _inside(data, root: Path):
    """``data`` (plain containers) with each string that is a path inside the run directory ``root`` (the
    clone a population's learners start from, ``init=``) written relative to it: where the run lies is no
    part of its training."""
    if isinstance(data, dict):
        return {k: _inside(v, root) for k, v in data.items()}
    if isinstance(data, list):
        return [_inside(v, root) for v in data]
    if isinstance(data, str) and Path(data).is_absolute():
        try:
            return str(Path(data).resolve().relative_to(Path(root).resolve()))
        except ValueError:  # outside the run: another run's, named by the user
            return data
    return data


def write_summary(run, cfg, algo: str, counts: tuple, metric: str, final_eval: dict | None, extra: dict, wandb=None) -> dict:
    """The one writer of a run's summary.json, a learner's (``Trainer.finish``) and a population's
    (``population/loop.py``): the keys every run has (``counts``: its frames, iterations and wall
    seconds), ``final_eval`` where there is one, then the caller's ``extra``; ``wandb`` (the caller's
    own W&B run, None: none or not the caller's to end) is ended with it."""
    frames, iterations, wall = counts
    summary = {
        "task": cfg.task.name,
        "algo": algo,
        "action_space": cfg.env.action_space,
        "num_envs": cfg.env.num_envs,
        "seed": cfg.seed,
        "frames": int(frames),
        "iterations": int(iterations),
        "wall_time_s": wall,
        "frames_per_s": frames / max(wall, 1e-9),
        "metric": metric,
        **({"final_eval": final_eval} if final_eval is not None else {}),
        **extra,
        "version": __version__,
    }
    run.write_summary(summary)
    if wandb:
        wandb.finish(summary, run)
    return summary


def _next_multiple(frames: int, every: int) -> int:
    return (frames // every + 1) * every if every else sys.maxsize
