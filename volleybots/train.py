"""The run loop every algorithm shares: collect, update, log, checkpoint, evaluate.

A batch is ``algo.steps_per_batch`` steps of every env (auto-reset as episodes end), stacked into a
[num_envs, steps] tensordict in TorchRL's layout (``("next", ...)`` holds the observation before any
reset, so a truncated episode's last value can be bootstrapped).

Checkpoints are written at batch boundaries and all envs start fresh episodes right after one (the
cut episodes count as truncated, hence bootstrapped). The run's state is then exactly the networks,
optimiser, normalisers, counters and random generators, and a run resumed from a checkpoint repeats
the uninterrupted one bit for bit on a CPU.

Seats say whom the learner plays for (spec: populations.md). ``AllAgents`` (the default): it drives
every drone and learns from all of them; on a match that is MAPPO's shared-parameter self-play, one
actor for both teams and a critic over all drones, whose ``win`` is team 0's and says little.
``SelfPlay``: one actor and critic for a team, both teams driven by it, each side's samples (mirrored
views) a separate slice of the batch it learns from. ``Versus``: the learner plays team 0 against a
frozen competitor on team 1 (a checkpoint, a population's mixture drawn per episode, scripted or
random) and learns from its own team only; ``win`` is then the learner's.

``init=RUN_OR_CHECKPOINT`` starts a new run from another run's networks (``apply_init``): the actor,
and the critic where it fits, with a fresh optimiser; a resumed run restores its own checkpoint instead.
"""

from __future__ import annotations

import math
import sys
import time
from pathlib import Path

import torch

import volleybots
from volleybots.algos.base import AgentSpec
from volleybots.config import apply_overrides, check_memory, make_env, to_dict, validate
from volleybots.errors import ConfigError
from volleybots.eval import run_episodes, summarize
from volleybots.runs import (
    CKPT_FORMAT, MetricsLog, RunDir, WandbLogger, check_writable, load_algo_state, lock, memory_errors_as, read_checkpoint, unlock,
)
from volleybots.replay import write_curves

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


# ------------------------------------------------------------------------------------------ seats
def team_slice(batch, idx: torch.Tensor):
    """The ``("agents", ...)`` entries of the agents ``idx`` of a [N, T] batch (``next`` too)."""
    out = batch.exclude("agents", ("next", "agents"))
    out.set("agents", batch.get("agents")[:, :, idx])
    out.set(("next", "agents"), batch.get(("next", "agents"))[:, :, idx])
    return out


class AllAgents:
    """The learner drives every drone and learns from all of them."""

    yardstick = None  # a competitor the evaluations play on team 1 (None: the learner plays every drone)

    def spec(self, env) -> AgentSpec:
        return AgentSpec.of(env)

    def policy(self, env, learner):
        return learner

    def eval_policy(self, env, learner):
        """What the periodic and final evaluations play: against a fixed yardstick, so that the curves
        of successive learners (and of self-play, whose own win rate is 1/2) compare."""
        if self.yardstick is None:
            return self.policy(env, learner)
        from volleybots.tasks.multi import TeamPolicies

        return TeamPolicies(env, (learner, self.yardstick.team_policy(env, deterministic=False)))

    def view(self, env, batch):
        return batch

    def state_dict(self) -> dict:
        return {}

    def load_state_dict(self, state: dict) -> None:
        pass


class SelfPlay(AllAgents):
    """One learner for a team plays both teams; each team's samples train it (mirrored views), as
    2N envs of one team each, so a centralised critic sees its own team."""

    def __init__(self, yardstick=None):
        self.yardstick = yardstick

    def spec(self, env) -> AgentSpec:
        return AgentSpec.of(env, len(env.team_index(0)))

    def view(self, env, batch):
        return torch.cat([team_slice(batch, env.team_index(t)) for t in (0, 1)], dim=0)


