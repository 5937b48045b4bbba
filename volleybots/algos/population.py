"""The population presets: ``sp``, ``fsp``, ``psro_uniform``, ``psro_nash`` (``population=NAME``).

They are one loop (``volleybots.population.loop``); a preset names its three parts: a meta-solver, a
learner (``algo=``: MAPPO with a critic over its own team by default, PPO for one drone a side; HAPPO or
MAT on teams of several drones) and its loop settings (``LoopConfig``). A run config holds the loop's
keys under ``population.*`` and the learner's, from the learner's own file, under ``algo.*``;
``population_of(cfg)`` is how code reads the loop's keys, ``is_population`` the one question that sends
a config to the loop. ``PRESETS`` is their registry, apart from the algorithms' (``volleybots.algos.ALGOS``).
"""

from __future__ import annotations

import copy
import dataclasses
from dataclasses import dataclass, field

from volleybots.algos.base import class_attr
from volleybots.algos.happo import HAPPO
from volleybots.algos.mat import MAT
from volleybots.algos.ppo import MAPPO
from volleybots.errors import ConfigError, ranged
from volleybots.ratings.solvers import SOLVERS  # a leaf module (numpy and scipy only)

CLONE = "bc"  # the run's behaviour clone of the scripted team: a learner_init and a seed_members name
TRAIN = "train"  # population.drills (and a seed_members entry): the drills the run trains itself (stage I)
ZOO = "zoo"  # learners fine-tuned from the task's zoo start (ZOO_STARTS), the first member that policy
INITS = ("scratch", "last", CLONE, ZOO)
# a hierarchical oracle's high level starts near uniform (scratch), from the newest member's (last) or from
# the first member's, the team the run starts from (first: what flat PSRO's learners do from the clone)
HIERARCHICAL_INITS = ("scratch", "last", "first")
# population.start: what a population starts from where population.learner_init / seed_members are left unset.
# "clone" is the default because learners from scratch do not hit the ball within a default budget:
# a bare `train task=3v3 algo=psro_nash` from scratch ended with the Nash mixture on `random` alone
# "zoo" starts from the package's best learned policy of the task (ZOO_STARTS), with the scripted player
# as a fixed opponent beside the mixture (population.fixed_opponents): a 1v1 population from the clone stayed
# below scripted (0.39 against it), from dag_rally it keeps the returns the receive work taught;
# "auto": zoo where the task has a zoo start (not for sp), clone elsewhere
STARTS = ("auto", "clone", "scratch", ZOO)
ZOO_STARTS = {"1v1": "zoo:1v1/dag_rally"}
ZOO_FIXED = (["scripted"], 0.5)  # fixed opponents and their share of a zoo start or hierarchical members, where unset
# the learners an oracle may train (algo=): those that learn one team of a match with a critic
# over their own team; HAPPO and MAT only where the team has several drones (3v3, 6v6)
LEARNERS = {cls.name: cls for cls in (MAPPO, HAPPO, MAT)}
# population.members: the policy space of a population. flat: every member one network over the whole team
# (the paper's table 3); hierarchical (3v3): drills under a learned high level, each oracle training a
# high level over the run's drills (the HCSP route, volleybots/population/hierarchical.py); auto:
# hierarchical on 3v3, flat elsewhere (what the headline's targets were met with: docs/competitive.md)
MEMBERS = ("auto", "flat", "hierarchical")
HIERARCHICAL_TASKS = ("3v3",)
POOLS = ("serial", "ray")  # where payoff games (and hierarchical oracles' games) are played: here, or as Ray tasks (volleybots.play.pool)


