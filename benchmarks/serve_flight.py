"""What a serve does to the receiver: the ball's flight after the serve touch against the receiver's reach.

    python benchmarks/serve_flight.py SERVER RECEIVER games=100 seed=9500 [task=1v1] [json=OUT]

SERVER serves every game (team 0), RECEIVER receives (team 1); both are competitors
(``zoo:1v1/sp_noanchor``, ``scripted``, a run dir, ...). Each game is followed from the serve touch
(the server's first touch) to its end, on the env's own physics state:

- ``flight_s``: seconds from the serve touch to the receiver's first touch, or to the end of the
  point (a landing, for an ace); the other figures are read over the same stretch;
- ``ball_speed``: the ball's speed just after the serve touch (m/s);
- ``apex_z``: the highest point of the ball after the serve touch (m);
- ``land_x``: where the ball was at the stretch's end (the receiver's side is x < 0);
- ``receiver_to_land_m``: horizontal distance from the receiver's position at the serve touch to
  the ball's position at the stretch's end;
- ``closest_m``: the receiver's closest approach to the ball during the flight;
- ``receiver_max_speed``: the receiver's top speed during the flight (m/s).

Each is reported as mean, min and max over the aces (serves the receiver never touched) and over the
returned serves. ``docs/results/table3-1v1.md`` ("Longer self-play: the ace serve") quotes its figures.
"""

from __future__ import annotations

import json
import statistics
from dataclasses import dataclass
from pathlib import Path
from typing import Optional

import torch
from omegaconf import OmegaConf

from volleybots.config import load, make_env, to_dict
from volleybots.config.args import option, script_options
from volleybots.policies import resolve_competitor
from volleybots.tasks.multi import TeamPolicies

KEYS = ("flight_s", "ball_speed", "apex_z", "land_x", "receiver_to_land_m", "closest_m", "receiver_max_speed")


def flights(server: str, receiver: str, games: int, seed: int, task: str = "1v1", max_steps: int = 400) -> list[dict]:
    """One record per game whose serve was touched and then returned or ended within ``max_steps`` steps."""
    cfg = OmegaConf.create(to_dict(load([f"task={task}", "threads=1"])))
    cfg.task.serve = 0
    env = make_env(cfg, num_envs=games, seed=seed)
    with torch.random.fork_rng(devices=[]):
        torch.manual_seed(seed)
        gen = torch.Generator().manual_seed(seed)
        teams = tuple(resolve_competitor(c).team_policy(env, False, gen) for c in (server, receiver))
        policy = TeamPolicies(env, teams)
        td = env.reset()
        ball, pos, hits0, hits1, done = [], [], [], [], []
        for _ in range(max_steps):
            # env.step, not step_and_maybe_reset: the state at a game's last step is the one read
            td = env.step(policy(td))["next"].clone()
            s = env.physics.state
            ball.append(s.ball_pos.clone())
            pos.append(s.pos.clone())
            hits0.append(td["stats", "hits_team0"].reshape(games).clone())
            hits1.append(td["stats", "hits_team1"].reshape(games).clone())
            done.append(td["done"].reshape(games).clone())
            if torch.stack(done).any(0).all():
                break
    ball, pos = torch.stack(ball, 1), torch.stack(pos, 1)  # [N, T, 3], [N, T, drones, 3]
    hits0, hits1, done = torch.stack(hits0, 1), torch.stack(hits1, 1), torch.stack(done, 1)
    receiver_drone = env.n_drones // 2  # team 1's first drone (1v1: the receiver)
    dt = env.params.dt
    out = []
    for i in range(games):
        ended = bool(done[i].any())
        end = int(done[i].float().argmax()) if ended else done.shape[1] - 1
        served = hits0[i, : end + 1] >= 1
        if not served.any():
            continue
        t0 = int(served.float().argmax())
        touched = hits1[i, t0 : end + 1] >= 1
        returned = bool(touched.any())
        if not (ended or returned):
            continue
        stop = t0 + int(touched.float().argmax()) if returned else end  # the receiver's touch, or the point's end
        fl, rec = ball[i, t0:stop + 1], pos[i, t0:stop + 1, receiver_drone]
        speed = ((ball[i, t0 + 1] - ball[i, t0]) / dt).norm().item() if t0 < stop else float("nan")
        rec_speed = ((rec[1:] - rec[:-1]) / dt).norm(dim=-1).max().item() if len(rec) > 1 else 0.0
        out.append({
            "returned": returned, "flight_s": (stop - t0) * dt, "ball_speed": speed,
            "apex_z": fl[:, 2].max().item(), "land_x": ball[i, stop, 0].item(),
            "receiver_to_land_m": (rec[0, :2] - ball[i, stop, :2]).norm().item(),
            "closest_m": (fl - rec).norm(dim=-1).min().item(), "receiver_max_speed": rec_speed,
        })
    return out


def summary(records: list[dict]) -> dict:
    def stat(rows, key):
        v = [r[key] for r in rows]
        return {"mean": statistics.fmean(v), "min": min(v), "max": max(v)} if v else None

    aces = [r for r in records if not r["returned"]]
    returned = [r for r in records if r["returned"]]
    return {"games": len(records), "aces": len(aces), "returned": len(returned),
            **{k: {"ace": stat(aces, k), "returned": stat(returned, k)} for k in KEYS}}


@dataclass
class Args:
    server: Optional[str] = option(None, "the serving competitor", positional=True)
    receiver: Optional[str] = option(None, "the receiving competitor", positional=True)
    games: int = option(100, "games played")
    seed: int = option(9500, "the seed")
    task: str = option("1v1", "the task")
    json: Optional[Path] = option(None, "also write the summary here")


def main() -> None:
    a = script_options(Args, None, __doc__)
    torch.set_num_threads(1)
    res = {"server": a.server, "receiver": a.receiver, "seed": a.seed, "task": a.task,
           **summary(flights(a.server, a.receiver, a.games, a.seed, a.task))}
    text = json.dumps(res, indent=1)
    print(text)
    if a.json:
        a.json.write_text(text + "\n")


if __name__ == "__main__":
    main()
