"""Match rules from constructed states: each violation and its blame, draws, serve faults, and the
mirrored observations (swapping the teams' states swaps their observations)."""

import math

import pytest
import torch

import volleybots
from volleybots.physics.math import euler_to_quat
from volleybots.rules import Referee
from volleybots.tasks.multi import rotate_quat_z180

ALL = torch.ones(1, dtype=torch.bool)


def match(name, serve=0, **kw):
    env = volleybots.make_env(name, num_envs=1, seed=0, serve=serve, **kw)
    td = env.reset()
    return env, td


def hover(env):
    return torch.tensor(env.params.drone.hover_command).expand(env.num_envs, env.n_drones, 4).clone()


def step(env, td):
    return env.step(td.set(("agents", "action"), hover(env)))["next"]


def place(env, drone, pos):
    p = env.physics.state.pos.clone()
    p[0, drone] = torch.tensor(pos)
    env.physics.set_state(ALL, pos=p[ALL])


def ball(env, pos, vel=(0.0, 0.0, 0.0)):
    env.place_ball(ALL, pos, vel)
    env.referee.prev_ball_x[:] = pos[0]


def racket_shot(env, drone, vz=-3.0):
    """Put the ball just above ``drone``'s racket, falling onto it: a racket hit within one step."""
    p = env.physics.state.pos[0, drone].tolist()
    ball(env, (p[0], p[1], p[2] + 0.2), (0.0, 0.0, vz))


def body_shot(env, drone):
    """Put the ball beside ``drone``'s body, flying into it: a body hit within one step."""
    p = env.physics.state.pos[0, drone].tolist()
    ball(env, (p[0] + 0.37, p[1], p[2]), (-3.0, 0.0, 0.0))


def result(td):
    reason = int(td["stats", "reason"].item())
    return int(td["stats", "winner"].item()), (Referee.FAULTS[reason] if reason >= 0 else None)


def test_serve_setup_ball_above_server_and_only_server_may_hit():
    for name, above, server in (("1v1", 1.5, [0, 1]), ("3v3", 3.0, [2, 5]), ("6v6", 3.0, [4, 10])):
        for team in (0, 1):
            env, td = match(name, serve=team)
            s = env.physics.state
            sv = server[team]
            assert torch.allclose(s.ball_pos[0], s.pos[0, sv] + torch.tensor([0.0, 0.0, above]))
            assert (s.ball_vel == 0).all()
            assert env.referee.may_hit[0].nonzero().flatten().tolist() == [sv]
            assert env.team_ids[sv].item() == team


def test_cross_the_net_loses_the_rally():
    env, td = match("1v1")
    place(env, 1, (0.5, 0.0, 2.0))  # team 1's drone flies into team 0's half
    td = step(env, td)
    assert td["done"].item() and result(td) == (0, "cross")
    assert td["agents", "reward"][0, :, 0].tolist() == pytest.approx([100.0, -100.0], abs=1.0)


def test_touching_the_net_loses_the_rally():
    env, td = match("3v3")
    place(env, 0, (0.1, -1.5, 1.5))  # team 0's front drone at the net, below its top
    td = step(env, td)
    assert result(td) == (1, "net_drone")


def test_receiver_touching_the_serve_is_a_wrong_turn():
    env, td = match("1v1", serve=0)
    racket_shot(env, 1)  # drone 1 (team 1) touches before the server
    td = step(env, td)
    assert result(td) == (0, "wrong_turn")


def test_second_touch_by_one_drone_in_a_possession_is_a_wrong_turn():
    env, td = match("3v3", serve=0)
    racket_shot(env, 2)  # the server's legal serve
    td = step(env, td)
    assert not td["done"].item() and env.referee.may_hit[0].tolist() == [True, True, False, False, False, False]
    for _ in range(4):
        ball(env, (3.0, 0.0, 4.0))
        td = step(env, td)
    racket_shot(env, 2)  # the server again, same possession
    td = step(env, td)
    assert result(td) == (1, "wrong_turn")


