"""Train the hierarchical 3 vs 3 team's high level by RL against an opponent (the HCSP route;
docs/hierarchical.md#a-learned-high-level).

The drills stay fixed (scripted or trained checkpoints); the high level's three choices (who
receives, who sets, who attacks on which side: ``volleybots.scripted.hierarchical.CHOICES``) are
made by a ``HighLevelNet`` that samples them. Each batch plays ``batch`` games (one per world, the
team on team 0 and team 1 in turn, the server drawn at random) against the opponent; every choice
a team made in a game is paid that game's result from its side (+1 won, -1 lost, 0 drawn), less
the value head's estimate for that choice, and the heads take ``epochs`` clipped-ratio (PPO)
steps on it. Games are short and each holds a handful of choices, so the result itself is the return:
there is nothing to discount.

A batch's games are played in ``chunks`` parts of near-equal size, each by a ``ChunkPlayer`` that keeps
its own envs, generator and share of torch's random stream from batch to batch, seeded by the run's
seed and the chunk alone (``chunk_seed``), so where a chunk is played does not change its games:
``pool`` keeps the players here, playing in turn, or in Ray actors playing at once
(``volleybots.play.pool``, ``population.oracle_pool``), and the chunks' choices and results are joined in
chunk order before the update, so either pool trains the same high level, bit for bit (one torch
thread). The number of chunks does change the games, and costs serial play (a chunk lasts as long as
its longest game, and stepping 64 worlds costs nearly what 256 do: 4 chunks of 64 took 2.3-4.9x one
batch of 256 on 2 cores), so it is part of the recipe: 1 by default (the games of before chunks), more
only to spread a batch over a cluster.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from types import SimpleNamespace

import numpy as np
import torch

from volleybots.errors import ConfigError
from volleybots.keys import DONE
from volleybots.play.episodes import run_episodes
from volleybots.play.games import side_env
from volleybots.play.pool import call_workers, check_pool, start_workers, stop_workers
from volleybots.policies.builtin import learned_drill
from volleybots.policies.competitors import resolve_competitor
from volleybots.policies.high_level import HighLevelNet, LearnedChooser
from volleybots.scripted.hierarchical import CHOICES, make_hierarchical
from volleybots.tasks.multi import TeamPolicies


@dataclass
class HighLevelConfig:
    games: int = 4096  # games to train on (each side half of them)
    batch: int = 128  # games (worlds) per batch and update
    lr: float = 1e-3  # Adam's learning rate, for the choice and value heads
    epochs: int = 4  # clipped-ratio steps per batch
    clip: float = 0.2  # PPO's ratio clip
    entropy: float = 0.01  # entropy bonus per choice: keeps every option tried while the results are noisy
    value_coeff: float = 0.5  # weight of the value heads' squared error
    hidden: tuple[int, ...] = (64, 64)  # hidden sizes of every head
    seed: int = 0  # the run's seed: games, sampling and the networks' start
    receive_coming: bool = False  # call a receiver only for balls coming down in the own half (saved with the net)
    receive_attack: bool = False  # a front drone called to receive returns the ball at once with the attack drill (saved too)
    time_limit: float = 0.0  # seconds; 0: none (the batch under way is finished)
    pool: str = "serial"  # where a batch's chunks are played: serial (here, in turn) or ray (Ray tasks; the same games)
    chunks: int = 1  # parts a batch's games are played in (each its own env; Ray tasks with pool=ray); at most batch

    def check(self) -> None:
        for key in ("games", "batch", "epochs", "chunks"):
            v = getattr(self, key)
            if not isinstance(v, int) or isinstance(v, bool) or not 1 <= v <= 10**8:
                raise ConfigError(f"high level {key}={v!r} must be an int in 1..1e8")
        for key, hi in (("lr", 1.0), ("clip", 1.0), ("entropy", 10.0), ("value_coeff", 100.0)):
            v = getattr(self, key)
            if not isinstance(v, (int, float)) or isinstance(v, bool) or not 0 <= v <= hi:
                raise ConfigError(f"high level {key}={v!r} must be a number in [0, {hi}]")
        if self.chunks > self.batch:
            raise ConfigError(f"high level chunks={self.chunks} must be at most batch={self.batch} (a chunk plays at least one game)")


def _results(winner: torch.Tensor, side: int) -> torch.Tensor:
    """+1 / -1 / 0 per game from the side of team ``side`` (the referee's winner is -1 for a draw)."""
    w = winner.round().long()
    return torch.where(w < 0, 0.0, torch.where(w == side, 1.0, -1.0))


def play_batch(env, team, opponent, chooser: LearnedChooser, side: int) -> tuple[torch.Tensor, dict]:
    """One game per world with the learned team on team ``side``: the results [N] from its side and
    the episode statistics; the chooser's choices after a world's first game ended are dropped."""
    done_at = torch.full((env.num_envs,), 1 << 30, dtype=torch.long)
    policies = TeamPolicies(env, (team, opponent) if side == 0 else (opponent, team))

    def act(td):
        chooser.tick()
        return policies(td)

    def on_step(env_, td, nxt):
        done = nxt[DONE].reshape(-1).cpu()
        done_at.copy_(torch.where(done & (done_at == 1 << 30), chooser.step, done_at))

    chooser.memory.clear()
    chooser.step = 0
    stats = run_episodes(env, act, on_step)
    kept = []
    for kind, envs, step, feats, legal, pick in chooser.memory:
        live = step <= done_at[envs]  # made before (or at the step) the world's first game ended
        kept.append((kind, envs[live], step, feats[live], legal[live], pick[live]))
    chooser.memory[:] = kept
    return _results(stats["winner"], side), stats


def update(net: HighLevelNet, opt, chooser, results: torch.Tensor, cfg: HighLevelConfig) -> dict:
    """PPO steps on the recorded choices (``chooser.memory``), each paid its game's result."""
    by_kind = {}
    for kind in CHOICES:
        rows = [(e, f, ok, p) for k, e, _, f, ok, p in chooser.memory if k == kind and len(e)]
        if rows:
            e, f, ok, p = (torch.cat(x) for x in zip(*rows))
            with torch.no_grad():
                old = torch.log_softmax(net.logits(kind, f, ok), -1).gather(1, p[:, None]).squeeze(1)
            by_kind[kind] = (f, ok, p, results[e], old)
    if not by_kind:
        return {"choices": 0}
    for _ in range(cfg.epochs):
        loss = 0.0
        for kind, (f, ok, p, ret, old) in by_kind.items():
            logits = net.logits(kind, f, ok)
            logp = torch.log_softmax(logits, -1)
            new = logp.gather(1, p[:, None]).squeeze(1)
            value = net.value(kind, f)
            adv = ret - value.detach()
            ratio = (new - old).exp()
            policy_loss = -torch.min(ratio * adv, ratio.clamp(1 - cfg.clip, 1 + cfg.clip) * adv).mean()
            probs = logp.exp()
            entropy = -(probs * torch.where(ok, logp, torch.zeros_like(logp))).sum(-1).mean()
            loss = loss + policy_loss - cfg.entropy * entropy + cfg.value_coeff * (value - ret).pow(2).mean()
        opt.zero_grad()
        loss.backward()
        opt.step()
    return {"choices": int(sum(len(v[0]) for v in by_kind.values())),
            **{f"choices_{k}": int(len(v[0])) for k, v in by_kind.items()}}


def chunk_seed(seed: int, chunk: int) -> int:
    """The seed of chunk ``chunk`` (>= 1) of a run seeded ``seed``: a hash of the two (numpy's SeedSequence),
    so neighbouring runs and chunks do not share games; below 2**61, so that the env's seed offsets stay in
    a torch generator's range. Chunk 0 keeps the run's seed itself (one chunk: the games of before)."""
    a, b = np.random.SeedSequence([seed, chunk]).generate_state(2)
    return (int(a) << 29) | (int(b) >> 3)


class ChunkPlayer:
    """One chunk of every batch: its worlds on each side (an env a side, built once), its generator and
    its share of torch's global random stream (``rng``, swapped in around each call), so that its games
    depend on its seed and the weights it is handed alone, wherever it runs (here, or in a Ray actor).

    Chunk 0 is built as the whole batch was before chunks (seed, envs ``seed * 2 + side``, the global
    stream as the net's initialisation left it, ``rng``), so one chunk trains the high levels of before."""

    def __init__(self, match_cfg, drills: dict | None, opponent, hidden, options: tuple[bool, bool], size: int, seed: int, rng=None):
        with torch.random.fork_rng(devices=[]):  # drills and flat opponents sample from torch's global generator
            self.net = HighLevelNet(hidden)  # before the chunk's stream: its weights come with every call
            if rng is None:
                torch.manual_seed(seed)
            else:
                torch.set_rng_state(rng)
            self.gen = torch.Generator().manual_seed(seed)
            self.chooser = LearnedChooser(self.net, greedy=False, generator=self.gen, record=True, receive_coming=options[0],
                                          receive_attack=options[1])
            # self-play (opponent None): the same drills under a second chooser over the same net, sampling
            # its choices and recording none
            mirror = LearnedChooser(self.net, greedy=False, generator=self.gen, record=False, receive_coming=options[0],
                                    receive_attack=options[1])
            comp = resolve_competitor(opponent) if isinstance(opponent, str) else opponent
            self.envs, self.teams, self.opps = [], [], []
            for side in (0, 1):
                env = side_env(match_cfg, side, "any", size, seed * 2 + side)
                lows = {k: learned_drill(k, v, env, True) for k, v in (drills or {}).items()}
                self.envs.append(env)
                self.teams.append(make_hierarchical(env, lows, self.gen, self.chooser))
                self.opps.append(make_hierarchical(env, lows, self.gen, mirror) if comp is None else comp.team_policy(env, False, self.gen))
            self.rng = torch.get_rng_state()

    def play(self, state: dict, side: int) -> dict:
        """The chunk's next game a world with the high level of weights ``state`` on team ``side``: the
        results from its side, frames, the team's touches per game and the choices (chunk world indices)."""
        self.net.load_state_dict(state)
        with torch.random.fork_rng(devices=[]):
            torch.set_rng_state(self.rng)
            results, stats = play_batch(self.envs[side], self.teams[side], self.opps[side], self.chooser, side)
            self.rng = torch.get_rng_state()
        return {"results": results, "frames": int(stats["episode_len"].sum()), "touches": stats[f"hits_team{side}"],
                "memory": list(self.chooser.memory)}

    def rng_state(self) -> torch.Tensor:
        return self.rng


def play_chunks(players: list, sizes: list[int], net: HighLevelNet, side: int):
    """A batch's games on side ``side``, every chunk at once (Ray) or in turn, joined in chunk order: the
    results [batch], frames, mean touches and a holder of the choices (``update``'s ``chooser``)."""
    state = {k: v.detach().clone() for k, v in net.state_dict().items()}
    parts = call_workers(players, "play", [(state, side)] * len(players))
    memory, offset = [], 0
    for n, part in zip(sizes, parts):  # a chunk's worlds follow the ones before it
        memory += [(kind, envs + offset, step, f, ok, pick) for kind, envs, step, f, ok, pick in part["memory"]]
        offset += n
    results = torch.cat([p["results"] for p in parts])
    touches = float(torch.cat([p["touches"] for p in parts]).mean())
    return results, sum(p["frames"] for p in parts), touches, SimpleNamespace(memory=memory)


def train_high_level(match_cfg, drills: dict | None, opponent, cfg: HighLevelConfig, log=None,
                      start: HighLevelNet | None = None) -> tuple[HighLevelNet, list[dict]]:
    """A high level trained against ``opponent`` (a competitor spec, or a ``Competitor``: a population's
    mixture draws one member per world and game; None: self-play, the same drills under a second
    chooser over the learning net, which samples its choices and records none) over the ``drills``
    (drill -> checkpoint; the others scripted) on the 3 vs 3 match config ``match_cfg``, from ``start``'s weights if given (else near
    uniform); the per-batch history (results, choices, the share of each option) goes to ``log`` as it
    is made."""
    cfg.check()
    if match_cfg.task.name != "3v3":
        raise ConfigError(f"a high level plays task 3v3, not {match_cfg.task.name!r}")
    if cfg.pool != "serial":
        check_pool(cfg.pool, "population.oracle_pool")  # before the first game: ray installed, RAY_ADDRESS answering
    torch.manual_seed(cfg.seed)
    net = HighLevelNet(start.hidden if start is not None else cfg.hidden)
    if start is not None:
        net.load_state_dict(start.state_dict())
    opt = torch.optim.Adam(net.parameters(), lr=cfg.lr)
    sizes = [cfg.batch // cfg.chunks + (c < cfg.batch % cfg.chunks) for c in range(cfg.chunks)]
    options = (cfg.receive_coming, cfg.receive_attack)
    inits = [(drills, opponent, net.hidden, options, n, chunk_seed(cfg.seed, c) if c else cfg.seed, None if c else torch.get_rng_state())
             for c, n in enumerate(sizes)]
    players = start_workers(ChunkPlayer, match_cfg, inits, cfg.pool, "population.oracle_pool")
    history, played, t0 = [], 0, time.monotonic()
    try:
        while played < cfg.games:
            side = (played // cfg.batch) % 2
            results, frames, touches, chosen = play_chunks(players, sizes, net, side)
            row = {"games": played + cfg.batch, "side": side, "frames": frames, "won": int((results > 0).sum()),
                   "drawn": int((results == 0).sum()), "lost": int((results < 0).sum()), "touches": touches,
                   "wall_s": round(time.monotonic() - t0, 1), **update(net, opt, chosen, results, cfg)}
            for kind, n in CHOICES.items():
                picks = [p for k, *_, p in chosen.memory if k == kind]
                if picks:
                    row[f"share_{kind}"] = torch.bincount(torch.cat(picks), minlength=n).tolist()
            history.append(row)
            if log is not None:
                log(row)
            played += cfg.batch
            if cfg.time_limit and time.monotonic() - t0 > cfg.time_limit:
                break
        torch.set_rng_state(call_workers(players[:1], "rng_state", [()])[0])  # torch's stream left as one chunk's games left it
    finally:
        stop_workers(players)
    net.eval()
    return net, history


__all__ = ["ChunkPlayer", "HighLevelConfig", "chunk_seed", "play_batch", "play_chunks", "train_high_level", "update"]
