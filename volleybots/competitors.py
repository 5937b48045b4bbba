"""Competitors: whatever can play one side of a match (spec: evaluation.md, populations.md).

A competitor is ``scripted``, ``random``, ``hierarchical`` (3v3 only: drills under an event-driven high
level, ``volleybots.scripted.hierarchical``; a ``*.yaml`` file ``hierarchical: {drill: checkpoint}``
gives it trained drills), a checkpoint file, a run directory (its final policy) or a
population run (its members and final meta-strategy); ``name=PATH`` gives it a label. Its
``team_policy(env)`` acts for one team: it reads a team's ``("agents", "observation")`` [N, A_t]
(already mirrored, so one policy plays either side) and writes ``("agents", "action")``. A competitor
of several members draws one member per env each time that env's episode starts (``TeamPolicies``
calls ``begin_episodes``), so one batch mixes opponents as the meta-strategy says.

This module sits below ``eval`` (games, cross-play) and ``population`` (opponents of a learner,
members of a population): both read competitors from here, and neither imports the other for it.

Population run layout (written by ``volleybots.population``): ``population/member_<k>.pt`` (a
checkpoint of one member, or a record naming ``scripted`` / ``random``), ``population/meta.jsonl``
(one mixture per line, the last is the final meta-strategy).
"""

from __future__ import annotations

import hashlib
import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

import torch
from tensordict import TensorDictBase

from volleybots.config import ConfigError, validate
from volleybots.runs import RunDir, load_algo_state, read_checkpoint

BUILTIN = ("scripted", "random", "hierarchical")  # hierarchical: 3v3 only (drills under a rule-based high level)
HIERARCHICAL_TASK = "3v3"
POPULATION_DIR = "population"
META_FILE = "meta.jsonl"


def member_path(run_path: Path, k: int) -> Path:
    return Path(run_path) / POPULATION_DIR / f"member_{k:03d}.pt"


def sha256(path: Path) -> str:
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


@dataclass
class Member:
    """One policy: ``make(env, deterministic)`` builds a function acting for one team of ``env``."""

    label: str
    make: Callable[..., Callable[[TensorDictBase], TensorDictBase]]
    source: dict  # provenance: kind, path and sha256 for files
    task: str | None = None  # None: fits any task (scripted, random)
    action_space: str | None = None
    obs_dim: int | None = None


@dataclass
class Competitor:
    label: str
    members: list[Member]
    mixture: list[float] = field(default_factory=lambda: [1.0])

    @property
    def sources(self) -> list[dict]:
        return [m.source for m in self.members]

    def check_fits(self, task: str, action_space: str, obs_dim: int) -> None:
        """Raise ``ConfigError`` unless every member was made for this task and action space."""
        for m in self.members:
            if m.task is not None and m.task != task:
                raise ConfigError(f"competitor {self.label!r} plays task {m.task!r}, not {task!r}")
            if m.action_space is not None and m.action_space != action_space:
                raise ConfigError(f"competitor {self.label!r} acts in env.action_space={m.action_space!r}, not {action_space!r}")
            if m.obs_dim is not None and m.obs_dim != obs_dim:
                raise ConfigError(f"competitor {self.label!r} sees observations of size {m.obs_dim}, the task gives {obs_dim}")

    def team_policy(self, env, deterministic: bool = False, generator: torch.Generator | None = None) -> "MixturePolicy":
        """A policy for one team of ``env`` (frozen policies act stochastically unless told)."""
        return MixturePolicy([m.make(env, deterministic) for m in self.members], self.mixture, env.num_envs, env.device, generator)


