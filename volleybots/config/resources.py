"""Resources: counts checked against the memory they need before anything is written."""

from __future__ import annotations

from volleybots.config.envs import build_env, make_env
from volleybots.config.schema import _typed, check_values, to_dict
from volleybots.config.verbs import BenchOptions
from volleybots.errors import ConfigError, check_device


def check_memory(cfg, worlds: int | None = None) -> None:
    """Refuse a batch, replay buffer or episode count that cannot fit in memory, before anything is
    written: a training run (``worlds=None``) holds a batch of ``env.num_envs x algo.steps_per_batch``
    env steps, its replay buffer and the evaluation's ``evaluation.episodes`` worlds; ``eval`` holds
    ``worlds`` (its episodes) worlds.

    The need is a lower bound measured on a one-world probe env (the bytes of one env step's
    tensordict), so a refusal is certain; counts that pass can still run out of memory in the
    update, which the CLI reports as one line too."""
    probe = make_env(cfg, num_envs=1, seed=cfg.seed)
    step_bytes, obs_dim = _step_bytes(probe), int(probe.obs_dim)
    if worlds is not None:
        needs = [(worlds * step_bytes, f"episodes={worlds} ({step_bytes} bytes per world)", "episodes", cfg.env.device)]
    else:
        a = cfg.algo
        needs = [
            (cfg.env.num_envs * a.steps_per_batch * step_bytes,
             f"env.num_envs={cfg.env.num_envs} x algo.steps_per_batch={a.steps_per_batch} ({step_bytes} bytes per world and step)",
             "env.num_envs or algo.steps_per_batch", cfg.env.device),
            (cfg.evaluation.episodes * step_bytes,
             f"evaluation.episodes={cfg.evaluation.episodes} ({step_bytes} bytes per world)",
             "evaluation.episodes", cfg.env.device),
        ]
        if "buffer_size" in a:  # flat per-drone transitions: observation, next observation, action, reward, flags
            per = 4 * (2 * obs_dim + max(1, probe.actions.dim if probe.actions.continuous else 1) + 3)
            needs.append((a.buffer_size * per, f"algo.buffer_size={a.buffer_size} ({per} bytes per transition)",
                          "algo.buffer_size", a.get("buffer_device") or cfg.env.device))
    check_fits(needs)


GAME_BYTES = 16  # a lower bound of what one played game keeps: its outcome in the list, the string and the JSON


def check_play(cfg, games: int, pairs: int, batch: int, key: str = "games") -> None:
    """Refuse ``games`` per pair for ``pairs`` pairs in batches of ``batch`` worlds that cannot fit in
    memory, before any game is played: each side's env holds a batch, and every game's outcome is kept
    (for Elo's rounds and the results file). ``key`` is the option that gave ``games``."""
    probe = make_env(cfg, num_envs=1, seed=0)
    step = _step_bytes(probe)
    worlds = 2 * min(batch, games)
    check_fits([
        (worlds * step, f"batch={batch} ({step} bytes per world, one env of a batch per side)", "batch", cfg.env.device),
        (games * pairs * GAME_BYTES, f"{key}={games} x {pairs} pair(s) ({GAME_BYTES} bytes per game kept)", key, "cpu"),
    ])


# Elo steps through its games one at a time in Python (each step updates every order at once): a bound
# on the games keeps a run to about a minute, and one on the updates keeps the orders' arrays and time sane
ELO_MAX_GAMES = 10**7
ELO_MAX_UPDATES = 10**9


def check_rounds(rounds: int, n: int, orders: int = 1) -> None:
    """Refuse Elo over ``rounds`` round robins of ``n`` competitors (and ``orders`` further orders of
    them) that is more work than ``ELO_MAX_GAMES`` / ``ELO_MAX_UPDATES``, or whose games, rating
    history (float64, one row per game) and orders' schedules cannot fit in memory."""
    pairs = n * (n - 1) // 2
    games = rounds * pairs
    if games > ELO_MAX_GAMES:
        raise ConfigError(f"rounds={rounds} x {pairs} pair(s) is {games:,} Elo games; the bound is {ELO_MAX_GAMES:,}: lower rounds")
    if games * orders > ELO_MAX_UPDATES:
        raise ConfigError(f"rounds={rounds} x {pairs} pair(s) x orders={orders} is {games * orders:,} Elo updates; the bound is "
                          f"{ELO_MAX_UPDATES:,}: lower orders or rounds")
    per = 8 * (n + 3) + 24 * orders  # each order's schedule: the two players and the score of every game
    check_fits([(games * per, f"rounds={rounds} x {pairs} pair(s) x orders={orders} ({per} bytes per game)", "rounds or orders", "cpu")])


