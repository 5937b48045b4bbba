"""Scripted model-based players: controller, intercept planning against the physics, task policies."""

import math

import pytest
import torch

import volleybots
from volleybots.physics import TorchPhysics, WorldParams
from volleybots.physics.params import DroneParams
from volleybots.physics.torch_backend import Constants
from volleybots.play import run_episodes
from volleybots.scripted import DroneController, StrikePlanner, make_scripted_policy, quintic
from volleybots.scripted.ballistics import ball_at, bounce, launch_for_apex, launch_for_range, racket_for, time_to_height
from volleybots.scripted.control import DroneObs, heading_yaw_rate


def test_allocation_inverts_the_airframe():
    """Hover thrusts equal DroneParams' (the Iris's arms differ), and any feasible wrench is met."""
    ctrl = DroneController()
    d = DroneParams()
    hover = ctrl.allocate(torch.tensor(d.mass * 9.81, dtype=torch.float64), torch.zeros(3, dtype=torch.float64))
    assert torch.allclose(hover, torch.tensor(d.hover_thrusts, dtype=torch.float64), atol=1e-9)
    torque = torch.tensor([[0.3, -0.2, 0.02]], dtype=torch.float64)
    t = ctrl.allocate(torch.tensor([16.0], dtype=torch.float64), torque)
    tmap = Constants(WorldParams(), "cpu", torch.float64).torque_map
    assert torch.allclose(t.sum(-1), torch.tensor([16.0], dtype=torch.float64))
    assert torch.allclose(t @ tmap, torque, atol=1e-9)
    # beyond the rotors' range the torque shrinks (same direction), the thrust keeps 90 %
    big = ctrl.allocate(torch.tensor([12.0], dtype=torch.float64), torch.tensor([[5.0, 0.0, 0.0]], dtype=torch.float64))
    assert (big >= 0).all() and (big <= d.max_rotor_thrust + 1e-9).all()
    got = big @ tmap
    assert 0 < got[0, 0] < 5.0 and abs(got[0, 1]) < 1e-6 and big.sum() >= 0.9 * 12.0 - 1e-6


@pytest.mark.slow  # not slow by nature, but measured too long for the quick tier
@pytest.mark.parametrize("space", ["prt", "ctbr"])
def test_position_controller_reaches_and_holds_a_target(space):
    env = volleybots.make_env("hover", num_envs=4, action_space=space, seed=1)
    td = env.reset()
    ctrl = DroneController(env.params, space)
    target = env.physics.state.pos + torch.tensor([[0.6, -0.4, 0.3]])
    zero = torch.zeros_like(target)
    for _ in range(150):
        drone = DroneObs.from_obs(td["agents", "observation"], space == "prt")
        td["agents", "action"] = ctrl.act(drone, target, zero)
        assert td["agents", "action"].abs().max() <= 1.0
        td = env.step(td)["next"]
    err = (env.physics.state.pos - target).norm(dim=-1)
    assert err.max() < 0.05, err
    assert env.physics.state.vel.norm(dim=-1).max() < 0.1


@pytest.mark.slow  # not slow by nature, but measured too long for the quick tier
def test_heading_control_turns_the_drone():
    env = volleybots.make_env("hover", num_envs=2, seed=0)
    td = env.reset()
    ctrl = DroneController(env.params)
    hold = env.physics.state.pos.clone()
    yaw_des = torch.tensor([[2.0], [-1.0]])
    for _ in range(250):  # yaw authority is small: the rotors' drag torque arm is KM / KF = 16 mm
        drone = DroneObs.from_obs(td["agents", "observation"], True)
        td["agents", "action"] = ctrl.act(drone, hold, torch.zeros_like(hold), yaw_rate=heading_yaw_rate(drone, yaw_des, 2.0))
        td = env.step(td)["next"]
    heading = td["agents", "observation"][..., 13:16]
    yaw = torch.atan2(heading[..., 1], heading[..., 0])
    assert torch.allclose(yaw, yaw_des, atol=0.05), yaw
    assert (env.physics.state.pos - hold).norm(dim=-1).max() < 0.15  # a fast turn saturates the rotors a while


def test_intercept_prediction_matches_the_physics():
    """time_to_height / ball_at predict where and when a thrown ball comes down through a height."""
    params = WorldParams()
    phys = TorchPhysics(params, 3, 1)
    all_envs = torch.ones(3, dtype=torch.bool)
    p0 = torch.tensor([[1.0, 0.0, 2.0], [-2.0, 1.0, 3.0], [0.0, 0.0, 1.0]])
    v0 = torch.tensor([[2.0, 0.5, 5.0], [1.0, -1.0, 0.0], [-3.0, 0.0, 8.0]])
    phys.set_state(all_envs, ball_pos=p0, ball_vel=v0, pos=torch.full((3, 1, 3), 50.0))  # drones far away
    height = 1.5
    t_pred = time_to_height(p0[:, 2], v0[:, 2], height)
    p_pred, v_pred = ball_at(p0, v0, t_pred)
    assert torch.allclose(p_pred[:, 2], torch.full((3,), height), atol=1e-5)
    ps, ts = [], []
    hover = torch.tensor(params.drone.hover_command).expand(3, 1, 4)
    for k in range(1, 200):
        phys.step(lambda s: hover)
        ps.append(phys.state.ball_pos.clone())
        ts.append(k * params.dt)
    ps = torch.cat((p0.unsqueeze(0), torch.stack(ps)))  # [T, 3, 3], step 0 = the start
    ts = [0.0, *ts]
    for i in range(3):
        z = ps[:, i, 2]
        below = ((z[:-1] >= height) & (z[1:] < height)).nonzero()[0].item() + 1  # first downward crossing
        a, b = ps[below - 1, i], ps[below, i]
        frac = (a[2] - height) / (a[2] - b[2])
        cross = a + (b - a) * frac
        t_cross = ts[below - 1] + frac * params.dt
        assert torch.allclose(cross, p_pred[i], atol=0.02), (cross, p_pred[i])
        assert abs(t_cross - t_pred[i].item()) < 0.01
    assert time_to_height(torch.tensor(1.0), torch.tensor(1.0), 3.0).isinf()  # apex 1.05 m, never at 3 m


