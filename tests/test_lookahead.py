"""Lookahead (scripted/lookahead.py): its rollouts are the physics (a set flown on the model leaves
the racket as the env's does), and it flies the variant its cost ranks best."""

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