@dataclass
class LoopConfig:
    """The population loop's own keys (``population.solver``, ``population.iterations``, ...); the learner's
    (``algo.actor_lr``, ``algo.hidden``, ...) are its own config class's, under ``algo``."""

    name: str = "psro_nash"
    solver: str = "nash"
    start: str = "auto"
    # None: from population.start (Preset.starts); saved configs hold the resolved value
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
    oracle_pool: str = "serial"  # where a hierarchical oracle's games are played (volleybots.train.high_level.play_chunks)
    oracle_chunks: int = ranged(1, ge=1)  # the parts each of its batches is played in (the games depend on it, not on the pool)
    # the run's time_limit by task where it gives none (0), seconds: the bare 6v6 headline's five oracles
    # take about 90 minutes on 2 cores, so it is bounded by an hour ({6v6: 0} lifts it)
    default_time_limit: dict[str, float] = field(default_factory=lambda: {"6v6": 3600.0})
    members: str = "auto"
    drills: str = "zoo:3v3/hcsp_return"  # a hierarchical population's drills: a zoo team, a team file, hierarchical, or train
    # stage I of HCSP (population/stage_one.py), with drills=train: each drill imitated, then fine-tuned by PPO
    drill_bc_frames: int = ranged(500_000, ge=1)  # imitation frames per drill
    drill_frames: int = ranged(500_000, ge=1)  # PPO frames per drill, from its clone
    high_level_games: int = ranged(1024, ge=1)  # games each hierarchical oracle trains its high level on
    high_level_batch: int = ranged(256, ge=1)  # games (worlds) per high-level update
    high_level_lr: float = ranged(1e-3, gt=0, le=1)  # Adam's learning rate of a high level
    # fixed opponents every oracle also trains against (a league's anchors), beside the meta-strategy;
    # never members, so never in the mixture; fixed_share: their share of the oracle's games
    # (None: from population.start; saved configs hold the resolved values)
    fixed_opponents: list[str] | None = None
    fixed_share: float | None = ranged(None, ge=0, le=1)
    oracle_fall_fault: bool = True  # hierarchical oracles train with task.fall_fault on (payoffs and evaluations: the task's rule)
    # stage III of HCSP (population/tune_drills.py): before a hierarchical oracle trains its high level, the
    # drills named here are fine-tuned by PPO on the serves recorded against its opponent ([]: off)
    tune_drills: list[str] = field(default_factory=list)
    tune_at: list[int] = ranged(factory=lambda: [1], ge=1)  # the iterations whose oracle first tunes the drills
    tune_games: int = ranged(256, ge=1)  # games recorded (the team receiving) for the ball bank
    tune_frames: int = ranged(1_000_000, ge=1)  # PPO frames per tuned drill
    tune_share: float = ranged(0.5, ge=0, le=1)  # share of a tuned drill's balls drawn from the bank (the rest: its own)


@dataclass
class SelfPlayLoop(LoopConfig):
    self_play: bool = True
    iterations: int = 1


# the learner keys whose population defaults differ from the learner's own: the fine-tuning recipe of
# docs/imitation.md (critic warm-up, KL anchor at 0.3), set under algo by conf/population/psro_nash.yaml;
# they act on learners that start from a policy (the clone, or init=); the loop sets both to 0 for a
# learner from scratch
TUNABLE = ("pass", "attack")  # the drills that receive a serve: the ones a ball bank can feed (tasks/drills.py serve_bank)
FINE_TUNING = {"actor_freeze_updates": 10, "anchor_coeff": 0.3}


