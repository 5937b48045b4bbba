"""The run loop every algorithm shares: collect, update, log, checkpoint, evaluate.

A batch is ``algo.steps_per_batch`` steps of every env (auto-reset as episodes end), stacked into a
[num_envs, steps] tensordict in TorchRL's layout (``("next", ...)`` holds the observation before any
reset, so a truncated episode's last value can be bootstrapped).

Checkpoints are written at batch boundaries and all envs start fresh episodes right after one (the
cut episodes count as truncated, hence bootstrapped). The run's state is then exactly the networks,
optimiser, normalisers, counters and random generators, and a run resumed from a checkpoint repeats
the uninterrupted one bit for bit on a CPU.
"""

from __future__ import annotations

import math
import sys
import time
from pathlib import Path

import torch

import volleybots
from volleybots.config import apply_overrides, check_memory, make_env, to_dict
from volleybots.errors import ConfigError
from volleybots.eval import run_episodes, summarize
from volleybots.runs import (
    CKPT_FORMAT, MetricsLog, RunDir, WandbLogger, check_writable, load_algo_state, lock, memory_errors_as, read_checkpoint, unlock,
    write_curves,
)

# keys a resumed run may change: how long it goes on and how it reports, not what it learns
RESUME_KEYS = ("total_frames", "time_limit", "progress", "threads", "logger", "wandb", "checkpoint", "evaluation", "env.device")
EVAL_SEED_OFFSET = 10_000  # periodic evaluations play the same episodes every time, unlike training's


def collect(env, policy, td, steps: int):
    """``steps`` steps of every env; returns the [num_envs, steps] batch and the next input."""
    out = []
    for _ in range(steps):
        td = policy(td)
        step, td = env.step_and_maybe_reset(td)
        out.append(step)
    return torch.stack(out, dim=1), td


def finished_stats(batch) -> dict[str, float]:
    """Means of the statistics of the episodes that ended in ``batch`` (NaN when none did)."""
    nxt = batch["next"]
    done = nxt["done"].reshape(-1)
    n = int(done.sum())
    out = {"episodes": float(n)}
    for k in nxt["stats"].keys():
        v = nxt["stats", k].reshape(-1)[done]
        out[k] = float(v.mean()) if n else math.nan
    return out