def check_fits(needs) -> None:
    """``needs``: (bytes, what needs them, the keys to lower, device); their sums per device must fit."""
    per_device: dict[str, int] = {}
    for n, _, _, device in needs:
        per_device[str(device)] = per_device.get(str(device), 0) + n
    for device, total in per_device.items():
        free = available_memory(device)
        if free is not None and total > free:
            n, what, keys, _ = max((x for x in needs if str(x[3]) == device), key=lambda x: x[0])
            raise ConfigError(
                f"{what} needs at least {_gib(n)} of memory but {device} has {_gib(free)} available; lower {keys}"
            )


def available_memory(device) -> int | None:
    """Bytes that can still be allocated on ``device`` (RAM plus free swap for the CPU); None if unknown."""
    import torch

    dev = torch.device(device)
    if dev.type == "cuda":
        return int(torch.cuda.mem_get_info(dev)[0])
    if dev.type != "cpu":
        return None
    try:
        import psutil
    except ImportError:
        return None
    return int(psutil.virtual_memory().available + psutil.swap_memory().free)


def _gib(n: int) -> str:
    return f"{n / 2**30:,.1f} GiB"


def _step_bytes(probe) -> int:
    """The bytes of one step of a one-world ``probe`` env (closed afterwards): the tensordict of
    observations, actions, rewards, flags and statistics that a batch holds per world and step."""
    n = int(probe.rand_step(probe.reset()).bytes())
    close = getattr(probe.physics, "close", None)
    if close is not None:
        close()
    return n


def check_bench_options(options: dict) -> dict:
    """The ``volleybots bench`` options ``options`` checked (types, names, ranges, memory) and as
    plain values; raises ``ConfigError`` naming the first bad one. Only the given keys are returned."""

    from volleybots.physics import ACTION_SPACES, BACKENDS
    from volleybots.tasks import TASKS

    lists = ("tasks", "backends", "num_envs", "devices")
    data = {k: (v if isinstance(v, list) or k not in lists else [v]) for k, v in options.items()}
    for k in lists:
        if data.get(k) == []:
            raise ConfigError(f"bad value for {k!r}: an empty list measures nothing")
    typed = _typed(BenchOptions, data, "")
    check_values(BenchOptions, typed, "")
    out = {k: to_dict(typed)[k] for k in data}
    for key, allowed in (("tasks", sorted(TASKS)), ("backends", list(BACKENDS)), ("action_space", list(ACTION_SPACES))):
        given = out.get(key)
        for v in given if isinstance(given, list) else [given] if given is not None else []:
            if v not in allowed:
                raise ConfigError(f"unknown {key} {v!r}; allowed: {', '.join(allowed)}")
    comp = out.get("compile")
    if comp is not None and not all(isinstance(c, bool) for c in (comp if isinstance(comp, list) else [comp])):
        raise ConfigError(f"bad value for 'compile': {comp!r} (must be true, false or a list of them)")
    for d in out.get("devices") or ():
        check_device("devices", d)
    n = max(out.get("num_envs") or [1])
    for task in out.get("tasks") or ["solo_bump"]:
        step_bytes = _step_bytes(build_env(task, num_envs=1, action_space=out.get("action_space", "prt")))
        what = f"num_envs={n} ({task}, {step_bytes} bytes per world)"
        check_fits([(n * step_bytes, what, "num_envs", d) for d in out.get("devices") or ["cpu"]])
    return out


__all__ = [
    "BenchOptions", "GAME_BYTES", "available_memory", "check_bench_options", "check_fits", "check_memory", "check_play", "check_rounds",
]
