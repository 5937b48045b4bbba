"""Competitors: whatever can play one side of a match (docs/evaluation.md, docs/competitive.md).

A competitor is ``scripted``, ``random``, ``hierarchical`` (3v3 only: drills under an event-driven high
level, ``volleybots.scripted.hierarchical``; a ``*.yaml`` file ``hierarchical: {drill: checkpoint}``
gives it trained drills), a checkpoint file, a run directory (its final policy), a
population run (its members and final meta-strategy) or a zoo entry (a zoo mixture: its members and
weights); ``name=PATH`` gives it a label. Its
``team_policy(env)`` acts for one team: it reads a team's ``("agents", "observation")`` [N, A_t]
(already mirrored, so one policy plays either side) and writes ``("agents", "action")``. A competitor
of several members draws one member per env each time that env's episode starts (``TeamPolicies``
calls ``begin_episodes``), so one batch mixes opponents as the meta-strategy says.

This module sits below ``play`` (games), ``train`` (opponents of a learner), ``population`` (members)
and ``eval`` (cross-play): all read competitors from here.

Population run layout (written by ``volleybots.population``): ``population/member_<k>.pt`` (a
checkpoint of one member, or a record naming ``scripted`` / ``random``), ``population/meta.jsonl``
(one mixture per line, the last is the final meta-strategy).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Callable

import torch
from tensordict import TensorDictBase

from volleybots import zoo
from volleybots.algos.population import method_name
from volleybots.errors import ConfigError
from volleybots.keys import ACTION, AGENTS
from volleybots.policies.builtin import BUILTIN, HIERARCHICAL_TASK, PLAYERS, acted, hierarchical_policy, read_drills_file
from volleybots.policies.foreign import TORCHSCRIPT, CallablePolicy, import_target, load_sb3, load_torchscript
from volleybots.policies.store import load_learner, parse_single, parse_spec, saved_config, sha256, split_mixture
from volleybots.runs import (
    META_FILE,
    POPULATION_DIR,
    is_population_run,
    member_path,
    population_members,
    read_checkpoint,
    read_metas,
    read_population,
    run_policy_checkpoint,
)
from volleybots.tasks import plays_as


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
            if m.task is not None and plays_as(m.task) != plays_as(task):
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
            return acted(self.policies[0], td)
        action = None
        for k, policy in enumerate(self.policies):
            a = acted(policy, td.clone(recurse=False).set(AGENTS, td.get(AGENTS).clone(recurse=False))).get(ACTION)
            pick = (self.choice == k).reshape(-1, *([1] * (a.dim() - 1)))
            action = a if action is None else torch.where(pick, a, action)
        td.set(ACTION, action)
        return td



class AssignedPolicy:
    """Acts for one team with a fixed member per block of envs, never redrawn: envs ``[k * per, (k + 1) * per)``
    play ``policies[k]`` (a payoff row plays one competitor against every member at once, each member in
    its own envs). A member that keeps nothing per env (``stateless``: a trained network) acts on its own
    envs alone; one that does (a scripted player keeps state for every env of the batch it was made
    for) acts on the whole batch, and its block of actions is kept."""

    def __init__(self, policies: list[Callable], per: int, stateless: list[bool]):
        self.policies, self.per, self.stateless = policies, per, stateless

    def __call__(self, td: TensorDictBase) -> TensorDictBase:
        parts = []
        for k, (policy, alone) in enumerate(zip(self.policies, self.stateless)):
            block = slice(k * self.per, (k + 1) * self.per)
            if alone:
                parts.append(acted(policy, td[block]).get(ACTION))
            else:
                whole = td.clone(recurse=False).set(AGENTS, td.get(AGENTS).clone(recurse=False))
                parts.append(acted(policy, whole).get(ACTION)[block])
        td.set(ACTION, torch.cat(parts, 0))
        return td


def hierarchical_member(drills: dict | None = None, label: str = "hierarchical") -> Member:
    """The hierarchical team as a member; its source names the drills' checkpoints (with hashes)."""
    drills = {k: str(v) for k, v in (drills or {}).items()}
    files = {k: {"path": v, "sha256": sha256(v)} for k, v in drills.items() if Path(v).is_file()}
    source = {"kind": "hierarchical", "drills": drills, "drill_files": files}
    return Member(label, lambda env, deterministic=False: hierarchical_policy(env, drills), source, HIERARCHICAL_TASK)


def builtin_member(name: str, drills: dict | None = None) -> Member:
    """A member of ``volleybots.policies.builtin.PLAYERS`` (the hierarchical team with ``drills``)."""
    if name == "hierarchical":
        return hierarchical_member(drills)
    player = PLAYERS[name]
    return Member(name, lambda env, deterministic=False: player.team(env), {"kind": name}, player.task)


