"""Lookahead (scripted/lookahead.py): its rollouts are the physics (a set flown on the model leaves
the racket as the env's does), and it flies the variant its cost ranks best."""

import pytest
import torch

import volleybots
from volleybots.scripted import make_scripted_policy
from volleybots.scripted.control import DroneObs

G = 9.81
STEPS = 60  # the dropped ball meets the setter's racket about 0.6 s in


def setter_view(td, pol):
    """The setter's (drone 0's) state, the ball and its home, from the observation."""
    drone, parts = pol.parts(td["agents", "observation"][:, 0])
    ball_p, ball_v = pol.ball(drone, parts)
    return drone, ball_p, ball_v, drone.pos - parts["anchor"]


def free_flight(p, v):
    """What a free flight keeps: horizontal velocity and apex height."""
    return torch.cat((v[..., :2], (p[..., 2] + v[..., 2] ** 2 / (2 * G)).unsqueeze(-1)), -1)


def test_rollout_predicts_the_envs_set():
    env = volleybots.make_env("set_and_spike_easy", num_envs=4, seed=0)
    pol = make_scripted_policy(env)
    td = env.reset()
    drone, bp, bv, home = setter_view(td, pol)
    out = pol.lookahead.rollout(drone, bp, bv, lambda d, p, v: pol.set_action(d, p, v, pol.set_velocity, home), STEPS)
    assert out.hit.sum() >= 3 and (out.hit ^ out.body).all()
    predicted = free_flight(out.ball_pos, out.ball_vel)

    # the env flies the same set (the attacker hovers 5 m away: no downwash reaches the setter)
    seen = torch.full_like(predicted, float("nan"))
    for _ in range(STEPS):
        drone, bp, bv, home = setter_view(td, pol)
        attacker = DroneObs.from_obs(td["agents", "observation"][:, 1], True)
        action = torch.stack((pol.set_action(drone, bp, bv, pol.set_velocity, home),
                              pol.ctrl.act(attacker, attacker.pos, torch.zeros_like(attacker.pos))), 1)
        td["agents", "action"] = action
        td = env.step(td)["next"]
        hit = td["stats", "setter_hit"].reshape(-1) > 0
        drone, bp, bv, _ = setter_view(td, pol)
        seen = torch.where((hit & seen[:, 0].isnan()).unsqueeze(-1), free_flight(bp, bv), seen)
    # the model's body touches are the env's too (a body touch ends the episode: no set is seen)
    assert torch.equal(~seen[:, 0].isnan(), out.hit)
    # a set's speed is ~6 m/s and its apex ~5 m: the model gets both to within a centimetre
    assert torch.allclose(predicted[out.hit], seen[out.hit], atol=1e-2), (predicted, seen)


def test_choose_flies_the_cheapest_variant():
    env = volleybots.make_env("set_and_spike_easy", num_envs=3, seed=1)
    pol = make_scripted_policy(env)
    drone, bp, bv, home = setter_view(env.reset(), pol)
    steps = torch.tensor((0.0, -1.0, 1.0))
    variants = torch.cartesian_prod(steps, steps) * 0.3  # the set aimed around the attack spot

    def fly(d, p, v, var, w):
        return pol.set_action(d, p, v, lambda q, u: pol.set_velocity(q, u, var), w)

    k = len(variants)
    action, cost = pol.lookahead.choose(drone, bp, bv, variants, lambda d, p, v, var: fly(d, p, v, var, home.repeat_interleave(k, 0)),
                                        pol.set_cost, STEPS)
    # every variant on its own
    each, first = [], []
    for var in variants:
        out = pol.lookahead.rollout(drone, bp, bv, lambda d, p, v, var=var: fly(d, p, v, var.expand(len(p), 2), home), STEPS)
        each.append(pol.set_cost(out))
        first.append(out.action)
    each, first = torch.stack(each, 1), torch.stack(first, 1)
    best = each.argmin(1)
    assert torch.allclose(cost, each.min(1).values, atol=1e-5)
    assert torch.allclose(action, first[torch.arange(3), best], atol=1e-5)
    # the plain set (variant 0) is never better than the one chosen, and every set is a racket touch
    assert (cost <= each[:, 0] + 1e-6).all() and (each < 100).all()


def test_variant_rows_lists_every_combination_plain_first():
    from volleybots.scripted.lookahead import variant_rows

    aims = torch.tensor(((0.0, 0.0), (1.0, 0.0), (0.0, -1.0)))
    table = variant_rows(aims, torch.tensor((0.0, 1.0)), torch.tensor((0.0, -0.25)))
    assert table.shape == (12, 4)
    assert torch.equal(table[0], torch.zeros(4))  # every table's plain value first
    # the first table varies slowest: its row repeats over the 4 combinations of the others
    assert torch.equal(table[:4, :2], aims[:1].expand(4, 2)) and torch.equal(table[4:8, :2], aims[1:2].expand(4, 2))
    assert len({tuple(r.tolist()) for r in table}) == 12


def _searched_per_step(every: int, steps: int, seed: int = 0):
    """Bump and Pass's opening (its lookahead chooses over the ball's whole fall) with ``every``:
    how many drones each step searched for, the actions, and the player."""
    env = volleybots.make_env("bump_and_pass", num_envs=2, seed=seed)
    pol = make_scripted_policy(env).replan_every(every)
    search, counts = pol.lookahead._search, []

    def counted(drone, ball_p, *args, **kw):
        counts[-1] += ball_p.shape[0]
        return search(drone, ball_p, *args, **kw)

    pol.lookahead._search = counted
    td, actions = env.reset(), []
    for _ in range(steps):
        counts.append(0)
        td = pol(td)
        actions.append(td["agents", "action"].clone())
        td = env.step_mdp(env.step(td))
    return counts, torch.stack(actions), (env, pol, td)


@pytest.mark.slow  # not slow by nature, but measured too long for the quick tier
def test_a_kept_choice_searches_every_k_steps_and_starts_as_the_memoryless_player():
    """Lookahead.every: a drone searches once per ``every`` steps of a touch (about ``every`` times
    fewer searches), its first step is the memoryless player's own, and a new episode searches
    afresh (the memo follows the plan's time to go, which a new touch resets)."""
    fresh, plain, _ = _searched_per_step(1, 30)
    kept, held, (env, pol, td) = _searched_per_step(4, 30)
    assert sum(fresh) >= 2 * 20  # both openers choose on most steps of the fall
    assert torch.equal(plain[0], held[0]) and fresh[0] == kept[0] == 2
    assert sum(fresh) / 4 - 2 <= sum(kept) <= sum(fresh) / 4 + 2, (sum(fresh), sum(kept))
    assert not torch.equal(plain, held)  # later, the kept variants fly differently
    # a new episode's opening: its first choosing step searches for every opener again
    td = env.reset()
    memo = next(iter(pol.lookahead._memo.values()))
    memo["age"].zero_()  # as if each had just searched: only the plan's time to go tells the touches apart
    pol(td)
    assert not memo["valid"].any()
