"""The population presets of the registry: ``sp``, ``fsp``, ``psro_uniform``, ``psro_nash``.

They are one loop (``volleybots.population.loop``); a preset names its three parts: a meta-solver, a
learner (``algo.learner``: MAPPO with a critic over its own team by default, PPO for one drone a side;
HAPPO or MAT on teams of several drones) and its loop settings (``LoopConfig``). ``algo.*`` holds the
learner's keys and the loop's flat, so ``algo.actor_lr=...`` sets the learner's and ``algo.iterations=...``
the loop's; ``Preset.config_class`` joins the two dataclasses. ``is_population`` is the one question
that sends a config to the loop.
"""

from __future__ import annotations

import copy
import functools
from dataclasses import dataclass, field, make_dataclass

from volleybots.algos.base import class_attr
from volleybots.algos.happo import HAPPO
from volleybots.algos.mat import MAT
from volleybots.algos.ppo import MAPPO
from volleybots.errors import ConfigError, ranged
from volleybots.ratings.solvers import SOLVERS  # a leaf module (numpy and scipy only)

CLONE = "bc"  # the run's behaviour clone of the scripted team: a learner_init and a seed_members name
ZOO = "zoo"  # learners fine-tuned from the task's zoo start (ZOO_STARTS), the first member that policy
INITS = ("scratch", "last", CLONE, ZOO)
# algo.start: what a population starts from where algo.learner_init / algo.seed_members are left unset.
# "clone" is the default because learners from scratch do not hit the ball within a default budget:
# a bare `train task=3v3 algo=psro_nash` from scratch ended with the Nash mixture on `random` alone
# "zoo" starts from the package's best learned policy of the task (ZOO_STARTS), with the scripted player
# as a fixed opponent beside the mixture (algo.fixed_opponents): a 1v1 population from the clone stayed
# below scripted (0.39 against it), from dag_rally it keeps the returns the receive work taught;
# "auto": zoo where the task has a zoo start (not for sp), clone elsewhere
STARTS = ("auto", "clone", "scratch", ZOO)
ZOO_STARTS = {"1v1": "zoo:1v1/dag_rally"}
ZOO_FIXED = (["scripted"], 0.5)  # fixed opponents and their share of a zoo start or hierarchical members, where unset
# the learners an oracle may train (algo.learner): those that learn one team of a match with a critic
# over their own team; HAPPO and MAT only where the team has several drones (3v3, 6v6)
LEARNERS = {cls.name: cls for cls in (MAPPO, HAPPO, MAT)}
# algo.members: the policy space of a population. flat: every member one network over the whole team
# (the paper's table 3); hierarchical (3v3): drills under a learned high level, each oracle training a
# high level over the run's drills (the HCSP route, volleybots/population/hierarchical.py); auto:
# hierarchical on 3v3, flat elsewhere (what the headline's targets were met with: docs/competitive.md)
MEMBERS = ("auto", "flat", "hierarchical")
HIERARCHICAL_TASKS = ("3v3",)
POOLS = ("serial", "ray")  # where payoff games are played: here, or as tasks of a Ray pool (volleybots.play.pool)


