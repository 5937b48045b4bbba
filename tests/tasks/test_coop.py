"""Cooperative tasks: specs, sizes, bump counting, set-and-spike components and the defence racket,
from constructed states; long random rollouts stay finite."""

import pytest
import torch
from torchrl.envs.utils import check_env_specs

import volleybots
from volleybots.tasks.defence import DefenceRacket, ballistic_crossing, racket_angles, racket_normal

COOP = {"bump_and_pass": 39, "set_and_spike_easy": 40, "set_and_spike_hard": 40}
G = 9.81


def make(name, n=1, **kw):
    env = volleybots.make_env(name, num_envs=n, seed=0, **kw)
    return env, env.reset()


def step(env, td):
    hover = torch.tensor(env.params.drone.hover_command).expand(env.num_envs, env.n_drones, 4).clone()
    return env.step(td.set(("agents", "action"), hover))["next"]


def ball(env, pos, vel=(0.0, 0.0, 0.0)):
    everyone = torch.ones(env.num_envs, dtype=torch.bool)
    pos = torch.as_tensor(pos, dtype=torch.float32).reshape(-1, 3).expand(env.num_envs, 3)
    env.place_ball(everyone, pos, vel)
    env.prev_ball[:] = pos
    env.referee.prev_ball_x[:] = pos[:, 0]


def racket_shot(env, drone):
    p = env.physics.state.pos[:, drone]
    ball(env, p + torch.tensor([0.0, 0.0, 0.2]), (0.0, 0.0, -3.0))


def aim(start, land, t):
    """Velocity that carries a ball from ``start`` to ``land`` in ``t`` seconds."""
    start, land = torch.tensor(start), torch.tensor(land)
    v = (land - start) / t
    v[2] += 0.5 * G * t
    return v


@pytest.mark.parametrize("action_space", ["prt", "ctbr", "discrete"])
@pytest.mark.parametrize("name", list(COOP))
def test_specs_and_observation_sizes(name, action_space):
    env = volleybots.make_env(name, num_envs=2, action_space=action_space)
    check_env_specs(env)
    td = env.reset()
    obs = COOP[name] - (4 if action_space == "ctbr" else 0)
    assert td["agents", "observation"].shape == (2, 2, obs)
    assert env.episode_len == 800


def test_reset_places_drones_around_anchors_and_ball_above_the_first():
    for name in COOP:
        env, td = make(name, n=16)
        s = env.physics.state
        off = s.pos - env.anchors
        assert (off[..., :2].abs() <= 0.5 + 1e-6).all() and (off[..., 2].abs() <= 0.2 + 1e-6).all()
        assert torch.allclose(s.ball_pos, (env.anchors[0] + torch.tensor([0.0, 0.0, 2.0])).expand(16, 3))
        assert env.referee.may_hit[:, 0].all() and not env.referee.may_hit[:, 1].any()


def test_bump_counts_only_high_crossings_toward_the_partner():
    env, td = make("bump_and_pass", n=2)
    racket_shot(env, 0)
    td = step(env, td)
    assert td["stats", "hits"].squeeze(-1).tolist() == [1.0, 1.0]
    assert env.referee.may_hit[:, 1].all()  # drone 1's turn now
    assert (td["agents", "observation"][:, :, 35:37] == torch.tensor([0.0, 1.0])).all()  # turn one-hot
    # the ball crosses the midline toward drone 1 at 4.3 m (env 0) and at 3.5 m (env 1)
    ball(env, torch.tensor([[4.5, -0.03, 4.3], [4.5, -0.03, 3.5]]), (0.0, 3.0, 0.0))
    td = step(env, td)
    assert td["stats", "passes"].squeeze(-1).tolist() == [1.0, 0.0]
    assert td["stats", "bumps"].squeeze(-1).tolist() == [1.0, 0.0]
    assert td["stats", "r_success_cross"].squeeze(-1).tolist() == [1.0, 0.0]  # shared: +1 to both
    assert not td["done"].any()


