"""The policy store: the one place where a checkpoint becomes a policy, and the one grammar for naming
what plays.

``load_policy(path, env)`` reads a checkpoint (``weights_only=True``), rebuilds the learner it was
saved from (a population preset's learner where the run was one) for ``env``'s agents, loads its
weights and returns its acting function. Loaded networks are kept per file content (sha256), device and
agent shape, so a cross-play of several runs builds each network once however many pairs and sides it
plays, and a file changed on disk is read again.

The grammar (``parse_spec``), used by ``eval``, ``replay``, ``eval crossplay``, ``opponent=``,
``population.seed_members`` and ``init=``::

    scripted | receiver | random | hierarchical
                                         a built-in player (``volleybots.policies.builtin.PLAYERS``)
    PATH.pt                              a checkpoint file (a run's, or a population member)
    RUN_DIR                              a run: its population (members and final mixture) if it is a
                                         population run, else its final (else latest) checkpoint
    PATH.yaml                            a hierarchical team with trained drills: ``hierarchical: {drill: checkpoint}``
    zoo:TASK/METHOD                      a policy shipped in the package (``volleybots.zoo``), or a shipped
                                         mixture of policies (a population's meta-strategy)
    MODULE:FUNCTION                      a user's policy in their own importable code (``volleybots.policies.foreign``)
    torchscript:FILE                     a user's policy saved with ``torch.jit.save``
    sb3:FILE.zip                         a PPO / A2C model saved by Stable-Baselines3 (loaded without unpickling)
    NAME=any of the above                the same, labelled NAME
    A+B[+...]                            where a competitor plays (``opponent=``, ``eval crossplay``): a mixture,
                                         one of A, B, ... drawn for each episode, uniformly ...
    A*3+B                                ... or with these relative weights (1 where none is given); a population in
                                         it counts with its own meta-strategy times its weight
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import torch

from volleybots import zoo
from volleybots.errors import ConfigError
from volleybots.files import exists, sha256
from volleybots.overrides import split_arg
from volleybots.policies.foreign import SB3, TORCHSCRIPT, is_import_spec
from volleybots.runs import RunDir, load_algo_state, read_checkpoint, refuse_interpolation, run_policy_checkpoint

MIX, WEIGHT = "+", "*"  # A+B, A*3+B: a mixture of competitors (a path holding them is that path)
KINDS = ("builtin", "checkpoint", "run", "drills", "mixture", "import", "torchscript", "sb3")
# (sha256, device, n_agents, obs_dim, action_space) -> the learner with its weights loaded; shared safely because
# acting never changes a learner (observation statistics move only in ``update``)
_CACHE: dict[tuple, object] = {}
# the names of volleybots.policies.builtin.PLAYERS (which imports this module; tests/tasks/test_receive.py keeps the two equal)
BUILTIN_NAMES = ("scripted", "receiver", "random", "hierarchical")
_CACHE_SIZE = 64  # distinct networks kept; a cross-play of many populations still fits in a few hundred MB


@dataclass(frozen=True)
class Spec:
    """A parsed name of what plays."""

    label: str  # the given label, or "" (the caller derives one)
    kind: str  # one of KINDS
    target: str  # the built-in's name, the path as given (a zoo entry's file), or a zoo mixture's name
    zoo: str = ""  # the zoo name it was given as ("zoo:TASK/METHOD"), which labels it when no label is given

    @property
    def path(self) -> Path:
        return Path(self.target)


def parse_spec(spec: str, builtins=BUILTIN_NAMES, what: str = "competitor") -> Spec:
    """Split ``[NAME=]TARGET`` and say what TARGET is; a missing file is one ``ConfigError`` line."""
    label, target = split_arg(spec)
    if target is None or exists(str(spec)):  # a path whose name holds '=' is that path, not NAME=PATH
        label, target = "", str(spec)
    allowed = f"a run dir, a checkpoint file, or one of: {', '.join(builtins)}"
    if not target.strip():
        raise ConfigError(f"{what} {spec!r} names no policy; expected {allowed}")
    if target in builtins:
        return Spec(label, "builtin", target)
    for prefix, kind in ((TORCHSCRIPT, "torchscript"), (SB3, "sb3")):  # a user's exported policy (volleybots.policies.foreign)
        if target.startswith(prefix):
            return Spec(label, kind, target[len(prefix):])
    if is_import_spec(target):  # a user's own code, imported by module name
        return Spec(label, "import", target)
    if target.startswith(zoo.PREFIX):
        entry = zoo.lookup(target)
        if entry is None:
            shipped = ", ".join(zoo.PREFIX + n for n in zoo.entries()) or "none in this install"
            raise ConfigError(f"{what} {target!r} is not in the zoo; shipped: {shipped}")
        if entry.is_mixture:
            return Spec(label, "mixture", target, zoo=target)
        if entry.is_team:  # the card is the team's file
            return Spec(label, "drills", str(entry.card_file), zoo=target)
        return Spec(label, "checkpoint", str(entry.checkpoint), zoo=target)
    path = Path(target)
    if not exists(path):
        # a very long name is cut in the middle: its end (the file's own name) is what tells it apart
        shown = target if len(target) <= 160 else f"{target[:40]}...{target[-117:]}"
        # NAME=TARGET labels a competitor, so the verbs' option --out DIR mistyped as out=DIR lands here
        named = " (read as a competitor named 'out'; the output folder is --out DIR)" if label == "out" else ""
        raise ConfigError(f"{what} {shown!r} does not exist{named}; expected {allowed}")
    if path.is_file():
        return Spec(label, "drills" if path.suffix in (".yaml", ".yml") else "checkpoint", target)
    if path.is_dir():
        if not RunDir(path).is_run():
            raise ConfigError(f"{target!r} is not a run directory (no config.yaml) nor a checkpoint file")
        return Spec(label, "run", target)
    raise ConfigError(f"{what} {target!r} does not exist; expected {allowed}")


def split_mixture(spec: str) -> tuple[str, list[tuple[str, float]]] | None:
    """``(label, [(part, weight), ...])`` of ``[NAME=]A+B`` or ``[NAME=]A*3+B`` (relative weights, 1 where
    none is given), the weights scaled to sum to 1, the label NAME or else the mixture as written; None
    where ``spec`` names one competitor (no ``+``, or an existing path that holds one)."""
    spec = str(spec)
    if MIX not in spec or exists(spec):
        return None
    label, target = split_arg(spec)
    if target is None or MIX not in target or exists(target):  # the '=' belongs to a part (B=PATH), not the whole
        label, target = "", spec
    parts, weights = [], []
    for raw in target.split(MIX):
        name, star, w = raw.rpartition(WEIGHT)
        weight = None
        if star and not exists(raw):
            try:
                weight = float(w)
            except ValueError:
                weight = None
            if weight is None or not 0 < weight < float("inf"):
                raise ConfigError(f"mixture {spec!r}: weight {w!r} of {name!r} is not a positive number; write A*3+B (weighted)")
        parts.append(name if weight is not None else raw)
        weights.append(weight)
    if any(not p.strip() for p in parts):
        raise ConfigError(f"mixture {spec!r} has an empty part; write A+B (uniform) or A*3+B (weighted)")
    weights = [1.0 if w is None else w for w in weights]  # relative: a part without a weight weighs 1
    top = max(weights)
    weights = [w / top for w in weights]  # scaled to at most 1 first: the sum of two weights of 1e308 is inf
    if 0.0 in weights:
        small = parts[weights.index(0.0)]
        raise ConfigError(f"mixture {spec!r}: the weight of {small!r} is too small beside the largest to be drawn in any game")
    return label or target, [(p, w / sum(weights)) for p, w in zip(parts, weights)]


def learner_class(algo_cfg):
    """The class whose networks a checkpoint of the validated ``algo`` config holds (a population's
    learner too: ``validate`` reads an old population config's ``algo.learner``, MAPPO before there was one)."""
    from volleybots.algos import ALGOS

    return ALGOS[algo_cfg.name]


def saved_config(state: dict, what: str):
    """A checkpoint's config, validated (files it names are not opened)."""
    from volleybots.config import validate

    if not isinstance(state.get("config"), dict):
        raise ConfigError(f"{what} is damaged (it holds no config)")
    refuse_interpolation(state["config"], what)
    try:
        return validate(state["config"])
    except ConfigError as e:
        raise ConfigError(f"{what}: its saved config is not valid here ({e})") from None


def build_learner(state: dict, spec, what: str, cfg=None, side: str = "run"):
    """The learner of a checkpoint ``state`` built for ``spec`` (an ``AgentSpec``) with its weights;
    ``cfg`` (default: the saved config) is what the checkpoint is compared with, named ``side``."""
    saved = saved_config(state, what)
    # the initial weights are overwritten at once: drawing them must not move the caller's random
    # stream (a resumed run builds its opponents after restoring that stream)
    with torch.random.fork_rng(devices=[]):
        algo = learner_class(saved.algo)(saved.algo, spec, seed=saved.seed)
    load_algo_state(algo, state, what, cfg if cfg is not None else saved, side=side)
    return algo


def load_learner(path, env, n_agents: int | None = None, cfg=None, side: str = "its config"):
    """The learner saved in checkpoint ``path``, built for ``n_agents`` agents of ``env`` (default: the
    count it was saved with), from the cache when the same file was loaded for the same shape before."""
    from volleybots.algos.base import AgentSpec

    path = Path(path)
    state = read_checkpoint(path)
    if "algo" not in state:
        raise ConfigError(f"{str(path)!r} is a built-in player ({state.get('builtin')}), not a trained policy")
    n = int(n_agents or state.get("n_agents", env.n_drones))
    spec = AgentSpec.of(env, n)
    key = (sha256(path), str(spec.device), n, int(spec.obs_dim), env.action_space_name)
    algo = _CACHE.get(key)
    if algo is None:
        algo = build_learner(state, spec, f"checkpoint {str(path)!r}", cfg, side)
        if len(_CACHE) >= _CACHE_SIZE:
            _CACHE.pop(next(iter(_CACHE)))
        _CACHE[key] = algo
    return algo, state


def load_policy(path, env, deterministic: bool = True, n_agents: int | None = None):
    """A checkpoint's acting function for ``env`` (``td -> td``, writes ``("agents", "action")``)."""
    algo, _ = load_learner(path, env, n_agents)
    return algo.policy(deterministic=deterministic)


def parse_single(spec: str, what: str, builtins=BUILTIN_NAMES) -> Spec:
    """``parse_spec`` where one policy must play (``init=``, a target, ``population.seed_members``): a zoo
    mixture is one ``ConfigError`` line naming its member files, which are what to give instead."""
    mix = split_mixture(spec)
    if mix is not None:
        raise ConfigError(f"{what} {spec!r} is a mixture of {len(mix[1])} competitors, not one policy; name one of them")
    s = parse_spec(spec, builtins, what=what)
    if s.kind == "mixture":
        e = zoo.lookup(s.target)
        raise ConfigError(f"{what} {spec!r} is a zoo mixture of {len(e.members)} policies, not one policy; give one of its member "
                          f"files instead ({', '.join(p.name for p in e.members)} in {e.members[0].parent})")
    return s


def policy_checkpoint(spec: str, what: str, builtins=BUILTIN_NAMES) -> Path:
    """The checkpoint a single-policy name stands for: the file, a zoo entry, or a run's final (else
    latest) one, checked against what the run holds; anything else is one ``ConfigError`` line."""
    s = parse_single(spec, what, builtins)
    if s.kind == "checkpoint":
        return s.path
    if s.kind == "run":
        return run_policy_checkpoint(s.path, f"{what} {s.target!r}")
    raise ConfigError(f"{what} {spec!r} is not a trained policy; expected a run directory or a checkpoint file")


__all__ = [
    "BUILTIN_NAMES", "KINDS", "Spec", "build_learner", "learner_class", "load_learner", "load_policy", "parse_single",
    "parse_spec", "policy_checkpoint", "saved_config", "sha256", "split_mixture",
]