def test_body_hit_loses_the_rally():
    env, td = match("1v1", serve=1)
    body_shot(env, 1)
    td = step(env, td)
    assert result(td) == (0, "body_hit")


def test_ball_out_blames_the_last_hitter_at_any_height_in_1v1():
    env, td = match("1v1", serve=0)
    racket_shot(env, 0)
    td = step(env, td)
    assert env.referee.last_hitter.item() == 0 and not td["done"].item()
    ball(env, (2.0, 1.6, 4.0), (0.0, 1.0, 0.0))  # leaves the 3 m wide court high in the air
    td = step(env, td)
    assert result(td) == (1, "ball_out")


def test_ball_out_counts_only_where_it_lands_in_3v3():
    env, td = match("3v3", serve=1)
    racket_shot(env, 5)  # team 1's server
    td = step(env, td)
    ball(env, (-3.0, 3.5, 4.0), (0.0, 0.5, 0.0))  # outside the court, in the air: play on
    td = step(env, td)
    assert not td["done"].item()
    ball(env, (-3.0, 3.5, 0.15), (0.0, 0.0, -1.0))  # it lands outside: team 1 hit it out
    td = step(env, td)
    assert result(td) == (0, "ball_out")


def test_ball_into_the_net_blames_the_last_hitter():
    env, td = match("3v3", serve=0)
    racket_shot(env, 2)
    td = step(env, td)
    ball(env, (0.2, 0.0, 1.5), (-1.0, 0.0, 0.0))
    td = step(env, td)
    assert result(td) == (1, "ball_net")


def test_ball_landing_in_a_half_loses_for_that_half():
    env, td = match("1v1", serve=0)
    racket_shot(env, 0)
    td = step(env, td)
    ball(env, (-1.0, 0.5, 0.15), (0.0, 0.0, -2.0))
    td = step(env, td)
    assert result(td) == (0, "landed")
    assert td["stats", "win"].item() == 1 and td["stats", "loss"].item() == 0 and td["stats", "draw"].item() == 0


def test_unserved_ball_out_is_the_servers_fault():
    env, td = match("6v6", serve=0)
    ball(env, (9.3, 0.0, 0.15), (0.0, 0.0, -2.0))  # the serve lands behind the end line untouched
    td = step(env, td)
    assert result(td) == (1, "ball_out")


def test_both_teams_violating_in_one_step_is_a_draw():
    env, td = match("1v1")
    place(env, 0, (-0.5, 0.0, 2.0))
    place(env, 1, (0.5, 0.0, 2.0))
    td = step(env, td)
    assert td["done"].item() and result(td) == (-1, None) and td["stats", "draw"].item() == 1
    assert td["agents", "reward"][0, :, 0].abs().max().item() < 10


def test_crash_is_a_draw_with_a_penalty_for_the_crashing_drone():
    env, td = match("3v3")
    place(env, 4, (-3.0, 1.5, 0.25))
    td = step(env, td)
    assert td["terminated"].item() and result(td) == (-1, None) and td["stats", "draw"].item() == 1
    rew = td["agents", "reward"][0, :, 0]
    assert rew[4].item() < -90 and (rew[[0, 1, 2, 3, 5]] > -5).all()


def test_teammates_too_close_is_a_draw_with_a_penalty_for_both():
    env, td = match("3v3")
    place(env, 0, (3.0, 1.0, 2.0))  # 0.5 m from drone 1
    td = step(env, td)
    assert td["terminated"].item() and result(td) == (-1, None)
    rew = td["agents", "reward"][0, :, 0]
    assert rew[0].item() < -90 and rew[1].item() < -90 and (rew[2:] > -5).all()


def test_time_limit_is_a_draw():
    env, td = match("1v1", episode_len=3)
    for _ in range(3):
        ball(env, (1.5, 0.0, 3.5))  # keep the serve hanging
        td = step(env, td)
    assert td["truncated"].item() and not td["terminated"].item()
    assert td["stats", "draw"].item() == 1 and result(td) == (-1, None)