@dataclass(frozen=True)
class Preset:
    """A population method in three parts: its meta-solver, its learner and its loop settings. Not an
    algorithm of its own: ``population=NAME`` selects it (``algo=NAME`` is read as that, with its default
    learner), and ``volleybots.population.run.start`` hands its config to the population loop, which
    trains the learner ``algo=`` names as its oracle and the meta-solver over the members."""

    name: str
    solver: str  # the meta-solver (volleybots.ratings.solvers.SOLVERS) over the payoff table
    loop: type = LoopConfig  # the loop settings' dataclass
    learner: str = "mappo"  # the default learner (LEARNERS); algo= picks another
    # the learner starts (population.learner_init) the method is defined by, and what any other start would
    # make it instead; empty: every start in INITS
    learner_inits: tuple[str, ...] = ()
    otherwise: str = ""
    # population.start -> (learner_init, seed_members) where the config leaves them unset
    starts: tuple = (("clone", CLONE, (CLONE,)), ("scratch", "scratch", ("random",)))
    # hierarchical members: where each oracle's high level starts when learner_init is unset (HIERARCHICAL_INITS)
    hierarchical_init: str = "last"

    @property
    def config_cls(self) -> type:
        """The dataclass of its ``population.*`` keys."""
        return self.loop

    @property
    def learner_cls(self) -> type:
        return LEARNERS[self.learner]

    def learner_of(self, algo_cfg) -> type:
        """The class of the learner ``algo_cfg`` (a run's ``algo`` node) names: what the member checkpoints hold."""
        name = algo_cfg.get("name") or self.learner
        if name not in LEARNERS:
            raise ConfigError(f"population={self.name} cannot train algo={name} as its learner; allowed: {', '.join(LEARNERS)}")
        return LEARNERS[name]

    def resolve(self, cfg, has_init: bool = False, task: str | None = None, learner: str | None = None) -> None:
        """Fill ``learner_init`` and ``seed_members`` the ``population`` node ``cfg`` leaves unset (None) from its
        ``start``, and ``members=auto`` from the ``task``, so that a saved config holds what the run did and
        reloads the same whatever the defaults become. ``has_init``: the run names ``init=``, which is then
        every learner's start (``scratch``: no clone; the loop hands each learner ``init=`` with the
        fine-tuning recipe) where the start would clone. A hierarchical population starts from its drills'
        team (``population.drills``, with its high level if it has one) and each oracle from the newest high level.
        ``learner``: the run's ``algo=`` (None: the preset's own)."""
        if cfg.members not in MEMBERS:
            raise ConfigError(f"unknown population.members {cfg.members!r}; allowed: {', '.join(MEMBERS)}")
        if cfg.members == "auto":
            # self-play has one learner on both teams: a flat policy; so are another learner than the preset's
            # (algo=mat), the from-scratch recipe (start=scratch) and the clone named as a start or member
            # (learner_init=bc, seed_members=[bc]: table 3's commands), as they were before hierarchical members
            clone = cfg.learner_init == CLONE or CLONE in [str(x) for x in (cfg.seed_members or [])]
            flat = cfg.self_play or (learner or self.learner) != self.learner or cfg.start == "scratch" or clone
            cfg.members = "hierarchical" if task in HIERARCHICAL_TASKS and not flat else "flat"
        if cfg.start not in STARTS:
            raise ConfigError(f"unknown population.start {cfg.start!r}; allowed: {', '.join(STARTS)}")
        if cfg.start == "auto":
            # self-play keeps the clone (table 3's sp); a hierarchical population starts from its drills' team
            # and init= names every learner's start itself (as it did beside start=clone)
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
                cfg.learner_init = self.hierarchical_init if cfg.start == "clone" else "scratch"
            if cfg.seed_members is None:
                cfg.seed_members = [cfg.drills] if cfg.start == "clone" else ["random"]
            return
        if cfg.start == ZOO:
            if task not in ZOO_STARTS:
                raise ConfigError(f"population.start=zoo: task {task!r} has no zoo start; tasks with one: {', '.join(ZOO_STARTS)}")
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

    def check(self, pop, algo, task_cls, env_cfg) -> None:
        """The preset's own values (the ``population`` node ``pop``) and its learner's (``algo``); the files
        and players it names (``seed_members``, ``eval_opponent``) are checked before a run by
        ``volleybots.policies.check_references``."""
        if not class_attr(task_cls, "competitive"):
            from volleybots.tasks import TASKS

            matches = [n for n, t in TASKS.items() if class_attr(t, "competitive")]
            raise ConfigError(f"population={self.name} trains for matches, not task {task_cls.name!r}; allowed tasks: {', '.join(matches)}")
        if pop.fixed_share and not pop.fixed_opponents:
            raise ConfigError(f"population.fixed_share={pop.fixed_share} needs population.fixed_opponents (e.g. [scripted, hierarchical])")
        if pop.tune_drills and pop.members != "hierarchical":
            raise ConfigError(f"population.tune_drills={list(pop.tune_drills)} tunes a hierarchical team's drills; "
                              "give population.members=hierarchical (3v3) or population.tune_drills=[]")
        if pop.members == "hierarchical":
            self.check_hierarchical(pop, algo.name, task_cls)
            return
        learner_cls = self.learner_of(algo)
        if pop.learner_init == CLONE and learner_cls is not MAPPO:
            raise ConfigError(f"algo={algo.name} cannot start from the clone (population.learner_init=bc: its networks are "
                              "MAPPO's); give population.start=scratch or population.learner_init=scratch")
        view = algo
        if pop.learner_init != CLONE:  # the loop gives a learner from scratch no fine-tuning (_iteration_cfg)
            view = copy.deepcopy(algo)
            view.actor_freeze_updates, view.anchor_coeff = 0, 0.0
        check_team_learner(learner_cls, view, task_cls, env_cfg, f"population={self.name} algo={algo.name}")
        for value, allowed, key in ((pop.solver, SOLVERS, "population.solver"), (pop.learner_init, INITS, "population.learner_init"),
                                    (pop.payoff_pool, POOLS, "population.payoff_pool"), (pop.oracle_pool, POOLS, "population.oracle_pool")):
            if value not in allowed:
                raise ConfigError(f"unknown {key} {value!r}; allowed: {', '.join(allowed)}")
        if pop.oracle_pool != "serial" or pop.oracle_chunks != 1:  # a flat oracle is one learner stepping its own envs
            raise ConfigError(f"population.oracle_pool / oracle_chunks play hierarchical oracles' games; a flat member's oracle "
                              f"(algo={algo.name}) trains in this process: give population.oracle_pool=serial oracle_chunks=1")
        if self.learner_inits and pop.learner_init not in self.learner_inits:
            raise ConfigError(f"population={self.name} {self.otherwise.format(init=pop.learner_init)}")
        if pop.max_updates < pop.min_updates:
            raise ConfigError(f"population.max_updates={pop.max_updates} is below population.min_updates={pop.min_updates}")
        if pop.learner_init == CLONE or CLONE in [str(s) for s in pop.seed_members]:
            from volleybots.algos.bc import BC

            try:  # the clone is a bc run against the scripted team: it must be one this task can train
                BC.check(algo, task_cls, env_cfg)
            except ConfigError as e:
                raise ConfigError(f"population.learner_init=bc / population.seed_members=[bc] clone the scripted team: {e}") from None
        if not pop.self_play and not pop.seed_members:
            raise ConfigError(f"population={self.name} needs a first opponent: population.seed_members=[random] "
                              "(or scripted, or checkpoint paths)")


    def check_hierarchical(self, pop, learner: str, task_cls) -> None:
        """A hierarchical population's own values (the ``population`` node ``pop``; its learner is the high
        level's PPO, not ``algo=``, which must be the preset's own ``learner``)."""
        if task_cls.name not in HIERARCHICAL_TASKS:
            raise ConfigError(f"population.members=hierarchical plays task {', '.join(HIERARCHICAL_TASKS)}, not {task_cls.name!r}; "
                              "give population.members=flat")
        if learner != self.learner:
            raise ConfigError(f"algo={learner} trains flat members; a hierarchical member's oracle trains its high level "
                              "(population.high_level_*): give population.members=flat with it")
        for value, allowed, key in ((pop.solver, SOLVERS, "population.solver"),
                                    (pop.learner_init, HIERARCHICAL_INITS, "population.learner_init"),
                                    (pop.payoff_pool, POOLS, "population.payoff_pool"), (pop.oracle_pool, POOLS, "population.oracle_pool")):
            if value not in allowed:
                raise ConfigError(f"unknown {key} {value!r} for population.members=hierarchical; allowed: {', '.join(allowed)}")
        if self.learner_inits and pop.learner_init not in self.learner_inits:
            raise ConfigError(f"population={self.name} {self.otherwise.format(init=pop.learner_init)}")
        if pop.oracle_chunks > pop.high_level_batch:
            raise ConfigError(f"population.oracle_chunks={pop.oracle_chunks} must be at most population.high_level_batch="
                              f"{pop.high_level_batch} (a chunk plays at least one game)")
        bad = [d for d in pop.tune_drills if d not in TUNABLE]
        if bad:
            raise ConfigError(f"population.tune_drills: {bad[0]!r} cannot be tuned on recorded serves; allowed: {', '.join(TUNABLE)}")
        if any(not isinstance(i, int) or i < 1 for i in pop.tune_at):
            raise ConfigError(f"population.tune_at={list(pop.tune_at)!r} must list iterations >= 1")
        if not pop.seed_members:
            raise ConfigError(f"population={self.name} needs a first opponent: population.seed_members=[{pop.drills}] "
                              "(or scripted, hierarchical)")


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


