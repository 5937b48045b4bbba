"""PPO on Solo Bump through the Gymnasium vector env: a CleanRL-style single-file loop that knows
nothing of volleybots beyond the environment id.

    pip install -e ".[gym]"
    python examples/cleanrl_ppo_solo_bump.py                      # 4,096 steps, well under a minute on a CPU
    python examples/cleanrl_ppo_solo_bump.py --total-timesteps 2000000 --num-envs 256
    python examples/cleanrl_ppo_solo_bump.py --env-id volleybots/Hover-v0 --num-envs 64 --num-steps 64 \
        --total-timesteps 1000000 --curve outputs/cleanrl_hover.csv        # a curve that falls within minutes

It follows CleanRL's ``ppo_continuous_action.py`` (a Gaussian policy with a state-independent log-std,
GAE, clipped surrogate, minibatch epochs) with one change the env's autoreset asks for: the vector
env resets a finished world within the step (Gymnasium's same-step autoreset), so the value of a
truncated episode's last observation, ``info["final_obs"]``, is added to its last reward instead of
being lost at the cut. A short run on Solo Bump learns little (its first bumps take hours of PPO);
on Hover, 1M steps take the mean distance to the target from about 3.5 m to about 1 m in minutes
(docs/integrations.md shows two seeds). It prints the finished episodes' returns as it goes: as in
CleanRL, from Gymnasium's ``RecordEpisodeStatistics`` (``info["episode"]["r"]``), beside the task's own
metric (``info["final_stats"]``: Solo Bump's bumps, Hover's distance), and ``--curve`` writes them as CSV.
"""

from __future__ import annotations

import argparse
import time

import gymnasium as gym
import numpy as np
import torch
from torch import nn
from torch.distributions.normal import Normal

import volleybots.integrations  # noqa: F401  (registers the volleybots/... ids)


def parse_args(argv=None) -> argparse.Namespace:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--env-id", default="volleybots/SoloBump-v0")
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--total-timesteps", type=int, default=4096)
    p.add_argument("--num-envs", type=int, default=32)
    p.add_argument("--num-steps", type=int, default=32, help="steps per env per rollout")
    p.add_argument("--learning-rate", type=float, default=3e-4)
    p.add_argument("--gamma", type=float, default=0.99)
    p.add_argument("--gae-lambda", type=float, default=0.95)
    p.add_argument("--num-minibatches", type=int, default=4)
    p.add_argument("--update-epochs", type=int, default=4)
    p.add_argument("--clip-coef", type=float, default=0.2)
    p.add_argument("--ent-coef", type=float, default=0.0)
    p.add_argument("--vf-coef", type=float, default=0.5)
    p.add_argument("--max-grad-norm", type=float, default=0.5)
    p.add_argument("--threads", type=int, default=1, help="torch CPU threads")
    p.add_argument("--curve", default=None, help="CSV file for the learning curve (one row per iteration)")
    return p.parse_args(argv)


def layer(i: int, o: int, std: float = np.sqrt(2)) -> nn.Linear:
    lin = nn.Linear(i, o)
    nn.init.orthogonal_(lin.weight, std)
    nn.init.zeros_(lin.bias)
    return lin


class Agent(nn.Module):
    def __init__(self, obs_dim: int, act_dim: int):
        super().__init__()
        self.critic = nn.Sequential(layer(obs_dim, 64), nn.Tanh(), layer(64, 64), nn.Tanh(), layer(64, 1, 1.0))
        self.actor_mean = nn.Sequential(layer(obs_dim, 64), nn.Tanh(), layer(64, 64), nn.Tanh(), layer(64, act_dim, 0.01))
        self.actor_logstd = nn.Parameter(torch.zeros(1, act_dim))

    def value(self, x):
        return self.critic(x).squeeze(-1)

    def act(self, x, action=None):
        mean = self.actor_mean(x)
        dist = Normal(mean, self.actor_logstd.expand_as(mean).exp())
        if action is None:
            action = dist.sample()
        return action, dist.log_prob(action).sum(-1), dist.entropy().sum(-1), self.value(x)


