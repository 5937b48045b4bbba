"""The options of the verbs, as data: one dataclass per verb, each field with its default, its help and
what it allows (``volleybots.config.args.option``). The parser fills them from ``key=value`` words
(``volleybots.config.args.split_args``) and each verb's ``--help`` lists them (``describe``), so the two
never disagree. They live here, beside the config schemas, and import nothing heavy: the CLI builds its
help from them before torch loads.

A few defaults repeat a constant of a lower module that this one may not import without torch or
scipy (the batch of ``volleybots.play.games``, Elo's rounds and K of ``volleybots.ratings``, the pools
of ``volleybots.algos.population``): ``tests/config/test_verb_options.py`` holds them equal.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Optional

from volleybots.config.args import VerbOptions, option
from volleybots.config.schema import MAX_THREADS

SEED_MAX = 2**62  # a seed leaves room for the offsets the verbs add per pair, side and game (no generator past int64)
DEFAULT_BATCH = 256  # worlds played together: bounded so memory stays small while the batch amortises stepping
SCENARIOS = ("any", "serve", "receive")  # who serves: a random side each game, the first competitor, the other one
POOLS = ("serial", "ray")  # where the pairs are played: here in turn, or as Ray tasks together
UNTIL = ("budget", "plateau")  # a best response trains its whole budget, or until its win rate stops rising
SPLIT = "split"  # exploitability's serve responses and receive responses, half the games each (the paper's 3v3 figure)


@dataclass
class PlayOptions(VerbOptions):
    """How the games of a cross-play are played (``eval crossplay`` and ``eval elo``)."""

    seed: int = option(0, "seeds the games; the same seed replays the same games", ge=0, le=SEED_MAX)
    batch: int = option(DEFAULT_BATCH, "worlds played together", ge=1)
    scenario: str = option("any", "who serves: a random side each game, the first competitor, or the other one", choices=SCENARIOS)
    deterministic: bool = option(False, "competitors act with their mode instead of sampling")
    reuse: Optional[str] = option(None, "FILE: copy the pairs an earlier crossplay.json played with the same settings")
    pool: str = option("serial", "play the pairs in turn, or as Ray tasks together (the same numbers)", choices=POOLS)


@dataclass
class CrossplayOptions(PlayOptions):
    """``volleybots eval crossplay``: every pair of competitors plays ``games`` games."""

    games: int = option(1000, "games per pair, an even number: each competitor plays half of them on each side", ge=2)


@dataclass
class EloOptions(PlayOptions):
    """``volleybots eval elo``: ratings of games played now, or of a cross-play already played (``from=``)."""

    rounds: int = option(2000, "Elo rounds, every pair meeting once a round: the games per pair played, an even number", ge=1)
    k: float = option(168.0, "Elo's step (the paper's is 168)", gt=0)
    sample: bool = option(False, "draw each round's results from the pairs' win/draw/loss frequencies (as the paper "
                          "did) instead of the games played, in order")
    orders: int = option(100, "seeded game orders over which Elo's spread is reported", ge=1, le=10_000)
    source: Optional[str] = option(None, "CROSSPLAY_JSON: rate the games of an earlier cross-play instead of playing", key="from")
    # cross-play's spelling of the games per pair: a command line copied from eval crossplay keeps working
    games: Optional[int] = option(None, "another name of rounds=, as eval crossplay spells the games per pair (rounds= "
                                  "counts where both are given)", ge=2)


@dataclass
class ExploitabilityOptions(VerbOptions):
    """``volleybots eval exploitability``: a lower bound on a target's exploitability."""

    budget: int = option(1_000_000, "frames of each best response's training; 0 trains none (fixed responses only)", ge=0)
    seeds: int = option(2, "training seeds of the best response", ge=1, le=64)
    games: int = option(1000, "games the chosen response plays for the figure, an even number (a multiple of 4 with "
                        "scenario=split)", ge=2)
    select_games: int = option(200, "games every candidate plays to be chosen, apart from the figure's, an even number", ge=2)
    seed: int = option(0, "seeds the training (seed + 1000 i for seed i) and the games", ge=0, le=SEED_MAX)
    scenario: str = option("any", "who serves; split: serve and receive responses, half the games each (the paper's 3v3)",
                           choices=(*SCENARIOS, SPLIT))
    until: str = option("budget", "train the whole budget, or stop once the training win rate has plateaued; no rule stops "
                        "at a win-rate level", choices=UNTIL)
    init: Optional[str] = option(None, "RUN: the responses start from this policy (a critic warm-up first)")
    num_envs: Optional[int] = option(None, "worlds each response trains on (default: the learner's)", ge=1)
    batch: int = option(DEFAULT_BATCH, "worlds played together in the games", ge=1)
    members: bool = option(True, "a mixture's own members are candidates too")
    pool: str = option("serial", "train the seeds' responses in turn, or as Ray tasks together", choices=POOLS)
    progress: bool = option(True, "print each stage and the training's progress on stderr")
    response: list[str] = option(help="SPEC: a fixed candidate response (scripted, hierarchical, a run, zoo:...); repeatable", factory=list)
    high_level: int = option(0, "3v3: games of each best response over the high level (a high level trained over "
                             "high_level_drills against the target, one per seed); 0: none", ge=0, le=10**8)
    high_level_drills: str = option("zoo:3v3/hcsp_return", "the drills the high-level responses play (a hierarchical team)")


@dataclass
class ReplayOptions(VerbOptions):
    """``volleybots replay A B``: one match between two competitors."""

    seed: int = option(0, "seeds the match", ge=0, le=SEED_MAX)
    scenario: str = option("any", "who serves: a random side, A, or B", choices=SCENARIOS)
    deterministic: bool = option(False, "competitors act with their mode instead of sampling")


@dataclass
class BenchOptions:
    """``volleybots bench`` (the options ``volleybots.bench.run_bench`` measures with), typed and ranged
    like the config; a scalar where a list is expected is taken as a list of one."""

    tasks: Optional[list[str]] = option(help="task names (task= for one)", factory=lambda: ["solo_bump"])
    backends: Optional[list[str]] = option(help="physics backends (backend= for one)", factory=lambda: ["torch", "mujoco"])
    num_envs: Optional[list[int]] = option(help="env counts, the batch sizes", ge=1, factory=lambda: [1, 256, 4096])
    devices: Optional[list[str]] = option(None, "torch devices (device= for one; default cpu, and cuda where there is one)")
    compile: Any = option(False, "torch.compile the physics sub-step; [false,true] measures both ways")
    repeats: int = option(3, "timed repeats; a row reports their median", ge=1, le=20)
    # batched steps per repeat: 200 times the most ``default_steps`` gives
    steps: Optional[int] = option(None, "env steps per repeat (default: scaled by env count and backend)", ge=1, le=100_000)
    action_space: str = option("prt", "the action space the random actions are drawn in")
    threads: Optional[int] = option(None, "cores each row may use (default: torch's count)", ge=0, le=MAX_THREADS)
    train: bool = option(False, "also measure PPO (solo_bump) / MAPPO (3v3) training frames/s")
    train_batches: int = option(3, "timed training batches per training row", ge=1, le=1000)
    train_overrides: Optional[list[str]] = option(help="config overrides of the training rows (algo.steps_per_batch=8: quick rows)",
                                                  factory=list)


__all__ = ["BenchOptions", "CrossplayOptions", "DEFAULT_BATCH", "EloOptions", "ExploitabilityOptions", "PlayOptions", "POOLS",
           "ReplayOptions", "SCENARIOS", "SEED_MAX", "SPLIT", "UNTIL"]