def test_bump_and_pass_wrong_turn_punishes_the_hitter_only():
    env, td = make("bump_and_pass")
    racket_shot(env, 0)
    td = step(env, td)
    for _ in range(4):
        ball(env, (4.5, 0.0, 4.0))
        td = step(env, td)
    racket_shot(env, 0)  # drone 0 again: not its turn
    td = step(env, td)
    assert td["terminated"].item()
    rew = td["agents", "reward"][0, :, 0]
    assert rew[0].item() < -9 and rew[1].item() > -1


def test_set_and_spike_components_from_real_touches():
    env, td = make("set_and_spike_easy")
    turn = lambda td: td["agents", "observation"][0, 0, 35:38].tolist()  # noqa: E731
    assert turn(td) == [1.0, 0.0, 0.0]
    racket_shot(env, 0)
    td = step(env, td)
    assert td["stats", "setter_hit"].item() == 1 and td["stats", "attacker_hit"].item() == 0
    assert turn(td) == [0.0, 1.0, 0.0]
    racket_shot(env, 1)  # the ball bounces up off a level racket: no downward spike
    td = step(env, td)
    assert td["stats", "attacker_hit"].item() == 1 and td["stats", "downward_spike"].item() == 0
    assert turn(td) == [0.0, 0.0, 1.0]
    assert td["stats", "success_rate"].item() == pytest.approx(0.5)
    assert td["stats", "r_success_hit"].item() == pytest.approx(10.0)


def spiked(env, td):
    """Pretend setter and attacker have hit and the spike went down."""
    for k in ("setter_hit", "attacker_hit", "downward_spike"):
        env.flags[k][:] = True
    env.referee.seq_index[:] = 2
    env.referee.may_hit[:] = False
    return td


@pytest.mark.parametrize("land,in_target", [((-4.3, 0.4, 0.1), True), ((-6.5, 1.5, 0.1), False)])
def test_easy_landing_in_target_is_a_success_not_a_penalty(land, in_target):
    env, td = make("set_and_spike_easy")
    td = spiked(env, td)
    start = (1.0, 1.0, 3.0)
    ball(env, start, aim(start, land, 0.6))
    for _ in range(60):
        td = step(env, td)
        if td["done"].item():
            break
    assert td["terminated"].item()
    assert td["stats", "in_target"].item() == float(in_target)
    assert td["stats", "success_rate"].item() == pytest.approx(1.0 if in_target else 0.75)
    assert td["stats", "r_success_cross"].item() == pytest.approx(5.0)
    assert td["stats", "r_ball_misbehave"].item() == pytest.approx(0.0 if in_target else -10.0)


def test_hard_racket_intercepts_a_central_spike_and_returns_it_over_the_net():
    env, td = make("set_and_spike_hard")
    td = spiked(env, td)
    start = (1.0, 1.0, 3.0)
    ball(env, start, aim(start, (-4.5, 0.3, 0.1), 0.7))
    for _ in range(60):
        td = step(env, td)
        if td["done"].item():
            break
    assert td["terminated"].item() and td["stats", "intercepted"].item() == 1
    assert td["stats", "success_spike"].item() == 0 and td["stats", "success_rate"].item() == pytest.approx(0.75)
    assert td["stats", "r_ball_misbehave"].item() == 0.0  # an intercepted spike is not the drones' fault
    # the ball now flies back toward (3, 1, 1.3): integrate its ballistic flight for t_post
    s = env.physics.state
    p, v = s.ball_pos[0], s.ball_vel[0]
    assert torch.allclose(v, env.defence.v_post[0], atol=0.3)
    t = env.defence.p.t_post
    land = p + v * t + 0.5 * torch.tensor([0.0, 0.0, -G]) * t * t
    assert torch.allclose(land, torch.tensor(env.defence.p.return_target), atol=0.4)
    # and over the net on the way
    t_net = -p[0] / v[0]
    assert (p[2] + v[2] * t_net - 0.5 * G * t_net**2) > 2.43