# what a population config saved before population.members existed did: flat members from start=clone
# with no fixed opponents; a saved config reads as the run it was, whatever the defaults became since
LEGACY_KEYS = {"members": "flat", "start": "clone", "fixed_opponents": [], "fixed_share": 0.0}


def is_population(x) -> bool:
    """Whether ``x`` is a population: a preset's name, a preset, a run config with a ``population`` node,
    that node itself, or an ``algo`` node saved before ``population=`` was a group (named by a preset).
    The one question that sends a run to the population loop instead of the trainer alone."""
    if isinstance(x, Preset):
        return True
    if isinstance(x, str):
        return x in PRESETS
    if not hasattr(x, "get"):
        return False
    if x.get("population") is not None:
        return True
    name = x.get("name")
    return isinstance(name, str) and name in PRESETS


def population_of(cfg):
    """The population loop's keys of the run config ``cfg`` (its ``population`` node), or None for a run
    of one learner: the one accessor of the loop's keys."""
    return cfg.get("population") if hasattr(cfg, "get") else None


def method_name(cfg) -> str:
    """What a run config (or a saved one, a dict) trains with, by name: its population method, else its algorithm."""
    pop = population_of(cfg)
    return pop.get("name") if pop is not None else cfg["algo"]["name"]


def upgrade_saved(data: dict) -> dict:
    """A run config saved before ``population=`` was a group (``algo.name`` a preset, its loop's keys and its
    learner's flat under ``algo``, the learner named by ``algo.learner`` or MAPPO) in today's shape: the
    loop's keys under ``population``, the learner's under ``algo``. Any other config is returned as is."""
    algo = data.get("algo")
    if data.get("population") is not None or not isinstance(algo, dict) or algo.get("name") not in PRESETS:
        return data
    loop = {f.name for f in dataclasses.fields(PRESETS[algo["name"]].loop)}
    learner = {k: v for k, v in algo.items() if k not in loop and k != "learner"}
    learner["name"] = algo.get("learner") or "mappo"
    pop = {k: v for k, v in algo.items() if k in loop}
    if "members" not in pop:  # saved before population.members: the keys added since read as that version ran them
        pop = {**LEGACY_KEYS, **pop}
    return {**data, "population": pop, "algo": learner}