@dataclass
class LoopConfig:
    """The population loop's own keys (``algo.solver``, ``algo.iterations``, ...); the learner's (``algo.actor_lr``,
    ``algo.hidden``, ...) are its config class's. ``algo.*`` holds both flat: ``Preset.config_class`` joins them."""

    name: str = "psro_nash"
    solver: str = "nash"
    learner: str = "mappo"  # the oracle's learner (LEARNERS): what trains every best response
    start: str = "auto"
    # None: from algo.start (Preset.starts); saved configs hold the resolved value
    learner_init: str | None = None
    bc_frames: int = ranged(200_000, ge=1)
    # the clone's fit: Adam steps per teacher frame sampled (bc's replay_ratio); a small bc_frames
    # wants a high one (4096 frames at 8 are 8 steps: a clone that serves into play half the time)
    bc_replay_ratio: float = ranged(8.0, gt=0)
    self_play: bool = False
    iterations: int = ranged(5, ge=1)
    min_updates: int = ranged(10, ge=1)
    max_updates: int = ranged(30, ge=1)
    win_window: int = ranged(10, ge=1)
    win_mean: float = ranged(0.9, ge=0, le=1)
    win_std: float = ranged(0.05, ge=0)
    payoff_games: int = ranged(100, ge=1)
    seed_members: list[str] | None = None
    opponent_deterministic: bool = False
    eval_opponent: str = "random"
    payoff_pool: str = "serial"
    members: str = "auto"
    drills: str = "zoo:3v3/hcsp_return"  # a hierarchical population's drills: a zoo team, a team file, or hierarchical
    high_level_games: int = ranged(1024, ge=1)  # games each hierarchical oracle trains its high level on
    high_level_batch: int = ranged(256, ge=1)  # games (worlds) per high-level update
    high_level_lr: float = ranged(1e-3, gt=0, le=1)  # Adam's learning rate of a high level
    # fixed opponents every oracle also trains against (a league's anchors), beside the meta-strategy;
    # never members, so never in the mixture; fixed_share: their share of the oracle's games
    # (None: from algo.start; saved configs hold the resolved values)
    fixed_opponents: list[str] | None = None
    fixed_share: float | None = ranged(None, ge=0, le=1)
    oracle_fall_fault: bool = True  # hierarchical oracles train with task.fall_fault on (payoffs and evaluations: the task's rule)


@dataclass
class SelfPlayLoop(LoopConfig):
    self_play: bool = True
    iterations: int = 1


# the learner keys whose population defaults differ from the learner's own: the fine-tuning recipe of
# docs/imitation.md (critic warm-up, KL anchor at 0.3); they act on learners that start from a policy (the
# clone, or init=); the loop sets both to 0 for a learner from scratch
FINE_TUNING = (("actor_freeze_updates", int, ranged(10, ge=0)), ("anchor_coeff", float, ranged(0.3, ge=0)))


@functools.cache
def population_config(loop_cls: type, learner_cls: type, name: str, solver: str, learner: str) -> type:
    """The flat ``algo.*`` dataclass of a preset: the learner's config, the fine-tuning defaults, the loop's keys."""
    own = [*FINE_TUNING, ("name", str, field(default=name)), ("solver", str, field(default=solver)),
           ("learner", str, field(default=learner))]
    cls_name = f"{name.title().replace('_', '')}{learner_cls.__name__}Config"
    cls = make_dataclass(cls_name, own, bases=(loop_cls, learner_cls.config_cls))
    cls.__module__ = __name__
    return cls