def test_racket_solution_and_launches_are_consistent():
    v_in = torch.tensor([[0.3, -0.2, -6.0], [0.0, 0.0, -7.5]])
    v_out = torch.tensor([[0.5, 0.1, 6.0], [-7.0, 0.0, 7.0]])
    n, s = racket_for(v_in, v_out)
    assert torch.allclose(n.norm(dim=-1), torch.ones(2))
    assert torch.allclose(bounce(v_in, n, s.unsqueeze(-1) * n), v_out, atol=1e-5)
    # a launch for an apex peaks there and comes down through land_z at the target
    p = torch.tensor([[4.5, 0.0, 2.3]])
    v = launch_for_apex(p, torch.tensor([[4.0, 0.5]]), 3.9, 2.3)
    t_apex = v[0, 2] / 9.81
    assert abs(ball_at(p, v, t_apex)[0][0, 2].item() - 3.9) < 1e-4
    land, _ = ball_at(p, v, time_to_height(p[:, 2], v[:, 2], 2.3))
    assert torch.allclose(land[0, :2], torch.tensor([4.0, 0.5]), atol=1e-4)
    v = launch_for_range(p, torch.tensor([[-8.0, 0.0]]), 2.0, torch.tensor([math.radians(40.0)]))
    land, _ = ball_at(p, v, time_to_height(p[:, 2], v[:, 2], 2.0))
    assert torch.allclose(land[0, :2], torch.tensor([-8.0, 0.0]), atol=1e-3)
    assert abs(math.degrees(math.atan2(v[0, 2], v[0, :2].norm())) - 40.0) < 1e-3


def test_strike_reference_ends_in_the_contact_state():
    planner = StrikePlanner()
    ball_p, ball_v = torch.tensor([[4.5, 0.0, 4.0]]), torch.zeros(1, 3)
    strike = planner.plan(ball_p, ball_v, 2.35, lambda bp, bv: launch_for_apex(bp, torch.tensor([[4.5, 0.0]]), 3.9, 2.35))
    assert abs(strike.t.item() - math.sqrt(2 * 1.65 / 9.81)) < 1e-5
    # the racket centre sits under the ball by its radius along the normal
    assert torch.allclose(strike.ball_pos - strike.drone_pos, (0.1 + 0.05) * strike.normal)
    p, v, a = planner.reference(strike, 0.45)
    assert torch.allclose(p, planner.hold_point(strike, 0.45)) and v.abs().max() == 0  # still waiting
    arrived = planner.reference(type(strike)(**{**strike.__dict__, "t": torch.zeros(1)}), 0.45)
    for got, want in zip(arrived, (strike.drone_pos, strike.drone_vel, strike.drone_acc), strict=True):
        assert torch.allclose(got, want, atol=1e-5)
    # the quintic meets both boundary states
    p0, p1 = torch.zeros(1, 3), torch.ones(1, 3)
    end = quintic(p0, p0, p0, p1, 2 * p1, 3 * p1, torch.tensor([0.7]), torch.tensor([0.7]))
    assert all(torch.allclose(e, k * p1, atol=1e-5) for e, k in zip(end, (1, 2, 3), strict=True))


def test_registry_and_action_interface():
    with pytest.raises(ValueError, match="allowed:.*solo_bump"):
        make_scripted_policy("no_such_task")
    with pytest.raises(ValueError, match="prt"):
        make_scripted_policy("hover", "discrete")
    env = volleybots.make_env("back_and_forth", num_envs=3, action_space="ctbr")
    policy = make_scripted_policy(env)
    assert policy.action_space == "ctbr"
    td = policy(env.reset())
    action = td["agents", "action"]
    assert action.shape == (3, 1, 4) and action.abs().max() <= 1.0 and torch.isfinite(action).all()


def _play(task, space, n, seed):
    env = volleybots.make_env(task, num_envs=n, action_space=space, seed=seed)
    with torch.no_grad():
        return run_episodes(env, make_scripted_policy(env))[env.metric]


@pytest.mark.slow  # not slow by nature, but measured too long for the quick tier
def test_scripted_solo_bump_keeps_bumping():
    bumps = _play("solo_bump", "prt", 4, 3)
    assert bumps.mean() >= 8, bumps  # about 12 in 16 s when nothing goes wrong


def test_scripted_hit_the_ball_sends_it_far():
    dist = _play("hit_the_ball", "prt", 6, 0)
    assert dist.mean() >= 5.0 and (dist > 0).sum() >= 4, dist


def test_scripted_back_and_forth_shuttles():
    env = volleybots.make_env("back_and_forth", num_envs=2, seed=0, episode_len=250)
    with torch.no_grad():
        targets = run_episodes(env, make_scripted_policy(env))["targets"]
    assert (targets >= 2).all(), targets  # about 1.55 s per 6.4 m leg
