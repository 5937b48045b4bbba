"""The population presets of the registry: ``sp``, ``fsp``, ``psro_uniform``, ``psro_nash``.

They are one loop (``volleybots.population.loop``) with a swappable meta-solver and learner
initialisation; here live only their configs and what they accept. The learner is MAPPO with a critic
over its own team (for one drone a side that is PPO: a critic over one agent) with the paper's PPO
hyperparameters, which the config inherits (``algo.actor_lr=...`` sets the learner's).
"""

from __future__ import annotations

from dataclasses import dataclass

from volleybots.algos.base import class_attr
from volleybots.algos.ppo import MAPPO, MAPPOConfig
from volleybots.errors import ConfigError, ranged
from volleybots.population.solvers import SOLVERS  # a leaf module (numpy and scipy only)

CLONE = "bc"  # the run's behaviour clone of the scripted team: a learner_init and a seed_members name
INITS = ("scratch", "last", CLONE)
# algo.start: what a population starts from where algo.learner_init / algo.seed_members are left unset.
# "clone" is the default because learners from scratch do not hit the ball within a default budget:
# a bare `train task=3v3 algo=psro_nash` from scratch ended with the Nash mixture on `random` alone
STARTS = ("clone", "scratch")
POOLS = ("serial", "ray")  # where payoff games are played: here, or as tasks of a Ray pool (volleybots.play.pool)


@dataclass
class PopulationConfig(MAPPOConfig):
    name: str = "psro_nash"
    solver: str = "nash"
    start: str = "clone"
    # None: from algo.start (Preset.starts); saved configs hold the resolved value
    learner_init: str | None = None
    bc_frames: int = ranged(200_000, ge=1)
    # the clone's fit: Adam steps per teacher frame sampled (bc's replay_ratio); a small bc_frames
    # wants a high one (4096 frames at 8 are 8 steps: a clone that serves into play half the time)
    bc_replay_ratio: float = ranged(8.0, gt=0)
    # the fine-tuning recipe of docs/imitation.md (critic warm-up, KL anchor at 0.3); they act on learners
    # that start from a policy (the clone, or init=); the loop sets both to 0 for a learner from scratch
    actor_freeze_updates: int = ranged(10, ge=0)
    anchor_coeff: float = ranged(0.3, ge=0)
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


@dataclass
class SPConfig(PopulationConfig):
    name: str = "sp"
    solver: str = "last"
    self_play: bool = True
    iterations: int = 1


@dataclass
class FSPConfig(PopulationConfig):
    name: str = "fsp"
    solver: str = "uniform"


@dataclass
class PSROUniformConfig(PopulationConfig):
    name: str = "psro_uniform"
    solver: str = "uniform"


@dataclass(frozen=True)
class Preset:
    """A population method: its config and what it accepts. Not an algorithm of its own: ``algo=NAME``
    selects it like one, and ``volleybots.population.run.start`` hands its config to the population loop,
    which trains ``learner_cls`` learners as its oracle and the preset's meta-solver over them."""

    name: str
    config_cls: type
    learner_cls: type = MAPPO
    population: bool = True  # what sends a run to the population loop
    multi_agent: bool = True
    task_kinds: tuple[str, ...] = ("competitive",)
    # the learner starts (algo.learner_init) the method is defined by, and what any other start would
    # make it instead; empty: every start in INITS
    learner_inits: tuple[str, ...] = ()
    otherwise: str = ""
    # algo.start -> (learner_init, seed_members) where the config leaves them unset
    starts: tuple = (("clone", CLONE, (CLONE,)), ("scratch", "scratch", ("random",)))

    def resolve(self, cfg) -> None:
        """Fill ``learner_init`` and ``seed_members`` the config leaves unset (None) from ``algo.start``,
        so that a saved config holds what the run did and reloads the same whatever the defaults become."""
        if cfg.start not in STARTS:
            raise ConfigError(f"unknown algo.start {cfg.start!r}; allowed: {', '.join(STARTS)}")
        init, members = dict((s, (i, m)) for s, i, m in self.starts)[cfg.start]
        if cfg.learner_init is None:
            cfg.learner_init = init
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
        if env_cfg.action_space not in self.action_spaces:
            raise ConfigError(
                f"algo {self.name!r} does not support env.action_space={env_cfg.action_space!r}; "
                f"allowed: {', '.join(self.action_spaces)}"
            )
        self.learner_cls.check(cfg, task_cls, env_cfg)
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


# self-play has no frozen members: its one learner starts from the clone or from scratch
SP = Preset("sp", SPConfig, starts=(("clone", CLONE, ()), ("scratch", "scratch", ())))
# FSP is the uniform meta-solver with each learner continuing from the newest member; any other start
# makes it PSRO-uniform, run for run (a 3v3 run with learner_init=bc was)
FSP = Preset(
    "fsp", FSPConfig, learner_inits=("last",), starts=(("clone", "last", (CLONE,)), ("scratch", "last", ("random",))),
    otherwise="continues each learner from the newest member (algo.learner_init=last), not {init!r}, which makes it "
    "algo=psro_uniform; to start FSP from the clone give algo.seed_members=[bc] (its first learner continues from the clone)",
)
PSROUniform = Preset("psro_uniform", PSROUniformConfig)
PSRONash = Preset("psro_nash", PopulationConfig)
PRESETS = {p.name: p for p in (SP, FSP, PSROUniform, PSRONash)}