class Trainer:
    def __init__(self, cfg, run: RunDir, checkpoint: Path | None = None):
        self.cfg, self.run = cfg, run
        from volleybots.algos import ALGOS

        torch.manual_seed(cfg.seed)
        self.env = make_env(cfg)
        self.algo = ALGOS[cfg.algo.name](cfg.algo, self.env, seed=cfg.seed)
        self.frames = self.iteration = 0
        self.wall_offset = 0.0
        self.evals: list[dict] = []
        if checkpoint is not None:
            self._restore(read_checkpoint(checkpoint, device=self.env.device))
        self.frames_per_batch = self.env.num_envs * self.algo.steps_per_batch
        self.metric = self.env.metric
        self._eval_env = None

    # ---------------------------------------------------------------------- checkpoint state
    def _rng_state(self) -> dict:
        state = {"torch": torch.get_rng_state()}
        if getattr(self.env, "rng", None) is not None:
            state["env"] = self.env.rng.get_state()
        if torch.cuda.is_available():
            state["cuda"] = torch.cuda.get_rng_state_all()
        return state

    def _state(self) -> dict:
        return {
            "format": CKPT_FORMAT,
            "version": volleybots.__version__,
            "config": to_dict(self.cfg),
            "task": self.cfg.task.name,
            "action_space": self.cfg.env.action_space,
            "obs_dim": int(self.env.obs_dim),
            "n_agents": int(self.env.n_drones),
            "frames": int(self.frames),
            "iteration": int(self.iteration),
            "wall_time": float(self._wall()),
            "evals": self.evals,
            "algo": self.algo.state_dict(),
            "rng": self._rng_state(),
        }

    def _restore(self, state: dict) -> None:
        load_algo_state(self.algo, state, f"the checkpoint of run {str(self.run.path)!r}", self.cfg)
        self.frames, self.iteration = int(state["frames"]), int(state["iteration"])
        self.wall_offset = float(state["wall_time"])
        self.evals = list(state.get("evals", []))
        rng = state["rng"]
        torch.set_rng_state(rng["torch"])
        if "env" in rng:
            self.env.rng.set_state(rng["env"])
        if "cuda" in rng and torch.cuda.is_available():
            torch.cuda.set_rng_state_all(rng["cuda"])

    def _wall(self) -> float:
        return self.wall_offset + time.perf_counter() - self._t0

    # ---------------------------------------------------------------------------- evaluation
    def evaluate(self) -> dict:
        cfg = self.cfg
        if self._eval_env is None:
            self._eval_env = make_env(cfg, num_envs=cfg.evaluation.episodes, seed=cfg.seed + EVAL_SEED_OFFSET)
        env = self._eval_env
        env.set_seed(cfg.seed + EVAL_SEED_OFFSET)
        policy = self.algo.policy(deterministic=True)
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
    def fit(self) -> dict:
        cfg, run = self.cfg, self.run
        resumed = self.frames > 0
        self.metrics = MetricsLog(run.metrics_path, keep_until_frames=self.frames if resumed else None)
        wandb = WandbLogger(cfg, run.path, resumed) if cfg.logger == "wandb" else None
        self._t0 = time.perf_counter()
        policy = self.algo.policy()
        td = self.env.reset()
        ck_every, ev_every = cfg.checkpoint.every, cfg.evaluation.every
        next_ck = _next_multiple(self.frames, ck_every)
        next_ev = _next_multiple(self.frames, ev_every)
        last: dict = {}
        with _progress(cfg.progress, cfg.total_frames, self.frames) as bar:
            while self.frames < cfg.total_frames and not (cfg.time_limit and self._wall() >= cfg.time_limit):
                t_batch = time.perf_counter()
                batch, td = collect(self.env, policy, td, self.algo.steps_per_batch)
                self.frames += self.frames_per_batch
                self.iteration += 1
                stats = finished_stats(batch)
                losses = self.algo.update(batch)
                dt = time.perf_counter() - t_batch
                row = {"phase": "train", "frames": self.frames, "iteration": self.iteration, "wall_time": self._wall(), "fps": self.frames_per_batch / dt}
                row.update(stats)
                row.update(losses)
                row.update({f"eval_{self.metric}": None, f"eval_{self.metric}_std": None, "eval_return": None})
                self.metrics.write(row)
                if wandb:
                    wandb.log(row)
                if not math.isnan(stats.get(self.metric, math.nan)):
                    last = stats
                bar(self.frames, row["fps"], self.metric, last.get(self.metric))
                if ck_every and self.frames >= next_ck and self.frames < cfg.total_frames:
                    run.save_checkpoint(self._state(), keep=cfg.checkpoint.keep)
                    td = self.env.reset()  # see the module docstring: a checkpoint is a clean cut
                    next_ck = _next_multiple(self.frames, ck_every)
                    write_curves(run.metrics_path, run.curves_path)
                if ev_every and self.frames >= next_ev and self.frames < cfg.total_frames:
                    self._log_eval(self.evaluate(), wandb)
                    next_ev = _next_multiple(self.frames, ev_every)
        final_eval = self.evaluate()
        self._log_eval(final_eval, wandb)
        final = run.save_checkpoint(self._state(), final=True)
        write_curves(run.metrics_path, run.curves_path)
        summary = {
            "task": cfg.task.name,
            "algo": cfg.algo.name,
            "action_space": cfg.env.action_space,
            "num_envs": cfg.env.num_envs,
            "seed": cfg.seed,
            "frames": self.frames,
            "iterations": self.iteration,
            "wall_time_s": self._wall(),
            "frames_per_s": self.frames / max(self._wall(), 1e-9),
            "metric": self.metric,
            "final_eval": final_eval,
            "last_train_episodes": last,
            "checkpoints": [str(p.relative_to(run.path)) for p in [*run.periodic_checkpoints(), final]],
            "version": volleybots.__version__,
        }
        run.write_summary(summary)
        if wandb:
            wandb.close()
        return summary

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