@dataclass(frozen=True)
class Preset:
    """A population method in three parts: its meta-solver, its learner and its loop settings. Not an
    algorithm of its own: ``algo=NAME`` selects it like one, and ``volleybots.population.run.start`` hands
    its config to the population loop, which trains the named learner as its oracle (``algo.learner``)
    and the meta-solver over the members."""

    name: str
    solver: str  # the meta-solver (volleybots.ratings.solvers.SOLVERS) over the payoff table
    loop: type = LoopConfig  # the loop settings' dataclass
    learner: str = "mappo"  # the default learner (LEARNERS); algo.learner picks another
    multi_agent: bool = True
    task_kinds: tuple[str, ...] = ("competitive",)
    # the learner starts (algo.learner_init) the method is defined by, and what any other start would
    # make it instead; empty: every start in INITS
    learner_inits: tuple[str, ...] = ()
    otherwise: str = ""
    # algo.start -> (learner_init, seed_members) where the config leaves them unset
    starts: tuple = (("clone", CLONE, (CLONE,)), ("scratch", "scratch", ("random",)))

    def config_class(self, data=None) -> type:
        """The ``algo.*`` dataclass for the composed ``data``: the loop's keys and those of the learner
        ``data`` names (saved configs name none: theirs was MAPPO)."""
        learner = (data or {}).get("learner") or self.learner
        if learner not in LEARNERS:
            raise ConfigError(f"unknown algo.learner {learner!r}; allowed: {', '.join(LEARNERS)}")
        return population_config(self.loop, LEARNERS[learner], self.name, self.solver, learner)

    @property
    def config_cls(self) -> type:
        return self.config_class()

    @property
    def learner_cls(self) -> type:
        return LEARNERS[self.learner]

    def learner_of(self, cfg) -> type:
        """The class of the learner the config ``cfg.algo`` trains (what its member checkpoints hold)."""
        return LEARNERS[cfg.get("learner") or self.learner]

    def resolve(self, cfg, has_init: bool = False, task: str | None = None) -> None:
        """Fill ``learner_init`` and ``seed_members`` the config leaves unset (None) from ``algo.start``,
        and ``members=auto`` from the ``task``, so that a saved config holds what the run did and reloads
        the same whatever the defaults become. ``has_init``: the run names ``init=``, which is then every
        learner's start (``scratch``: no clone; the loop hands each learner ``init=`` with the fine-tuning
        recipe) where the start would clone. A hierarchical population starts from its drills' team
        (``algo.drills``, with its high level if it has one) and each oracle from the newest high level."""
        if cfg.members not in MEMBERS:
            raise ConfigError(f"unknown algo.members {cfg.members!r}; allowed: {', '.join(MEMBERS)}")
        if cfg.members == "auto":
            # self-play has one learner on both teams: a flat policy; so are a named flat learner (algo.learner)
            # and the from-scratch recipe (algo.start=scratch), as they were before hierarchical members
            flat = cfg.self_play or cfg.learner != self.learner or cfg.start == "scratch"
            cfg.members = "hierarchical" if task in HIERARCHICAL_TASKS and not flat else "flat"
        if cfg.start not in STARTS:
            raise ConfigError(f"unknown algo.start {cfg.start!r}; allowed: {', '.join(STARTS)}")
        if cfg.start == "auto":
            # self-play keeps the clone (table 3's sp); a hierarchical population starts from its drills' team
            # and init= names every learner's start itself (as it did beside algo.start=clone)
            zoo = task in ZOO_STARTS and cfg.members != "hierarchical" and not cfg.self_play and not has_init
            cfg.start = ZOO if zoo else "clone"
        # a zoo start and hierarchical members keep the scripted team beside the mixture: without it the
        # high levels forgot how to return its serve (0.58 against it, 1 of 42 receiving games won; with
        # it 0.75, 17 of 41: tuning seed 100, docs/competitive.md)
        anchored = cfg.start == ZOO or cfg.members == "hierarchical"
        fixed = (list(ZOO_FIXED[0]), ZOO_FIXED[1]) if anchored else ([], 0.0)
        cfg.fixed_opponents = list(fixed[0]) if cfg.fixed_opponents is None else cfg.fixed_opponents
        cfg.fixed_share = (fixed[1] if cfg.fixed_opponents else 0.0) if cfg.fixed_share is None else cfg.fixed_share
        if cfg.members == "hierarchical":
            if cfg.learner_init is None:
                cfg.learner_init = "last" if cfg.start == "clone" else "scratch"
            if cfg.seed_members is None:
                cfg.seed_members = [cfg.drills] if cfg.start == "clone" else ["random"]
            return
        if cfg.start == ZOO:
            if task not in ZOO_STARTS:
                raise ConfigError(f"algo.start=zoo: task {task!r} has no zoo start; tasks with one: {', '.join(ZOO_STARTS)}")
            # FSP continues from the newest member: its first learner from the zoo start itself
            init = self.learner_inits[0] if self.learner_inits else ZOO
            members = (ZOO_STARTS[task],) if not cfg.self_play else ()
        else:
            init, members = dict((s, (i, m)) for s, i, m in self.starts)[cfg.start]
        if cfg.learner_init is None:
            # init= and the clone both say where learners start (refused together): the command line's wins
            cfg.learner_init = "scratch" if has_init and init == CLONE else init
        if cfg.seed_members is None:
            cfg.seed_members = list(members)

    @property
    def action_spaces(self) -> tuple[str, ...]:
        return self.learner_cls.action_spaces

    def supported_kinds(self) -> tuple[str, ...]:
        return self.task_kinds

    def check(self, cfg, task_cls, env_cfg) -> None:
        """The preset's own values and its learner's; the files and players it names (``seed_members``,
        ``eval_opponent``) are checked before a run by ``volleybots.policies.check_references``."""
        if not class_attr(task_cls, "competitive"):
            from volleybots.tasks import TASKS

            matches = [n for n, t in TASKS.items() if class_attr(t, "competitive")]
            raise ConfigError(f"algo {self.name!r} trains for matches, not task {task_cls.name!r}; allowed tasks: {', '.join(matches)}")
        if cfg.fixed_share and not cfg.fixed_opponents:
            raise ConfigError(f"algo.fixed_share={cfg.fixed_share} needs algo.fixed_opponents (e.g. [scripted, hierarchical])")
        if cfg.members == "hierarchical":
            self.check_hierarchical(cfg, task_cls)
            return
        learner_cls = self.learner_of(cfg)
        if cfg.learner_init == CLONE and learner_cls is not MAPPO:
            raise ConfigError(f"algo.learner={cfg.learner} cannot start from the clone (algo.learner_init=bc: its networks are "
                              "MAPPO's); give algo.start=scratch or algo.learner_init=scratch")
        view = cfg
        if cfg.learner_init != CLONE:  # the loop gives a learner from scratch no fine-tuning (_iteration_cfg)
            view = copy.deepcopy(cfg)
            view.actor_freeze_updates, view.anchor_coeff = 0, 0.0
        check_team_learner(learner_cls, view, task_cls, env_cfg, f"algo={self.name} algo.learner={cfg.learner}")
        for value, allowed, key in ((cfg.solver, SOLVERS, "algo.solver"), (cfg.learner_init, INITS, "algo.learner_init"),
                                    (cfg.payoff_pool, POOLS, "algo.payoff_pool")):
            if value not in allowed:
                raise ConfigError(f"unknown {key} {value!r}; allowed: {', '.join(allowed)}")
        if self.learner_inits and cfg.learner_init not in self.learner_inits:
            raise ConfigError(f"algo={self.name} {self.otherwise.format(init=cfg.learner_init)}")
        if cfg.max_updates < cfg.min_updates:
            raise ConfigError(f"algo.max_updates={cfg.max_updates} is below algo.min_updates={cfg.min_updates}")
        if cfg.learner_init == CLONE or CLONE in [str(s) for s in cfg.seed_members]:
            from volleybots.algos.bc import BC

            try:  # the clone is a bc run against the scripted team: it must be one this task can train
                BC.check(cfg, task_cls, env_cfg)
            except ConfigError as e:
                raise ConfigError(f"algo.learner_init=bc / algo.seed_members=[bc] clone the scripted team: {e}") from None
        if not cfg.self_play and not cfg.seed_members:
            raise ConfigError(f"algo {self.name!r} needs a first opponent: algo.seed_members=[random] (or scripted, or checkpoint paths)")


    def check_hierarchical(self, cfg, task_cls) -> None:
        """A hierarchical population's own values (its learner is the high level's PPO, not algo.learner)."""
        if task_cls.name not in HIERARCHICAL_TASKS:
            raise ConfigError(f"algo.members=hierarchical plays task {', '.join(HIERARCHICAL_TASKS)}, not {task_cls.name!r}; "
                              "give algo.members=flat")
        if cfg.learner != self.learner:
            raise ConfigError(f"algo.learner={cfg.learner} trains flat members; a hierarchical member's oracle trains its high level "
                              "(algo.high_level_*): give algo.members=flat with it")
        if cfg.self_play:
            raise ConfigError(f"algo={self.name} has no hierarchical members (one learner plays both teams); use algo=fsp, "
                              "psro_uniform or psro_nash with algo.members=hierarchical, or algo.members=flat")
        for value, allowed, key in ((cfg.solver, SOLVERS, "algo.solver"), (cfg.learner_init, ("scratch", "last"), "algo.learner_init"),
                                    (cfg.payoff_pool, POOLS, "algo.payoff_pool")):
            if value not in allowed:
                raise ConfigError(f"unknown {key} {value!r} for algo.members=hierarchical; allowed: {', '.join(allowed)}")
        if self.learner_inits and cfg.learner_init not in self.learner_inits:
            raise ConfigError(f"algo={self.name} {self.otherwise.format(init=cfg.learner_init)}")
        if not cfg.seed_members:
            raise ConfigError(f"algo {self.name!r} needs a first opponent: algo.seed_members=[{cfg.drills}] (or scripted, hierarchical)")


