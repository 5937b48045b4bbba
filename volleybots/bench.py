"""Throughput benchmark of the envs: env-steps per second with random actions (docs/performance.md).

``run_bench`` measures full TorchRL env steps (physics, referee, rewards, observations and automatic
partial resets through ``step_and_maybe_reset``, as a collector does), excluding warm-up and
compilation, and reports the median over repeats; with ``train=True`` it adds the end-to-end training
rate (collection + updates, frames/s) of PPO on Solo Bump and MAPPO on 3 vs 3 (``TRAIN_CASES``), and
on a match also of the competitive seats (``SEATS``: self-play, a PSRO oracle against a mixed
population, an exploitability best response) with their rate over MAPPO's (``vs_mappo``).
``format_table`` renders the rows as Markdown with the torch/MuJoCo speed ratio of each task measured
in the same run. ``benchmarks/speed/bench.py`` and the ``volleybots bench`` verb are thin front ends to
these two functions.
"""

from __future__ import annotations

import statistics
import time
from typing import Callable, Sequence

import torch

from volleybots.config.verbs import BenchOptions

DEFAULT_TASKS = tuple(BenchOptions().tasks)  # (the options' defaults: one place)
DEFAULT_NUM_ENVS = tuple(BenchOptions().num_envs)
TRAIN_CASES = (("solo_bump", "ppo"), ("3v3", "mappo"))  # (task, algorithm) of the training rows


def default_devices() -> tuple[str, ...]:
    return ("cpu", "cuda") if torch.cuda.is_available() else ("cpu",)