# self-play has no frozen members: its one learner starts from the clone or from scratch
SP = Preset("sp", "last", SelfPlayLoop, starts=(("clone", CLONE, ()), ("scratch", "scratch", ())))
# FSP is the uniform meta-solver with each learner continuing from the newest member; any other start
# makes it PSRO-uniform, run for run (a 3v3 run with learner_init=bc was)
FSP = Preset(
    "fsp", "uniform", learner_inits=("last",), starts=(("clone", "last", (CLONE,)), ("scratch", "last", ("random",))),
    otherwise="continues each learner from the newest member (population.learner_init=last), not {init!r}, which makes it "
    "population=psro_uniform; to start FSP from the clone give population.seed_members=[bc] (its first learner continues from the clone)",
)
# PSRO-uniform's oracles start from the run's first team, as its flat learners start from the clone: had they
# continued from the newest member (last), a hierarchical PSRO-uniform would be FSP run for run (it was:
# the same high levels, bit for bit, seed 1). PSRO-Nash continues (the headline's setting, HCSP's one high
# level carried through the population); population.learner_init=first starts it as PSRO-uniform does
PSROUniform = Preset("psro_uniform", "uniform", hierarchical_init="first")
PSRONash = Preset("psro_nash", "nash")
PRESETS = {p.name: p for p in (SP, FSP, PSROUniform, PSRONash)}
