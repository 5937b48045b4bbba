"""A payoff row's chunks of games (``volleybots.play.rows``): here one after another, or as tasks of a Ray pool.

A chunk's games draw their random numbers from the chunk's own seed, so its W/D/L counts do not
depend on where or in which order it is played: the pool changes the wall time, never the results.
``ray`` connects to the cluster named by ``RAY_ADDRESS`` (``ray start --head`` prints it), joins the
cluster of the Ray task it runs in (a sweep job of ``hydra/launcher=ray``), or else starts a local
Ray instance for the rest of the process.
"""

from __future__ import annotations

import importlib.util
import os
import socket

from volleybots.algos.population import POOLS
from volleybots.config import to_dict, validate
from volleybots.errors import ConfigError
from volleybots.play.games import DEFAULT_BATCH
from volleybots.play.rows import play_row_chunk, row_chunks

EXTRA = "cluster"  # pip install 'volleybots[cluster]' installs ray
RAY_CONNECT_S = 10.0  # a cluster's head answers at once; nothing after this long means none is there


def check_pool(pool: str, key: str) -> None:
    """Raise ``ConfigError`` for an unknown pool, ``ray`` where ray is not installed, or a
    ``RAY_ADDRESS`` at which no cluster answers."""
    if pool not in POOLS:
        raise ConfigError(f"unknown {key} {pool!r}; allowed: {', '.join(POOLS)}")
    if pool == "ray" and importlib.util.find_spec("ray") is None:
        raise ConfigError(f"{key}=ray needs the ray package: pip install 'volleybots[{EXTRA}]' (or use {key}=serial)")
    if pool == "ray":
        check_ray_address(key)


def check_ray_address(key: str) -> None:
    """Refuse a ``RAY_ADDRESS`` (``host:port`` or ``ray://host:port``) at which nothing answers within
    ``RAY_CONNECT_S``: ``ray.init`` would wait on it for minutes, silent. ``auto`` and unset are Ray's."""
    addr = os.environ.get("RAY_ADDRESS", "").strip()
    if addr == "auto":  # Ray's own lookup of a running cluster: with none, ray.init raises ConnectionError later
        addr = _running_cluster(key)
    if addr in ("", "auto", "local"):
        return
    host, _, port = addr.removeprefix("ray://").rpartition(":")
    if not host or not port.isdigit() or not 0 < int(port) < 65536:
        raise ConfigError(f"RAY_ADDRESS={addr!r} is not host:port, ray://host:port or auto (what `ray start --head` prints)")
    try:
        socket.create_connection((host.strip("[]"), int(port)), timeout=RAY_CONNECT_S).close()
    except OSError as e:
        raise ConfigError(f"RAY_ADDRESS={addr!r}: no Ray cluster answers there within {RAY_CONNECT_S:g} s ({e.strerror or e}); "
                          f"start one with `ray start --head`, unset RAY_ADDRESS for a local one, or use {key}=serial") from None


def _running_cluster(key: str) -> str:
    """The address of the cluster ``RAY_ADDRESS=auto`` finds (``ray start --head`` leaves it on this
    machine); ``auto`` where this Ray cannot say (a private function of Ray's, so it may change)."""
    try:
        from ray._private.services import canonicalize_bootstrap_address
    except ImportError:
        return "auto"
    try:
        return canonicalize_bootstrap_address("auto") or "auto"
    except ConnectionError:
        raise ConfigError(f"RAY_ADDRESS=auto but no Ray cluster runs on this machine; start one with `ray start --head`, "
                          f"unset RAY_ADDRESS for a local one, or use {key}=serial") from None


def payoff_row(cfg, a, opponents: list, games: int, seed: int, pool: str = "serial", batch: int = DEFAULT_BATCH) -> list:
    """[3] wins, draws, losses of ``a`` against each of ``opponents``, ``games`` each, in order; the chunk
    of opponents from index ``j`` on plays on seed ``seed + j``."""
    chunks = [(a, [opponents[j] for j in r], games, seed + r.start) for r in row_chunks(len(opponents), games, batch)]
    if pool == "serial" or not chunks:
        return [w for c in chunks for w in play_row_chunk(cfg, *c)]
    check_pool(pool, "pool")
    import ray

    if not ray.is_initialized():
        ray.init(address=os.environ.get("RAY_ADDRESS"), include_dashboard=False, log_to_driver=False)
    task = ray.remote(num_cpus=1)(_chunk)
    data = ray.put(to_dict(cfg))
    return [w for part in ray.get([task.remote(data, os.getcwd(), *c) for c in chunks]) for w in part]