class MixturePolicy:
    """Acts for one team with one member per env, drawn from ``mixture`` when the env's episode starts.

    Every member acts on the whole batch each step (a stateful scripted member then sees unbroken
    episodes) and each env keeps the action of its own member."""

    def __init__(self, policies: list[Callable], mixture, num_envs: int, device, generator: torch.Generator | None = None):
        self.policies = policies
        self.mixture = torch.as_tensor(mixture, dtype=torch.float64)
        if len(self.mixture) != len(policies) or not torch.isclose(self.mixture.sum(), torch.tensor(1.0, dtype=torch.float64)):
            raise ValueError(f"a mixture over {len(policies)} members must have as many weights summing to 1, got {mixture}")
        self.generator = generator
        # drawn only when episodes start (a fresh env batch starts them all), so a resumed run draws
        # exactly what an uninterrupted one does after the same reset
        self.choice = torch.zeros(num_envs, dtype=torch.long, device=device)

    def begin_episodes(self, starts: torch.Tensor) -> None:
        n = int(starts.sum())
        if n and len(self.policies) > 1:
            draw = torch.multinomial(self.mixture.float(), n, replacement=True, generator=self.generator)
            self.choice[starts] = draw.to(self.choice.device)

    def __call__(self, td: TensorDictBase) -> TensorDictBase:
        if len(self.policies) == 1:
            return _acted(self.policies[0], td)
        action = None
        for k, policy in enumerate(self.policies):
            a = _acted(policy, td.clone(recurse=False).set("agents", td.get("agents").clone(recurse=False))).get(("agents", "action"))
            pick = (self.choice == k).reshape(-1, *([1] * (a.dim() - 1)))
            action = a if action is None else torch.where(pick, a, action)
        td.set(("agents", "action"), action)
        return td


def _acted(policy, td: TensorDictBase) -> TensorDictBase:
    out = policy(td)
    if isinstance(out, torch.Tensor):  # scripted players may return the action tensor
        td.set(("agents", "action"), out)
        return td
    return td if out is None else out


# ------------------------------------------------------------------------------- the built-ins
def random_policy(env) -> Callable[[TensorDictBase], TensorDictBase]:
    """Uniform actions for whichever agents the tensordict holds (one team or all)."""
    acts = env.actions

    def act(td: TensorDictBase) -> TensorDictBase:
        n, a = td.get("agents").batch_size
        if acts.continuous:
            action = torch.rand(n, a, acts.dim, device=td.device) * 2 - 1
        else:
            action = torch.randint(0, acts.n, (n, a), device=td.device)
        td.set(("agents", "action"), action)
        return td

    return act


def scripted_policy(env, action_space: str) -> Callable[[TensorDictBase], TensorDictBase]:
    """The task's scripted model-based player (``volleybots.scripted``), as a ``td -> td`` policy."""
    from volleybots.scripted import make_scripted_policy

    try:
        pol = make_scripted_policy(env, action_space)
    except (ValueError, KeyError) as e:
        raise ConfigError(f"no scripted policy for task {env.name!r} with env.action_space={action_space!r}: {e}") from None
    return lambda td: _acted(pol, td)


def hierarchical_policy(env, drills: dict | None = None) -> Callable[[TensorDictBase], TensorDictBase]:
    """The hierarchical 3v3 team (``volleybots.scripted.hierarchical``): scripted drills, or the
    trained checkpoints of ``drills`` (drill name -> checkpoint file or run dir). **Decision:** trained
    drills act on their mean, also where the competitor is asked for sampled play: a drill is a skill
    under the high level, whose own randomness is the attack's side (a Pass clone, seed 0, 100
    episodes: 0.41 success on its mean, 0.24 sampling its Gaussian); the scripted drills are
    deterministic too."""
    from volleybots.scripted.hierarchical import make_hierarchical

    try:
        return make_hierarchical(env, drills, deterministic=True)
    except ValueError as e:
        raise ConfigError(f"competitor 'hierarchical': {e}") from None


def hierarchical_member(drills: dict | None = None, label: str = "hierarchical") -> Member:
    """The hierarchical team as a member; its source names the drills' checkpoints (with hashes)."""
    drills = {k: str(v) for k, v in (drills or {}).items()}
    files = {k: {"path": v, "sha256": sha256(v)} for k, v in drills.items() if Path(v).is_file()}
    source = {"kind": "hierarchical", "drills": drills, "drill_files": files}
    return Member(label, lambda env, deterministic=False: hierarchical_policy(env, drills), source, HIERARCHICAL_TASK)


def builtin_member(name: str, drills: dict | None = None) -> Member:
    if name == "random":
        return Member("random", lambda env, deterministic=False: random_policy(env), {"kind": "random"})
    if name == "hierarchical":
        return hierarchical_member(drills)
    return Member("scripted", lambda env, deterministic=False: scripted_policy(env, env.action_space_name), {"kind": "scripted"})