class Versus(AllAgents):
    """The learner plays team 0 against a frozen ``Competitor`` on team 1 (the sides are mirror images,
    so a learner always on team 0 loses nothing: serves are drawn at random)."""

    def __init__(self, opponent, deterministic: bool = False, seed: int = 0, yardstick=None):
        self.opponent, self.deterministic, self.yardstick = opponent, deterministic, yardstick
        self.gen = torch.Generator()  # which population member each episode meets
        self.gen.manual_seed(seed)

    def spec(self, env) -> AgentSpec:
        return AgentSpec.of(env, len(env.team_index(0)))

    def policy(self, env, learner):
        from volleybots.tasks.multi import TeamPolicies

        return TeamPolicies(env, (learner, self.opponent.team_policy(env, self.deterministic, self.gen)))

    def view(self, env, batch):
        return team_slice(batch, env.team_index(0))

    def state_dict(self) -> dict:
        return {"gen": self.gen.get_state()}

    def load_state_dict(self, state: dict) -> None:
        self.gen.set_state(state["gen"])


def default_seat(cfg):
    """``opponent=``: the learner plays team 0 against that competitor; otherwise every drone."""
    if cfg.get("opponent") is None:
        return AllAgents()
    from volleybots.competitors import resolve_competitor

    return Versus(resolve_competitor(cfg.opponent), cfg.opponent_deterministic, cfg.seed)


# ------------------------------------------------------------------------------------------ init=
def init_checkpoint(spec: str) -> Path:
    """The checkpoint ``init=`` names: a checkpoint file, or a run dir's final (else latest) one."""
    from volleybots.runs import RunDir

    path = Path(spec)
    if path.is_file():
        return path
    run = RunDir(path)
    if not run.is_run():
        raise ConfigError(f"init={spec!r} is neither a run directory (with config.yaml) nor a checkpoint file")
    return run.policy_checkpoint(f"init={spec!r}")


def _side(algo: str, task: str, n_drones: int, action_space: str, obs_dim: int) -> str:
    return f"algo {algo}, task {task}, {n_drones} drone(s), env.action_space={action_space}, observation {obs_dim}"


def _shapes(module) -> dict[str, tuple]:
    return {k: tuple(v.shape) for k, v in module.state_dict().items()}


def _first_difference(there: dict, here: dict) -> str | None:
    """The first parameter whose name or shape differs between two parts (None: they fit)."""
    only_there, only_here = sorted(there.keys() - here.keys()), sorted(here.keys() - there.keys())
    if only_there and only_here:
        return f"other networks: {only_there[0]!r} only there, {only_here[0]!r} only here"
    for k in sorted(there.keys() | here.keys()):
        if there.get(k) != here.get(k):
            return f"{k} is {list(there[k]) if k in there else 'absent'} there, {list(here[k]) if k in here else 'absent'} here"
    return None