def pool_map(fn, cfg, calls: list[tuple], pool: str = "serial", key: str = "pool"):
    """``fn(cfg, *call)`` for each of ``calls``, yielded in the calls' order: here one after another, or
    as Ray tasks running together (each in its own worker, one torch thread). ``fn`` must draw its
    random numbers from its arguments alone, so that where it runs changes the wall time, never the
    results (cross-play pairs: each plays on the table's seed)."""
    if pool == "serial":
        for call in calls:
            yield fn(cfg, *call)
        return
    check_pool(pool, key)
    import ray

    if not ray.is_initialized():
        ray.init(address=os.environ.get("RAY_ADDRESS"), include_dashboard=False, log_to_driver=False)
    task = ray.remote(num_cpus=1)(_call)
    data = ray.put(to_dict(cfg))
    refs = [task.remote(fn, data, os.getcwd(), *call) for call in calls]
    for ref in refs:
        yield ray.get(ref)


def start_workers(cls, cfg, inits: list[tuple], pool: str = "serial", key: str = "pool") -> list:
    """Stateful workers ``cls(cfg, *init)``, one per ``inits``: objects here, or Ray actors (each in its own
    process, one torch thread, spread over the cluster's nodes) for ``pool=ray``. ``call_workers`` calls
    them alike; ``stop_workers`` ends the actors. A worker must draw its random numbers from its own
    state alone, so that where it runs changes the wall time, never the results."""
    if pool == "serial":
        return [cls(cfg, *init) for init in inits]
    check_pool(pool, key)
    import ray

    if not ray.is_initialized():
        ray.init(address=os.environ.get("RAY_ADDRESS"), include_dashboard=False, log_to_driver=False)
    # Ray's default actor resources: one CPU to be placed, none held while it runs, so more workers than
    # the cluster's CPUs still all start (with num_cpus=1 the ones beyond would wait for ever)
    actor = ray.remote(_Worker).options(scheduling_strategy="SPREAD")
    data = ray.put(to_dict(cfg))
    return [actor.remote(cls, data, os.getcwd(), *init) for init in inits]


def call_workers(workers: list, method: str, calls: list[tuple]) -> list:
    """``worker.method(*call)`` for each worker and its call, all at once on Ray; the results in order."""
    if workers and _is_actor(workers[0]):
        import ray

        return ray.get([w.call.remote(method, *c) for w, c in zip(workers, calls)])
    return [getattr(w, method)(*c) for w, c in zip(workers, calls)]


def stop_workers(workers: list) -> None:
    """End the Ray actors among ``workers`` (objects here are left to the garbage collector)."""
    for w in workers:
        if _is_actor(w):
            import ray

            ray.kill(w)


def _is_actor(worker) -> bool:
    """A Ray actor's handle (its methods are called with ``.remote``), not an object here."""
    return hasattr(getattr(worker, "call", None), "remote")


class _Worker:
    """A worker of ``start_workers`` inside a Ray actor: the object, built from the plain config."""

    def __init__(self, cls, cfg: dict, cwd: str, *init):
        _enter(cwd)
        self.obj = cls(validate(cfg), *init)

    def call(self, method: str, *args):
        return getattr(self.obj, method)(*args)


def _enter(cwd: str) -> None:
    """A Ray worker's setting for one call: one torch thread (as Ray's workers run with OMP_NUM_THREADS=1),
    and the driver's working directory where this machine has it, so that a relative path (a run dir
    given to the Python API, and the member and drill files named under it) opens the driver's file:
    Ray's workers start where Ray was started, not where the driver is now (or on another node, which
    needs the run dir at the same path: a shared filesystem)."""
    import torch

    torch.set_num_threads(1)
    if os.path.isdir(cwd):
        os.chdir(cwd)


def _call(fn, cfg: dict, cwd: str, *args):
    """One call of ``pool_map`` in a Ray worker."""
    _enter(cwd)
    return fn(validate(cfg), *args)


def _chunk(cfg: dict, cwd: str, a, opponents: list, games: int, seed: int):
    """One payoff chunk in a Ray worker."""
    _enter(cwd)
    return play_row_chunk(validate(cfg), a, opponents, games, seed)