def read_drills_file(path: Path) -> dict:
    """A hierarchical team's drill checkpoints from a YAML file ``hierarchical: {drill: path}``
    (relative paths are relative to the file)."""
    from omegaconf import OmegaConf

    data = OmegaConf.to_container(OmegaConf.load(path))
    drills = data.get("hierarchical") if isinstance(data, dict) else None
    if not isinstance(drills, dict):
        raise ConfigError(f"{str(path)!r} is no hierarchical team: expected a mapping 'hierarchical: {{drill: checkpoint}}'")
    return {k: str((Path(path).parent / v) if not Path(v).is_absolute() else v) for k, v in drills.items()}


# ------------------------------------------------------------------------------- trained policies
def checkpoint_member(path, label: str | None = None) -> Member:
    """A member from a checkpoint file: a run's checkpoint or a population member (``member_<k>.pt``,
    which may also name a built-in player)."""
    path = Path(path)
    state = read_checkpoint(path)
    if "builtin" in state:
        m = builtin_member(state["builtin"], state.get("drills"))
        m.label = label or m.label
        return m
    cfg = validate(state["config"])
    what = f"checkpoint {str(path)!r}"

    def make(env, deterministic: bool = False):
        from volleybots.algos import ALGOS
        from volleybots.algos.base import AgentSpec

        algo_cls = ALGOS[cfg.algo.name]
        learner_cls = getattr(algo_cls, "learner_cls", algo_cls)  # a population method's learner
        # the initial weights are overwritten at once: drawing them must not move the caller's
        # random stream (a resumed run builds its opponents after restoring that stream)
        with torch.random.fork_rng(devices=[]):
            algo = learner_cls(cfg.algo, AgentSpec.of(env, int(state["n_agents"])), seed=cfg.seed)
        load_algo_state(algo, state, what, cfg)
        return algo.policy(deterministic=deterministic)

    source = {"kind": "checkpoint", "path": str(path), "sha256": sha256(path), "frames": int(state["frames"]), "algo": cfg.algo.name}
    return Member(label or f"{cfg.algo.name}@{int(state['frames'])}", make, source, cfg.task.name, cfg.env.action_space, int(state["obs_dim"]))


def read_meta(run_path: Path) -> list[list[float]]:
    """Every meta-strategy a population run wrote, oldest first."""
    path = Path(run_path) / POPULATION_DIR / META_FILE
    if not path.is_file():
        return []
    return [json.loads(line)["mixture"] for line in path.read_text().splitlines() if line.strip()]


def population_members(run_path: Path) -> list[Path]:
    return sorted((Path(run_path) / POPULATION_DIR).glob("member_*.pt"))


def resolve_competitor(spec: str) -> Competitor:
    """``scripted``, ``random``, ``hierarchical``, a checkpoint, a run dir, a population run or a
    hierarchical team's drills file (``*.yaml``: ``hierarchical: {drill: checkpoint}``); ``name=PATH`` labels it."""
    label, eq, target = spec.partition("=")
    if not eq:
        label, target = "", spec
    if not target:
        raise ConfigError(f"competitor {spec!r} names no policy; expected a run dir, a checkpoint file, or one of: {', '.join(BUILTIN)}")
    if target in BUILTIN:
        return Competitor(label or target, [builtin_member(target)])
    path = Path(target)
    if path.is_file() and path.suffix in (".yaml", ".yml"):
        return Competitor(label or path.stem, [hierarchical_member(read_drills_file(path), label or path.stem)])
    if path.is_file():
        m = checkpoint_member(path)
        return Competitor(label or m.label, [m])
    if not path.is_dir():
        raise ConfigError(f"competitor {target!r} does not exist; expected a run dir, a checkpoint file, or one of: {', '.join(BUILTIN)}")
    run = RunDir(path)
    if not run.is_run():
        raise ConfigError(f"{target!r} is not a run directory (no config.yaml) nor a checkpoint file")
    members, metas = population_members(path), read_meta(path)
    if members and metas and len(metas[-1]) == len(members):
        ms = [checkpoint_member(p, f"{path.name}/{p.stem}") for p in members]
        return Competitor(label or path.name, ms, metas[-1])
    ckpt = run.policy_checkpoint(f"run {target!r}")
    return Competitor(label or path.name, [checkpoint_member(ckpt, path.name)])


__all__ = [
    "BUILTIN", "Competitor", "Member", "MixturePolicy", "builtin_member", "checkpoint_member", "hierarchical_member",
    "hierarchical_policy", "member_path", "read_drills_file",
    "population_members", "random_policy", "read_meta", "resolve_competitor", "scripted_policy", "sha256",
]
