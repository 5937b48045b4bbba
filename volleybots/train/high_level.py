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
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import torch

from volleybots.errors import ConfigError
from volleybots.keys import DONE
from volleybots.play.episodes import run_episodes
from volleybots.play.games import side_env
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

    def check(self) -> None:
        for key in ("games", "batch", "epochs"):
            v = getattr(self, key)
            if not isinstance(v, int) or isinstance(v, bool) or not 1 <= v <= 10**8:
                raise ConfigError(f"high level {key}={v!r} must be an int in 1..1e8")
        for key, hi in (("lr", 1.0), ("clip", 1.0), ("entropy", 10.0), ("value_coeff", 100.0)):
            v = getattr(self, key)
            if not isinstance(v, (int, float)) or isinstance(v, bool) or not 0 <= v <= hi:
                raise ConfigError(f"high level {key}={v!r} must be a number in [0, {hi}]")


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


def update(net: HighLevelNet, opt, chooser: LearnedChooser, results: torch.Tensor, cfg: HighLevelConfig) -> dict:
    """PPO steps on the recorded choices, each paid its game's result."""
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


def train_high_level(match_cfg, drills: dict | None, opponent, cfg: HighLevelConfig, log=None,
                      start: HighLevelNet | None = None) -> tuple[HighLevelNet, list[dict]]:
    """A high level trained against ``opponent`` (a competitor spec, or a ``Competitor``: a population's
    mixture draws one member per world and game; None: self-play, the same drills under a second
    chooser over the learning net, which samples its choices and records none) over the ``drills`` (drill -> checkpoint; the others
    scripted) on the 3 vs 3 match config ``match_cfg``, from ``start``'s weights if given (else near
    uniform); the per-batch history (results, choices, the share of each option) goes to ``log`` as it
    is made."""
    cfg.check()
    if match_cfg.task.name != "3v3":
        raise ConfigError(f"a high level plays task 3v3, not {match_cfg.task.name!r}")
    torch.manual_seed(cfg.seed)
    gen = torch.Generator().manual_seed(cfg.seed)
    net = HighLevelNet(start.hidden if start is not None else cfg.hidden)
    if start is not None:
        net.load_state_dict(start.state_dict())
    opt = torch.optim.Adam(net.parameters(), lr=cfg.lr)
    comp = resolve_competitor(opponent) if isinstance(opponent, str) else opponent
    mirror = LearnedChooser(net, greedy=False, generator=gen, record=False, receive_coming=cfg.receive_coming,
                            receive_attack=cfg.receive_attack)
    envs, teams, opps = [], [], []
    chooser = LearnedChooser(net, greedy=False, generator=gen, record=True, receive_coming=cfg.receive_coming,
                             receive_attack=cfg.receive_attack)
    for side in (0, 1):
        env = side_env(match_cfg, side, "any", cfg.batch, cfg.seed * 2 + side)
        lows = {k: learned_drill(k, v, env, True) for k, v in (drills or {}).items()}
        envs.append(env)
        teams.append(make_hierarchical(env, lows, gen, chooser))
        opps.append(make_hierarchical(env, lows, gen, mirror) if comp is None else comp.team_policy(env, False, gen))
    history, played, start = [], 0, time.monotonic()
    while played < cfg.games:
        side = (played // cfg.batch) % 2
        results, stats = play_batch(envs[side], teams[side], opps[side], chooser, side)
        row = {"games": played + cfg.batch, "side": side, "frames": int(stats["episode_len"].sum()), "won": int((results > 0).sum()),
               "drawn": int((results == 0).sum()),
               "lost": int((results < 0).sum()), "touches": float(stats[f"hits_team{side}"].mean()),
               "wall_s": round(time.monotonic() - start, 1), **update(net, opt, chooser, results, cfg)}
        for kind, n in CHOICES.items():
            picks = [p for k, *_, p in chooser.memory if k == kind]
            if picks:
                row[f"share_{kind}"] = torch.bincount(torch.cat(picks), minlength=n).tolist()
        history.append(row)
        if log is not None:
            log(row)
        played += cfg.batch
        if cfg.time_limit and time.monotonic() - start > cfg.time_limit:
            break
    net.eval()
    return net, history


__all__ = ["HighLevelConfig", "play_batch", "train_high_level", "update"]