def check_team_learner(learner_cls: type, cfg, task_cls, env_cfg, what: str) -> None:
    """Raise ``ConfigError`` unless ``learner_cls`` can learn one team of the match ``task_cls``: a team of one
    drone is a single-drone problem, a larger one a cooperative one (HAPPO and MAT learn only those)."""
    size = class_attr(task_cls, "team_size")
    kind = "single" if size == 1 else "cooperative"
    if kind not in learner_cls.supported_kinds():
        able = [n for n, c in LEARNERS.items() if kind in c.supported_kinds()]
        raise ConfigError(f"{what} cannot learn a team of {size} drone(s) (task {task_cls.name!r}); allowed learners: {', '.join(able)}")
    team = type(f"{task_cls.name}_team", (), {"name": f"{task_cls.name} (one team)", "n_drones": size, "competitive": False})
    learner_cls.check(cfg, team, env_cfg)


# what a population config saved before algo.members existed did: flat members from algo.start=clone
# with no fixed opponents; a saved config reads as the run it was, whatever the defaults became since
LEGACY_KEYS = {"members": "flat", "start": "clone", "fixed_opponents": [], "fixed_share": 0.0}


def with_legacy_keys(algo: dict) -> dict:
    """``algo`` (a population's ``algo`` dict) with the keys it lacks from before ``members`` filled as
    that version ran them; a config composed today holds every key and is returned as it is."""
    if "members" in algo:
        return algo
    return {**{k: v for k, v in LEGACY_KEYS.items() if k not in algo}, **algo}