def test_hard_fast_corner_spike_beats_the_racket():
    env, td = make("set_and_spike_hard")
    td = spiked(env, td)
    start = (1.0, 2.0, 3.0)
    ball(env, start, aim(start, (-8.3, 4.0, 0.1), 0.55))
    for _ in range(60):
        td = step(env, td)
        if td["done"].item():
            break
    assert td["terminated"].item()
    assert td["stats", "intercepted"].item() == 0 and td["stats", "success_spike"].item() == 1
    assert td["stats", "success_rate"].item() == pytest.approx(1.0)
    # it tried: the racket moved from home toward the ball at its speed limit
    assert (env.defence.pos[0] - env.defence.home).norm() > 1.0


def test_defence_equations():
    # normal <-> (roll, pitch) round trip (paper A.3)
    n = torch.nn.functional.normalize(torch.tensor([[0.5, -0.3, 0.8], [-0.2, 0.4, 0.9]]), dim=-1)
    assert torch.allclose(racket_normal(racket_angles(n)), n, atol=1e-6)
    # a ballistic crossing is exact
    t, p, v = ballistic_crossing(torch.tensor([[0.0, 0.0, 3.0]]), torch.tensor([[-5.0, 1.0, 2.0]]), 1.1, G)
    assert p[0, 2].item() == pytest.approx(1.1, abs=1e-5) and v[0, 2].item() == pytest.approx(2.0 - G * t.item(), abs=1e-5)
    # the strike velocity with restitution beta along n turns v_pre into v_post
    r = DefenceRacket(1, "cpu", 0.02, 0.1)
    beta = r.p.restitution
    v_pre, v_post = torch.tensor([-8.0, 1.0, -6.0]), torch.tensor([5.0, 0.5, 6.0])
    n = torch.nn.functional.normalize(v_post - v_pre, dim=0)
    vc = (beta * v_pre + v_post) / (1 + beta)
    vn = torch.dot(v_pre - vc, n)
    assert torch.allclose(v_pre - (1 + beta) * vn * n, v_post, atol=1e-5)


def test_defence_respects_speed_and_rotation_limits():
    r = DefenceRacket(1, "cpu", 0.02, 0.1)
    prev = torch.tensor([[0.5, 0.0, 3.0]])
    pos, vel = torch.tensor([[0.3, 0.0, 2.9]]), torch.tensor([[-12.0, 3.0, -5.0]])
    armed = torch.ones(1, dtype=torch.bool)
    for _ in range(10):
        p0, a0 = r.pos.clone(), r.angles.clone()
        r.step(prev, pos, vel, armed)
        assert (r.pos - p0).norm().item() <= 8.0 * 0.02 + 1e-5
        assert (r.angles - a0).abs().max().item() <= 4.0 * 0.02 + 1e-5
        prev, pos = pos, pos + vel * 0.02
        vel = vel + torch.tensor([0.0, 0.0, -G * 0.02])
    assert r.planned.item()


@pytest.mark.slow  # not slow by nature, but measured too long for the quick tier
@pytest.mark.parametrize("name", list(COOP))
def test_ten_thousand_random_steps_stay_finite(name):
    env = volleybots.make_env(name, num_envs=64, seed=3)
    td = env.rollout(160, break_when_any_done=False)
    nxt = td["next"]
    assert torch.isfinite(nxt["agents", "observation"]).all() and torch.isfinite(nxt["agents", "reward"]).all()
    done = nxt["done"].squeeze(-1)
    assert done.sum() > 64
    rate = nxt["stats", "success_rate" if name != "bump_and_pass" else "bumps"][done]
    assert (rate >= 0).all() and (rate <= (1 if name != "bump_and_pass" else 50)).all()