def main(argv=None) -> list[float]:
    """Train; returns the returns of the episodes that finished."""
    args = parse_args(argv)
    torch.set_num_threads(args.threads)
    torch.manual_seed(args.seed)
    envs = gym.wrappers.vector.RecordEpisodeStatistics(gym.make_vec(args.env_id, num_envs=args.num_envs))
    obs_dim = envs.single_observation_space.shape[0]
    act_dim = envs.single_action_space.shape[0]
    low, high = envs.single_action_space.low, envs.single_action_space.high
    agent = Agent(obs_dim, act_dim)
    optimizer = torch.optim.Adam(agent.parameters(), lr=args.learning_rate, eps=1e-5)

    n, t_len = args.num_envs, args.num_steps
    obs_buf = torch.zeros(t_len, n, obs_dim)
    act_buf = torch.zeros(t_len, n, act_dim)
    logp_buf, rew_buf, done_buf, val_buf = (torch.zeros(t_len, n) for _ in range(4))
    batch = n * t_len
    minibatch = batch // args.num_minibatches
    iterations = max(1, args.total_timesteps // batch)

    returns: list[float] = []
    metric: list[float] = []  # the task's headline statistic (Solo Bump's bumps, Hover's distance, ...)
    metric_name = getattr(envs.unwrapped, "metric", None)  # its key in info["final_stats"]
    curve = []  # one row per iteration: steps, seconds, episodes, mean return and metric of the last 20
    start = time.time()
    next_obs = torch.as_tensor(envs.reset(seed=args.seed)[0])
    next_done = torch.zeros(n)
    for it in range(iterations):
        for step in range(t_len):
            obs_buf[step], done_buf[step] = next_obs, next_done
            with torch.no_grad():
                action, logp, _, value = agent.act(next_obs)
            act_buf[step], logp_buf[step], val_buf[step] = action, logp, value
            obs, reward, term, trunc, info = envs.step(np.clip(action.numpy(), low, high))
            reward = torch.as_tensor(reward, dtype=torch.float32)
            if "final_obs" in info:  # same-step autoreset: bootstrap the cut-off episodes from their last observation
                cut = torch.as_tensor(trunc & info["_final_obs"])
                if cut.any():
                    with torch.no_grad():
                        last = agent.value(torch.as_tensor(info["final_obs"][cut.numpy()]))
                    reward[cut] += args.gamma * last
            if "episode" in info:  # the episodes that just ended (RecordEpisodeStatistics)
                returns += info["episode"]["r"][info["_episode"]].tolist()
                if metric_name in info.get("final_stats", {}):
                    metric += info["final_stats"][metric_name][info["_final_stats"]].tolist()
            rew_buf[step] = reward
            next_obs, next_done = torch.as_tensor(obs), torch.as_tensor(term | trunc, dtype=torch.float32)

        with torch.no_grad():  # GAE
            next_value = agent.value(next_obs)
            adv = torch.zeros(t_len, n)
            gae = torch.zeros(n)
            for t in reversed(range(t_len)):
                not_done = 1.0 - (next_done if t == t_len - 1 else done_buf[t + 1])
                nv = next_value if t == t_len - 1 else val_buf[t + 1]
                delta = rew_buf[t] + args.gamma * nv * not_done - val_buf[t]
                gae = delta + args.gamma * args.gae_lambda * not_done * gae
                adv[t] = gae
            ret = adv + val_buf

        b_obs, b_act, b_logp = obs_buf.reshape(batch, obs_dim), act_buf.reshape(batch, act_dim), logp_buf.reshape(batch)
        b_adv, b_ret = adv.reshape(batch), ret.reshape(batch)
        for _ in range(args.update_epochs):
            for mb in torch.randperm(batch).split(minibatch):
                _, logp, entropy, value = agent.act(b_obs[mb], b_act[mb])
                ratio = (logp - b_logp[mb]).exp()
                a = b_adv[mb]
                a = (a - a.mean()) / (a.std() + 1e-8)
                pg_loss = torch.max(-a * ratio, -a * ratio.clamp(1 - args.clip_coef, 1 + args.clip_coef)).mean()
                v_loss = 0.5 * (value - b_ret[mb]).pow(2).mean()
                loss = pg_loss - args.ent_coef * entropy.mean() + args.vf_coef * v_loss
                optimizer.zero_grad()
                loss.backward()
                nn.utils.clip_grad_norm_(agent.parameters(), args.max_grad_norm)
                optimizer.step()
        frames = (it + 1) * batch
        ret20, met20 = (float(np.mean(x[-20:])) if x else float("nan") for x in (returns, metric))
        curve.append((frames, time.time() - start, len(returns), ret20, met20))
        recent = f"{ret20:.2f}" + (f", {metric_name} {met20:.2f}" if metric else "")
        print(f"iter {it}: {frames} steps, {frames / (time.time() - start):.0f} steps/s, {len(returns)} episodes, "
              f"mean return of the last 20: {recent}, value loss {v_loss.item():.3f}")
    envs.close()
    if args.curve:
        write_curve(args.curve, curve, metric_name)
    return returns


def write_curve(path: str, rows: list[tuple], metric_name: str | None) -> None:
    """The learning curve as CSV: env-steps, wall seconds, episodes finished, and the mean return and
    task metric of the last 20 finished episodes (``benchmarks/curves_rise.py`` plots it)."""
    import csv
    from pathlib import Path

    Path(path).parent.mkdir(parents=True, exist_ok=True)
    with open(path, "w", newline="") as fh:
        out = csv.writer(fh)
        out.writerow(["steps", "seconds", "episodes", "return", metric_name or "metric"])
        out.writerows(rows)


if __name__ == "__main__":
    main()