# ------------------------------------------------------------------------------- trained policies
def checkpoint_member(path, label: str | None = None) -> Member:
    """A member from a checkpoint file: a run's checkpoint or a population member (``member_<k>.pt``,
    which may also name a built-in player). Its networks are built by the policy store when it plays."""
    path = Path(path)
    state = read_checkpoint(path)
    if "builtin" in state:
        if state["builtin"] not in PLAYERS:
            raise ConfigError(f"{str(path)!r} names an unknown built-in player {state['builtin']!r}; allowed: {', '.join(BUILTIN)}")
        m = builtin_member(state["builtin"], member_files(path, state.get("drills")))
        m.label = label or m.label
        return m
    cfg = saved_config(state, f"checkpoint {str(path)!r}")
    n_agents = int(state["n_agents"])

    def make(env, deterministic: bool = False):
        return load_learner(path, env, n_agents)[0].policy(deterministic=deterministic)

    method = method_name(cfg)  # a population member's is its population method's, as before population= was a group
    source = {"kind": "checkpoint", "path": str(path), "sha256": sha256(path), "frames": int(state["frames"]), "algo": method}
    label = label or f"{method}@{int(state['frames'])}"
    return Member(label, make, source, cfg.task.name, cfg.env.action_space, int(state["obs_dim"]))


def member_files(path: Path, drills) -> dict | None:
    """A hierarchical member's files (drill -> checkpoint, ``high_level``) with the paths a population
    run writes relative to the member's own folder made whole; a file it names that is not there is one
    ``ConfigError`` line (a member is played whole or not at all)."""
    if drills is None:
        return None
    if not isinstance(drills, dict) or not all(isinstance(k, str) and isinstance(v, str) and v for k, v in drills.items()):
        raise ConfigError(f"{str(path)!r}: its 'drills' are not a mapping of drill names to files")
    out = {}
    for name, target in drills.items():
        full = Path(target) if Path(target).is_absolute() else path.parent / target
        if not full.exists():
            raise ConfigError(f"{str(path)!r} names its {name} file {str(full)!r}, which does not exist: the member cannot play "
                              "without every file it names")
        out[name] = str(full)
    return out


# ------------------------------------------------------------------------------- a user's policies
def callable_competitor(fn: Callable, label: str = "", numpy: bool = False, task: str | None = None,
                        action_space: str | None = None, obs_dim: int | None = None, source: dict | None = None) -> Competitor:
    """A user's policy as a competitor (``volleybots.policies.foreign`` has the contract).

    Args:
        fn: observations ``[B, obs_dim]`` -> actions ``[B, 4]`` (or ``[B]`` discrete), torch or numpy.
        label: its name in tables (default: the function's name).
        numpy: hand ``fn`` a float32 numpy array instead of a torch tensor.
        task: the task it was made for, if known: a cross-play then refuses a match it does not fit,
            and a cross-play of it and the built-ins alone takes its task.
        action_space: the action space it acts in, if known (checked as ``task`` is).
        obs_dim: the observation size it takes, if known (checked as ``task`` is).
        source: its provenance in results files (default: kind ``callable`` and the function's name).

    Returns:
        A ``Competitor`` of one member; its ``team_policy(env)`` acts for one team of ``env``.
    """
    if not callable(fn):
        raise ConfigError(f"a callable competitor needs a function of the observation batch, got {type(fn).__name__}")
    if not isinstance(numpy, bool):
        raise ConfigError(f"numpy must be True or False, got {numpy!r}")
    name = label or getattr(fn, "__name__", type(fn).__name__)
    source = source or {"kind": "callable", "name": f"{getattr(fn, '__module__', '?')}.{getattr(fn, '__qualname__', name)}"}

    # ``deterministic`` is the user's to decide inside fn: a plain function acts one way only
    def make(env, deterministic: bool = False):
        return CallablePolicy(fn, env, name, numpy)

    return Competitor(name, [Member(name, make, source, task, action_space, obs_dim)])


def import_competitor(spec: str, label: str = "") -> Competitor:
    """The competitor a ``module:function`` spec names: a function (torch in, as ``callable_competitor``)
    or a ``Competitor`` the module built (with ``callable_competitor``, for numpy input or a task)."""
    obj = import_target(spec)
    if isinstance(obj, Competitor):
        return replace(obj, label=label) if label else obj
    if not callable(obj):
        raise ConfigError(f"competitor {spec!r} is a {type(obj).__name__}; expected a function of the observation batch or a Competitor")
    return callable_competitor(obj, label or spec, source={"kind": "import", "spec": spec})