def _next_multiple(frames: int, every: int) -> int:
    return (frames // every + 1) * every if every else sys.maxsize


class _progress:
    """A rich progress bar (frames, frames/s, the task metric of the last finished episodes)."""

    def __init__(self, enabled: bool, total: int, start: int):
        self.enabled, self.total, self.start = enabled, total, start

    def __enter__(self):
        if not self.enabled:
            return lambda *a: None
        from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn, TimeRemainingColumn

        self.p = Progress(
            TextColumn("[bold]train"), BarColumn(), MofNCompleteColumn(), TextColumn("frames"),
            TimeElapsedColumn(), TimeRemainingColumn(), TextColumn("{task.fields[info]}"),
        )
        self.p.__enter__()
        self.task = self.p.add_task("train", total=self.total, completed=self.start, info="")

        def update(frames, fps, metric, value):
            shown = "-" if value is None or math.isnan(value) else f"{value:.3g}"
            self.p.update(self.task, completed=min(frames, self.total), info=f"{fps:,.0f} frames/s  {metric} {shown}")

        return update

    def __exit__(self, *exc):
        if self.enabled:
            self.p.__exit__(*exc)
        return False


def train(cfg, run_dir) -> dict:
    """Start a new run of the validated config ``cfg`` in ``run_dir``, holding its lock while it trains."""
    check_memory(cfg)
    run = RunDir(run_dir)
    run.create(cfg)
    try:
        with memory_errors_as(_counts(cfg)):
            return Trainer(cfg, run).fit()
    finally:
        unlock(run.path)


def resume(run_dir, overrides=()) -> dict:
    """Continue the run in ``run_dir`` from its latest checkpoint (``train resume=DIR``); a run killed
    before its first checkpoint starts afresh, saying so.

    Everything is checked before anything is written (the config and overrides, the checkpoint
    against the run's task and networks, metrics.csv, memory); the run's lock is then taken, so a
    second resume of the same run is refused."""
    if not str(run_dir).strip():
        raise ConfigError("resume= needs a run directory: resume=RUN_DIR")
    run = RunDir(run_dir)
    cfg = apply_overrides(to_dict(run.load_config()), overrides, RESUME_KEYS, f"run {str(run_dir)!r} (resume)")
    check_writable(run.path, "the run directory")
    ckpt = run.latest_checkpoint()
    if ckpt is not None:
        done = int(read_checkpoint(ckpt)["frames"])
        if done >= cfg.total_frames:
            raise ConfigError(f"run {str(run_dir)!r} already has {done} frames >= total_frames={cfg.total_frames}; raise total_frames to continue it")
        run.check_metrics()
    check_memory(cfg)
    with memory_errors_as(_counts(cfg)):
        trainer = Trainer(cfg, run, checkpoint=ckpt)  # a checkpoint that does not fit the run fails here
        lock(run.path)
        try:
            if run.latest_checkpoint() != ckpt:
                raise ConfigError(f"run {str(run_dir)!r} was trained by another process while this one checked it; run the command again")
            if ckpt is None:
                run.clear_unfinished()
            run.write_config(cfg)
            return trainer.fit()
        finally:
            unlock(run.path)


def _counts(cfg) -> str:
    """The config's counts that decide the memory a run takes, for an out-of-memory message."""
    buffer = f", algo.buffer_size={cfg.algo.buffer_size}" if "buffer_size" in cfg.algo else ""
    return f"env.num_envs={cfg.env.num_envs}, algo.steps_per_batch={cfg.algo.steps_per_batch}, evaluation.episodes={cfg.evaluation.episodes}{buffer}"