def apply_init(algo, cfg, spec: AgentSpec) -> dict:
    """Load ``cfg.init``'s actor, and its critic where it fits, into ``algo`` (built for ``spec``); the
    optimiser, counters and random streams stay the new run's. Raises ``ConfigError`` naming both
    sides when the task, drone count, action space, observation or the actor's shapes differ. An
    algorithm whose networks cannot take the source's may keep them another way (``guide_from``:
    SAC from a bc / ppo / mappo run). Returns what was loaded (for summary.json)."""
    from volleybots.algos import ALGOS
    from volleybots.algos.base import class_attr
    from volleybots.runs import load_algo_state, read_checkpoint
    from volleybots.tasks import TASKS

    path = init_checkpoint(cfg.init)
    state = read_checkpoint(path, device=algo.device)
    if "algo" not in state:
        raise ConfigError(f"init={cfg.init!r} is a built-in player ({state.get('builtin')}), not a trained policy")
    try:
        src = validate(state["config"])
    except ConfigError as e:
        raise ConfigError(f"init={cfg.init!r}: the source's saved config is not valid here ({e})") from None
    here_drones = class_attr(TASKS[cfg.task.name], "n_drones")
    there_drones = class_attr(TASKS[src.task.name], "n_drones")
    here = _side(cfg.algo.name, cfg.task.name, here_drones, cfg.env.action_space, spec.obs_dim)
    there = _side(src.algo.name, src.task.name, there_drones, src.env.action_space, int(state["obs_dim"]))
    what = f"init={cfg.init!r} ({there}) does not fit this run ({here})"
    for name, a, b in (("task", src.task.name, cfg.task.name), ("drone count", there_drones, here_drones),
                       ("action space", src.env.action_space, cfg.env.action_space), ("observation size", int(state["obs_dim"]), spec.obs_dim)):
        if a != b:
            raise ConfigError(f"{what}: the {name} differs")
    src_cls = ALGOS[src.algo.name]
    src_cls = getattr(src_cls, "learner_cls", src_cls)  # a population method's learner
    # the source's random initial weights are overwritten at once: they must not move this run's stream
    with torch.random.fork_rng(devices=[]):
        source = src_cls(src.algo, AgentSpec(spec.device, int(state["n_agents"]), int(state["obs_dim"]), spec.actions), seed=src.seed)
    load_algo_state(source, state, f"init={cfg.init!r}", src)
    parts, src_parts = algo.init_parts(), source.init_parts()
    if "actor" not in parts:
        raise ConfigError(f"algo {cfg.algo.name!r} cannot start from another run (init=)")
    if algo.guide_from(source):  # networks that cannot take the source's: it guides them (sac from a clone)
        skipped = [f"{role} (algo {src.algo.name}'s networks are PPO's: its actor is the guide)" for role in parts]
        return _init_info(path, state, src, ["guide"], skipped)
    loaded, skipped = [], []
    for role, module in parts.items():
        diff = _first_difference(_shapes(src_parts[role]), _shapes(module)) if role in src_parts else f"algo {src.algo.name} has no {role}"
        if diff is None:
            module.load_state_dict(src_parts[role].state_dict())
            loaded.append(role)
        elif role == "actor":
            raise ConfigError(f"{what}: the actor's networks differ ({diff})")
        else:
            skipped.append(f"{role} ({diff})")
    algo.after_init()
    return _init_info(path, state, src, loaded, skipped)


def _init_info(path: Path, state: dict, src, loaded: list[str], skipped: list[str]) -> dict:
    """What ``init=`` loaded, for summary.json and the checkpoints."""
    from volleybots.competitors import sha256

    return {"source": str(path), "sha256": sha256(path), "algo": src.algo.name, "frames": int(state["frames"]), "loaded": loaded, "skipped": skipped}


def learner_spec(cfg, env) -> AgentSpec:
    """What the learner of ``cfg`` is built for (a population method's learner plays one team)."""
    from volleybots.algos import ALGOS

    return SelfPlay().spec(env) if getattr(ALGOS[cfg.algo.name], "population", False) else default_seat(cfg).spec(env)


def check_init(cfg) -> None:
    """Raise ``ConfigError`` now, before any run dir is written, when ``cfg.init`` does not fit."""
    if cfg.get("init") is None:
        return
    from volleybots.algos import ALGOS

    env = make_env(cfg, num_envs=1)
    spec = learner_spec(cfg, env)
    algo_cls = ALGOS[cfg.algo.name]
    with torch.random.fork_rng(devices=[]):
        algo = getattr(algo_cls, "learner_cls", algo_cls)(cfg.algo, spec, seed=cfg.seed)
    apply_init(algo, cfg, spec)