@pytest.mark.parametrize("name, server, kw, paid", [
    ("3v3", 2, {}, 10.0), ("6v6", 4, {}, 10.0), ("1v1", 0, {}, 5.0), ("1v1", 0, {"hit_reward": 20.0}, 20.0),
    ("3v3", 2, {"hit_reward": 30.0}, 30.0),
])
def test_legal_hit_counts_and_pays_the_team(name, server, kw, paid):
    # the paper's 10 (teams) and 5 (1 vs 1) by default; task.hit_reward replaces it; only the touching team is paid
    env, td = match(name, serve=0, **kw)
    racket_shot(env, server)
    td = step(env, td)
    assert td["stats", "hits_team0"].item() == 1 and td["stats", "hits_team1"].item() == 0
    rew = td["agents", "reward"][0, :, 0]
    team0 = env.team_ids == 0
    assert torch.allclose(rew[team0] - rew[~team0].mean(), torch.full((int(team0.sum()),), paid), atol=1.0), rew
    assert td["stats", "r_success_hit"].item() == pytest.approx(paid / 2)  # the mean over both teams' drones


# ---------------------------------------------------------------------------------------- mirror

def mirrored_state(state, team_size):
    """The world rotated by 180 degrees about z with the two teams' drones exchanged."""
    swap = list(range(team_size, 2 * team_size)) + list(range(team_size))
    flip = torch.tensor([-1.0, -1.0, 1.0])
    return dict(
        pos=state["pos"][:, swap] * flip,
        quat=rotate_quat_z180(state["quat"][:, swap]),
        vel=state["vel"][:, swap] * flip,
        omega=state["omega"][:, swap],  # body frame: unchanged
        throttle=state["throttle"][:, swap],
        ball_pos=state["ball_pos"] * flip,
        ball_vel=state["ball_vel"] * flip,
    ), swap


@pytest.mark.parametrize("name", ["1v1", "3v3", "6v6"])
def test_swapping_the_teams_swaps_their_observations(name):
    env = volleybots.make_env(name, num_envs=4, seed=2)
    env.reset()
    g = torch.Generator().manual_seed(7)
    n, a = env.num_envs, env.n_drones
    rpy = (torch.rand(n, a, 3, generator=g) - 0.5) * torch.tensor([0.8, 0.8, 2 * math.pi])
    state = dict(
        pos=env.anchors + 0.3 * torch.randn(n, a, 3, generator=g),
        quat=euler_to_quat(rpy[..., 0], rpy[..., 1], rpy[..., 2]),
        vel=torch.randn(n, a, 3, generator=g),
        omega=torch.randn(n, a, 3, generator=g),
        throttle=torch.rand(n, a, 4, generator=g),
        ball_pos=torch.tensor([[1.0, 0.5, 3.0]]) + torch.randn(n, 3, generator=g),
        ball_vel=torch.randn(n, 3, generator=g),
    )
    # a realistic turn state: some drones of one team may hit (the team differs between envs)
    turn_team = torch.arange(n) % 2
    may_hit = (torch.rand(n, a, generator=g) < 0.6) & (env.team_ids == turn_team.unsqueeze(1))
    everyone = torch.ones(n, dtype=torch.bool)

    env.physics.set_state(everyone, **state)
    env.referee.may_hit = may_hit.clone()
    obs = env.observe()

    swapped, swap = mirrored_state(state, env.team_size)
    env.physics.set_state(everyone, **swapped)
    env.referee.may_hit = may_hit[:, swap].clone()
    obs_swapped = env.observe()

    assert obs.shape == (n, a, env.obs_dim)
    assert torch.allclose(obs_swapped, obs[:, swap], atol=1e-5)
    # and the view really is egocentric: the two sides' observations differ in general
    assert not torch.allclose(obs[:, : env.team_size], obs[:, env.team_size :], atol=1e-3)