def exported_competitor(path, label: str = "", kind: str = "torchscript") -> Competitor:
    """A policy exported to a file as a competitor: a TorchScript module (``torch.jit.save``, ``forward(obs
    [B, obs_dim]) -> actions``) or, with ``kind="sb3"``, a model saved by Stable-Baselines3; a file of
    another kind is one ``ConfigError`` line. Known by its sha256 in results files, as a checkpoint is."""
    path = str(path)
    module = load_torchscript(path) if kind == "torchscript" else load_sb3(path)
    return callable_competitor(module, label or Path(path).stem, obs_dim=getattr(module, "obs_dim", None),
                               source={"kind": kind, "path": path, "sha256": sha256(path)})


def torchscript_competitor(path, label: str = "") -> Competitor:
    """A TorchScript module (``torch.jit.save``) as a competitor (``exported_competitor``)."""
    return exported_competitor(path, label, "torchscript")


def read_meta(run_path: Path) -> list[list[float]]:
    """Every meta-strategy a population run wrote, oldest first (each line checked)."""
    return [m["mixture"] for m in read_metas(run_path)]


def resolve_competitor(spec: str) -> Competitor:
    """``scripted``, ``random``, ``hierarchical``, a checkpoint, a run dir, a population run, a zoo entry,
    a user's ``module:function`` or ``torchscript:FILE`` (``volleybots.policies.foreign``)
    or a hierarchical team's drills file (``*.yaml``: ``hierarchical: {drill: checkpoint}``); ``name=PATH``
    labels it; ``A+B`` or ``A*3+B`` mixes competitors (the grammar of ``volleybots.policies.store.parse_spec``)."""
    mix = split_mixture(spec)
    if mix is not None:
        return mixed(*mix)
    s = parse_spec(spec)
    if s.kind == "builtin":
        return Competitor(s.label or s.target, [builtin_member(s.target)])
    if s.kind == "drills":
        label = s.label or s.zoo or s.path.stem
        return Competitor(label, [hierarchical_member(read_drills_file(s.path), label)])
    if s.kind == "import":
        return import_competitor(s.target, s.label)
    if s.kind in ("torchscript", "sb3"):
        return exported_competitor(s.target, s.label, s.kind)
    if s.kind == "checkpoint":
        m = checkpoint_member(s.path)
        return Competitor(s.label or s.zoo or m.label, [m])
    if s.kind == "mixture":  # members labelled <method>/<member>, as their files are named in the card
        e = zoo.lookup(s.target)
        ms = [checkpoint_member(p, f"{p.parent.name}/{p.stem}") for p in e.members]
        return Competitor(s.label or s.zoo, ms, list(e.weights))
    path = s.path
    if is_population_run(path):  # exactly its last complete iteration, or refused (runs.contents)
        pop = read_population(path, f"run {s.target!r}")
        ms = [checkpoint_member(p, f"{path.name}/{p.stem}") for p in pop.members]
        return Competitor(s.label or path.name, ms, pop.mixture)
    ckpt = run_policy_checkpoint(path, f"run {s.target!r}")
    return Competitor(s.label or path.name, [checkpoint_member(ckpt, path.name)])


def mixed(label: str, parts: list[tuple[str, float]]) -> Competitor:
    """One competitor ``label`` of ``parts`` (spec, weight): every member of each, a population's
    meta-strategy scaled by its part's weight; a one-policy part's member carries the part's label."""
    members, weights = [], []
    for spec, w in parts:
        c = resolve_competitor(spec)
        members += [replace(m, label=c.label) for m in c.members] if len(c.members) == 1 else c.members
        weights += [w * float(x) for x in c.mixture]
    return Competitor(label, members, weights)


def single_policy(spec: str, what: str) -> Competitor:
    """The competitor ``spec`` names where one policy must play (``population.seed_members``): a population
    run or a zoo mixture is one ``ConfigError`` line."""
    parse_single(spec, what)
    comp = resolve_competitor(spec)
    if len(comp.members) != 1:
        raise ConfigError(f"{what} {spec!r} is a population of {len(comp.members)} policies; name single policies (its member files)")
    return comp


__all__ = [
    "META_FILE", "POPULATION_DIR", "TORCHSCRIPT", "AssignedPolicy", "Competitor", "Member", "MixturePolicy", "builtin_member",
    "callable_competitor", "checkpoint_member", "exported_competitor", "hierarchical_member", "import_competitor", "member_path",
    "population_members", "read_meta", "resolve_competitor", "single_policy", "torchscript_competitor",
]