# ------------------------------------------------------------------------------------------ trainer
class Trainer:
    """The run loop over one learner. ``seat`` says whom it plays for (default: every drone);
    ``learner_cls`` overrides the registry's class (a population method's learner); ``extra_state``
    adds the caller's own counters to every checkpoint (the population loop's oracle)."""

    def __init__(self, cfg, run: RunDir, checkpoint: Path | None = None, seat=None, learner_cls=None, extra_state=None):
        self.cfg, self.run = cfg, run
        from volleybots.algos import ALGOS

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
            "n_agents": int(self.algo.n_agents),
            "frames": int(self.frames),
            "iteration": int(self.iteration),
            "wall_time": float(self._wall()),
            "evals": self.evals,
            "algo": self.algo.state_dict(),
            "rng": self._rng_state(),
            "seat": self.seat.state_dict(),
            "init": self.init_info,
            **self.extra_state(),
        }

    def _restore(self, state: dict) -> None:
        load_algo_state(self.algo, state, f"the checkpoint of run {str(self.run.path)!r}", self.cfg)
        self.frames, self.iteration = int(state["frames"]), int(state["iteration"])
        self.wall_offset = float(state["wall_time"])
        self.evals = list(state.get("evals", []))
        self.init_info = state.get("init")
        rng = state["rng"]
        torch.set_rng_state(rng["torch"])
        if "env" in rng:
            self.env.rng.set_state(rng["env"])
        if "cuda" in rng and torch.cuda.is_available():
            torch.cuda.set_rng_state_all(rng["cuda"])
        self.seat.load_state_dict(state.get("seat", {}))

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
    def fit(self) -> dict:
        """Train to ``total_frames``, then evaluate, write final.pt and summary.json."""
        self.train_loop()
        return self.finish()

    def train_loop(self, stop=None, row_extra=None) -> None:
        """Collect and update until ``total_frames`` (or ``time_limit``), or until ``stop(row)`` says so
        after a batch; ``row_extra`` adds columns to every metrics row."""
        cfg, run = self.cfg, self.run
        resumed = self.frames > 0
        self.metrics = MetricsLog(run.metrics_path, keep_until_frames=self.frames if resumed else None)
        self.wandb = wandb = WandbLogger(cfg, run.path, resumed) if cfg.logger == "wandb" else None
        self._t0 = time.perf_counter()
        policy = self.seat.policy(self.env, self.algo.policy())
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
                losses = self.algo.update(self.seat.view(self.env, batch))
                dt = time.perf_counter() - t_batch
                row = {"phase": "train", "frames": self.frames, "iteration": self.iteration, "wall_time": self._wall(), "fps": self.frames_per_batch / dt}
                row.update(row_extra or {})
                row.update(stats)
                row.update(losses)
                row.update({f"eval_{self.metric}": None, f"eval_{self.metric}_std": None, "eval_return": None})
                self.metrics.write(row)
                if wandb:
                    wandb.log(row)
                if not math.isnan(stats.get(self.metric, math.nan)):
                    last = stats
                bar(self.frames, row["fps"], self.metric, last.get(self.metric))
                # the caller's counters see this batch before a checkpoint records them
                stopping = stop is not None and stop(row)
                if stopping:
                    break
                if ck_every and self.frames >= next_ck and self.frames < cfg.total_frames:
                    run.save_checkpoint(self._state(), keep=cfg.checkpoint.keep)
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
            **({"best_eval": self._best_eval()} if run.best_path.is_file() else {}),
            "version": volleybots.__version__,
            **({"init": self.init_info} if self.init_info else {}),
            **(summary_extra or {}),
        }
        run.write_summary(summary)
        if wandb:
            wandb.close()
        return summary

    def _evaluate_and_log(self, wandb) -> dict:
        ev = self.evaluate()
        self._log_eval(ev, wandb)
        if self.cfg.checkpoint.best and self._best() is ev:  # a new best: it beats every earlier one
            self.run.save_checkpoint(self._state(), best=True)
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
    check_init(cfg)
    run = RunDir(run_dir)
    run.create(cfg)
    try:
        with memory_errors_as(_counts(cfg)):
            return Trainer(cfg, run).fit()
    finally:
        unlock(run.path)


def resume_config(run_dir, overrides=(), keys=RESUME_KEYS):
    """The saved config of the run in ``run_dir`` with the overrides a resume may make (``keys``)."""
    base = RunDir(run_dir).load_config()
    return apply_overrides(to_dict(base), overrides, keys, f"run {str(run_dir)!r} (resume)")


def resume(run_dir, overrides=()) -> dict:
    """Continue the run in ``run_dir`` from its latest checkpoint (``train resume=DIR``); a run killed
    before its first checkpoint starts afresh, saying so.

    Everything is checked before anything is written (the config and overrides, the checkpoint
    against the run's task and networks, metrics.csv, memory); the run's lock is then taken, so a
    second resume of the same run is refused."""
    if not str(run_dir).strip():
        raise ConfigError("resume= needs a run directory: resume=RUN_DIR")
    run = RunDir(run_dir)
    cfg = resume_config(run_dir, overrides)
    check_writable(run.path, "the run directory")
    ckpt = run.latest_checkpoint()
    stamp = run.checkpoint_stamp()
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
            if run.checkpoint_stamp() != stamp:
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