def is_population(algo) -> bool:
    """Whether ``algo`` (a name, an ``algo`` config or a registry entry) is a population preset: the one
    question that sends a run to the population loop instead of the trainer alone."""
    name = algo if isinstance(algo, str) else getattr(algo, "name", None)
    if name is None and hasattr(algo, "get"):
        name = algo.get("name")
    return isinstance(name, str) and name in PRESETS


# self-play has no frozen members: its one learner starts from the clone or from scratch
SP = Preset("sp", "last", SelfPlayLoop, starts=(("clone", CLONE, ()), ("scratch", "scratch", ())))
# FSP is the uniform meta-solver with each learner continuing from the newest member; any other start
# makes it PSRO-uniform, run for run (a 3v3 run with learner_init=bc was)
FSP = Preset(
    "fsp", "uniform", learner_inits=("last",), starts=(("clone", "last", (CLONE,)), ("scratch", "last", ("random",))),
    otherwise="continues each learner from the newest member (algo.learner_init=last), not {init!r}, which makes it "
    "algo=psro_uniform; to start FSP from the clone give algo.seed_members=[bc] (its first learner continues from the clone)",
)
PSROUniform = Preset("psro_uniform", "uniform")
PSRONash = Preset("psro_nash", "nash")
PRESETS = {p.name: p for p in (SP, FSP, PSROUniform, PSRONash)}
PopulationConfig = PSRONash.config_cls  # psro_nash's algo.* with its default learner (MAPPO)