def default_steps(num_envs: int, backend: str) -> int:
    """Env steps per repeat: enough work to time (about 1e5 env-steps for torch, 2e4 for MuJoCo)."""
    budget = 100_000 if backend == "torch" else 20_000
    return int(min(500, max(10, budget // num_envs)))


def _sync(device: str) -> None:
    if str(device).startswith("cuda"):
        torch.cuda.synchronize()


def measure(
    task: str,
    backend: str,
    num_envs: int,
    device: str = "cpu",
    compile: bool = False,
    repeats: int = 3,
    steps: int | None = None,
    warmup: int = 5,
    action_space: str = "prt",
    seed: int = 0,
) -> dict:
    """One row of ``run_bench``: the env-steps/s of one (task, backend, num_envs, device, compile)."""
    from volleybots.config import build_env

    steps = steps or default_steps(num_envs, backend)
    t0 = time.perf_counter()
    # make_env routes compile= to the physics sub-step only (static shapes); MuJoCo ignores it
    env = build_env(
        task, num_envs=num_envs, action_space=action_space, physics=backend, device=device, seed=seed,
        compile=bool(compile and backend == "torch"),
    )
    build_s = time.perf_counter() - t0
    torch.manual_seed(seed)
    threads = torch.get_num_threads()
    if backend == "mujoco":
        # Equal cores, each backend at its best: MuJoCo's rollout pool takes the row's threads (make_env
        # sized it so) and its torch glue runs on the calling thread alone. Idle torch workers spinning
        # between ops took cores from the pool: 88k against 110k env-steps/s (Solo Bump, 2 cores).
        torch.set_num_threads(1)
    try:
        row = _time_env(env, num_envs, device, repeats, steps, warmup)
    finally:
        torch.set_num_threads(threads)
        close = getattr(env.physics, "close", None)
        if close is not None:
            close()
    return {
        "task": task,
        "backend": backend,
        "device": str(device),
        "compile": bool(compile),
        "num_envs": int(num_envs),
        "n_drones": int(env.n_drones),
        "action_space": action_space,
        "steps": int(steps),
        "repeats": int(repeats),
        **row,
        "setup_s": build_s + row["setup_s"],  # build + warm-up, incl. compilation
        "threads": threads,
        "kind": "env",  # "train ALGO" for the rows of measure_training
    }


def _time_env(env, num_envs: int, device: str, repeats: int, steps: int, warmup: int) -> dict:
    """Warm up (and compile), then time ``repeats`` x ``steps`` random-action steps of ``env``."""
    t0 = time.perf_counter()
    # a few pre-drawn random actions, cycled, so that sampling does not count as env time
    actions = [env.full_action_spec.rand() for _ in range(8)]
    td = env.reset()
    for i in range(warmup):  # includes compilation when compile=True
        _, td = env.step_and_maybe_reset(td.update(actions[i % len(actions)]))
    _sync(device)
    setup_s = time.perf_counter() - t0
    rates, cpu_rates = [], []
    for _ in range(repeats):
        start, cpu_start = time.perf_counter(), time.process_time()
        for i in range(steps):
            _, td = env.step_and_maybe_reset(td.update(actions[i % len(actions)]))
        _sync(device)
        rates.append(num_envs * steps / (time.perf_counter() - start))
        cpu_rates.append(num_envs * steps / max(time.process_time() - cpu_start, 1e-9))
    rate = statistics.median(rates)
    return {
        "env_steps_per_s": rate,
        "step_ms": 1e3 * num_envs / rate,
        "all_env_steps_per_s": rates,
        # per second of this process's CPU time (all its threads): on a shared machine with one thread,
        # the rate it would reach with a core of its own
        "env_steps_per_cpu_s": statistics.median(cpu_rates),
        "setup_s": setup_s,
    }


def measure_training(
    task: str, algo: str, num_envs: int, device: str = "cpu", compile: bool = False, batches: int = 3, backend: str = "torch",
    seed: int = 0, seat: str | None = None, overrides: Sequence[str] = (),
) -> dict:
    """End-to-end training frames/s of ``algo`` on ``task``: collection (policy + env steps) and the
    algorithm's update, as ``volleybots train`` runs them, over ``batches`` batches after a first one
    that warms up (and compiles). The algorithm's own config (steps per batch, epochs) is the default.

    ``seat`` (a match, ``algo`` MAPPO): the learner plays in a competitive seat of ``SEATS`` instead
    of driving every drone, on the same task, batch and hyperparameters, so the rows compare."""
    from volleybots.algos import ALGOS
    from volleybots.config import load, make_env
    from volleybots.play.episodes import collect

    cfg = load([f"task={task}", f"algo={algo}", f"env.num_envs={num_envs}", f"env.device={device}", f"env.physics={backend}",
                f"env.compile={str(bool(compile and backend == 'torch')).lower()}", f"seed={seed}", *overrides])
    t0 = time.perf_counter()
    torch.manual_seed(seed)
    env = make_env(cfg)
    where = _seat(seat, cfg, env, seed)
    learner = ALGOS[cfg.algo.name](cfg.algo, where.spec(env), seed=seed)
    policy = where.policy(env, learner.policy())
    td = env.reset()
    frames = num_envs * learner.steps_per_batch

    def one_batch(td):
        batch, td = collect(env, policy, td, learner.steps_per_batch)
        learner.update(where.view(env, batch))
        return td

    td = one_batch(td)
    _sync(device)
    setup_s = time.perf_counter() - t0
    start, cpu_start = time.perf_counter(), time.process_time()
    for _ in range(batches):
        td = one_batch(td)
    _sync(device)
    wall, cpu = time.perf_counter() - start, time.process_time() - cpu_start
    close = getattr(env.physics, "close", None)
    if close is not None:
        close()
    rate = frames * batches / wall
    return {
        "task": task, "backend": backend, "device": str(device), "compile": bool(compile and backend == "torch"),
        "num_envs": int(num_envs), "n_drones": int(env.n_drones), "action_space": cfg.env.action_space, "kind": f"train {seat or algo}",
        "steps": int(learner.steps_per_batch), "repeats": int(batches), "env_steps_per_s": rate, "step_ms": 1e3 * num_envs / rate,
        "all_env_steps_per_s": [rate], "env_steps_per_cpu_s": frames * batches / max(cpu, 1e-9), "setup_s": setup_s,
        "threads": torch.get_num_threads(),
    }


# competitive seats measured beside plain MAPPO on a match (same task, batch and hyperparameters):
# sp: one learner plays both teams (SelfPlay); psro oracle: a learner against a population that mixes
# the scripted and random players and a learned member (the cost of the scripted planner included);
# best response: a learner against one fixed learned policy (what `eval exploitability` trains)
SEATS = ("sp", "psro oracle", "best response")


def _seat(seat: str | None, cfg, env, seed: int):
    """The seat of a training row; a learned member is a fresh MAPPO team policy (acting costs the same
    as a trained one's)."""
    from volleybots.algos.base import AgentSpec
    from volleybots.algos.ppo import MAPPO
    from volleybots.play.seats import AllAgents, SelfPlay, Versus
    from volleybots.policies import Competitor, builtin_member
    from volleybots.policies.competitors import Member

    if seat is None:
        return AllAgents()
    if seat == "sp":
        return SelfPlay()
    frozen = MAPPO(cfg.algo, AgentSpec.of(env, len(env.team_index(1))), seed=seed + 1)
    learned = Member("learned", lambda env, deterministic=False: frozen.policy(deterministic=deterministic), {"kind": "bench"})
    if seat == "psro oracle":
        opponent = Competitor("population", [builtin_member("scripted"), builtin_member("random"), learned], [1 / 3] * 3)
    elif seat == "best response":
        opponent = Competitor("target", [learned])
    else:
        raise ValueError(f"unknown seat {seat!r}; allowed: {', '.join(SEATS)}")
    return Versus(opponent, seed=seed)


def run_bench(options: BenchOptions | None = None, progress: Callable[[dict], None] | None = None) -> list[dict]:
    """Measure env-steps/s for every combination of task, backend, env count and device.

    Args:
        options: what to measure (``volleybots.config.verbs.BenchOptions``; its fields' help says each):
            ``tasks`` (of ``volleybots.tasks.TASKS``), ``backends`` (of ``volleybots.physics.BACKENDS``;
            MuJoCo steps on the CPU whatever the env device, so it is measured on "cpu" only),
            ``num_envs`` (batch sizes), ``devices`` (default "cpu", plus "cuda" when available),
            ``compile`` (``torch.compile`` the torch physics sub-step with static shapes: the first
            steps of each new shape compile, excluded from the timing, reported as ``setup_s``; a list
            such as ``[False, True]`` measures the torch backend both ways), ``repeats`` (a row reports
            their median), ``steps`` (per repeat; default ``default_steps``, scaled by env count and
            backend), ``action_space`` (random actions from its spec), ``threads`` (the cores each row
            may use: torch's intra-op threads for the torch backend, the rollout pool for MuJoCo, whose
            torch glue runs on one thread; on a machine shared with other work, 1 is often much faster
            than 2), ``train`` (also end-to-end training frames/s, ``measure_training``, of each
            ``TRAIN_CASES`` (task, algorithm) whose task is in ``tasks``, for every env count, device
            and compile mode, on the torch backend), ``train_batches`` and ``train_overrides`` (config
            overrides of every training row: ``algo.steps_per_batch=8`` gives tiny rows). ``None``: the defaults.
        progress: called with each row as soon as it is measured (for printing); one with a ``begin``
            method is first told the number of rows (``begin(total)``: its done / total and ETA).

    Returns:
        One dict per measurement with keys ``task, backend, device, compile, num_envs, n_drones,
        action_space, steps, repeats, env_steps_per_s`` (median), ``step_ms`` (one batched step),
        ``all_env_steps_per_s`` (every repeat), ``env_steps_per_cpu_s`` (per second of the process's
        CPU time), ``setup_s`` (build + warm-up, incl. compilation) and ``threads`` (torch threads).
    """
    o, default = options if options is not None else BenchOptions(), BenchOptions()
    tasks, num_envs, devices, compile = tuple(o.tasks or default.tasks), tuple(o.num_envs or default.num_envs), o.devices, o.compile
    before = torch.get_num_threads()
    if o.threads:
        torch.set_num_threads(o.threads)
    try:
        cases = _env_cases(tasks, tuple(o.backends or default.backends), num_envs, devices, compile)
        trained = _train_cases(tasks, num_envs, devices, compile) if o.train else []
        if hasattr(progress, "begin"):  # a progress that shows done / total and an ETA is told the total first
            progress.begin(len(cases) + len(trained))
        rows = _run(cases, o.repeats, o.steps, o.action_space, progress)
        return rows + _run_training(trained, o.train_batches, progress, tuple(o.train_overrides or ()))
    finally:
        torch.set_num_threads(before)


def _env_cases(tasks, backends, num_envs, devices, compile) -> list[tuple]:
    """(task, backend, num_envs, device, compile) of every env row, in the order they are measured."""
    devices = tuple(devices) if devices is not None else default_devices()
    # MuJoCo steps on the CPU and has nothing to compile: one row whatever the devices and modes
    return [(task, backend, n, device, comp) for task in tasks for n in num_envs for backend in backends for device in devices
            if not (backend == "mujoco" and device != "cpu") for comp in (_modes(compile) if backend == "torch" else (False,))]


def _run(cases, repeats, steps, action_space, progress) -> list[dict]:
    rows = []
    for task, backend, n, device, comp in cases:
        rows.append(measure(task, backend, n, device, compile=comp, repeats=repeats, steps=steps, action_space=action_space))
        if progress is not None:
            progress(rows[-1])
    return rows


def _modes(compile) -> tuple[bool, ...]:
    return (bool(compile),) if isinstance(compile, bool) else tuple(bool(c) for c in compile)


def _train_cases(tasks, num_envs, devices, compile) -> list[tuple]:
    """(task, algo, num_envs, device, compile, seat) of every training row: each competitive task's plain
    MAPPO row (seat None) first, then its seats' rows, which are compared with it."""
    devices = tuple(devices) if devices is not None else default_devices()
    return [(task, algo, n, device, comp, seat) for task, algo in TRAIN_CASES if task in tasks for n in num_envs for device in devices
            for comp in _modes(compile) for seat in ((None, *SEATS) if _competitive(task) else (None,))]


def _run_training(cases, batches, progress, overrides=()) -> list[dict]:
    rows, base = [], None  # base: the plain MAPPO row each seat's row is compared with
    for task, algo, n, device, comp, seat in cases:
        rows.append(measure_training(task, algo, n, device, compile=comp, batches=batches, seat=seat, overrides=overrides))
        if seat is not None:  # the seat's cost: its rate over plain MAPPO's of the same run
            rows[-1]["vs_mappo"] = rows[-1]["env_steps_per_s"] / base["env_steps_per_s"]
        base = rows[-1] if seat is None else base
        if progress is not None:
            progress(rows[-1])
    return rows


def _competitive(task: str) -> bool:
    from volleybots.tasks import TASKS

    return bool(TASKS[task].competitive)


def speed_ratios(rows: Sequence[dict]) -> dict[tuple[str, int, str, bool], float]:
    """(task, num_envs, torch device, compiled) -> torch env-steps/s over MuJoCo's, same task and env count."""
    env_rows = [r for r in rows if r.get("kind", "env") == "env"]
    mj = {(r["task"], r["num_envs"]): r["env_steps_per_s"] for r in env_rows if r["backend"] == "mujoco"}
    return {
        (r["task"], r["num_envs"], r["device"], r["compile"]): r["env_steps_per_s"] / mj[(r["task"], r["num_envs"])]
        for r in env_rows
        if r["backend"] == "torch" and (r["task"], r["num_envs"]) in mj
    }


def _rate(x: float) -> str:
    if x >= 1e6:
        return f"{x / 1e6:.2f}M"
    if x >= 1e3:
        return f"{x / 1e3:.1f}k"
    return f"{x:.0f}"


def format_table(rows: Sequence[dict]) -> str:
    """Markdown table of ``run_bench`` rows; torch env rows show their speed-up over MuJoCo (same run);
    training rows (``kind`` "train ALGO") give frames/s, collection and updates together."""
    ratios = speed_ratios(rows)
    lines = [
        "| task | measures | drones | backend | device | compile | threads | envs | env-steps/s | per CPU-s | ms / step "
        "| torch / MuJoCo, seat / mappo |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        kind = r.get("kind", "env")
        if r["backend"] == "torch" and kind == "env":
            ratio = ratios.get((r["task"], r["num_envs"], r["device"], r["compile"]))
        else:
            ratio = r.get("vs_mappo")
        lines.append(
            f"| {r['task']} | {kind} | {r['n_drones']} | {r['backend']} | {r['device']} "
            f"| {'yes' if r['compile'] else 'no'} | {r['threads']} "
            f"| {r['num_envs']} | {_rate(r['env_steps_per_s'])} | {_rate(r['env_steps_per_cpu_s'])} | {r['step_ms']:.2f} "
            f"| {'' if ratio is None else f'{ratio:.2f}x' if 'vs_mappo' in r else f'{ratio:.1f}x'} |"
        )
    return "\n".join(lines)
