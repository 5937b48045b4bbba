"""The torch and MuJoCo backends agree (spec: physics.md "Backends"; docs/backends.md).

Without contact both integrate the same equations with the same semi-implicit Euler step, so they agree
to float32 rounding over a second; a bounce agrees loosely (MuJoCo's contact is soft and discrete).
"""

import math

import pytest
import torch

from volleybots.physics import RateController, TorchPhysics, WorldParams
from volleybots.physics.math import euler_to_quat
from volleybots.physics.mujoco_backend import MujocoPhysics

pytestmark = pytest.mark.mujoco

P = WorldParams()
HOVER = torch.tensor(P.drone.hover_command)
STEPS = 50  # 1 s at 50 Hz
FIELDS = ("pos", "quat", "vel", "omega", "throttle", "ball_pos", "ball_vel")


def pair(n=1, d=1, params=P, **state):
    """Both backends with the same initial state (the given fields for every env)."""
    out = []
    for cls in (TorchPhysics, MujocoPhysics):
        ph = cls(params, n, d)
        ph.set_state(
            torch.ones(n, dtype=torch.bool),
            **{k: torch.as_tensor(v, dtype=torch.float32).expand_as(getattr(ph.state, k)) for k, v in state.items()},
        )
        out.append(ph)
    return out


def drone_state(pos=(0.0, 0.0, 2.0), **kw):
    s = dict(
        pos=pos, quat=(1.0, 0.0, 0.0, 0.0), vel=(0.0, 0.0, 0.0), omega=(0.0, 0.0, 0.0), ball_pos=(40.0, 0.0, 30.0), ball_vel=(0.0, 0.0, 0.0)
    )
    s.update(kw)
    return s


def run_both(phs, command_fns, steps=STEPS):
    traj = [[], []]
    for _ in range(steps):
        for k, (ph, fn) in enumerate(zip(phs, command_fns, strict=True)):
            ph.step(fn)
            traj[k].append(ph.state.clone())
    return traj


def max_diff(a, b):
    return {f: (getattr(a, f) - getattr(b, f)).abs().max().item() for f in FIELDS}


def test_backend_is_registered_and_keeps_layout():
    from volleybots.physics import BACKENDS, make_physics

    assert "mujoco" in BACKENDS
    ph = make_physics("mujoco", P, 3, 2)
    assert ph.name == "mujoco"
    t = TorchPhysics(P, 3, 2)
    for f in FIELDS:
        assert getattr(ph.state, f).shape == getattr(t.state, f).shape
        assert getattr(ph.state, f).dtype == torch.float32
    model = ph.model
    assert model.opt.timestep == pytest.approx(P.sub_dt)
    drone = model.body("drone0")
    assert drone.mass[0] == pytest.approx(P.drone.mass)
    assert drone.inertia.tolist() == pytest.approx(list(P.drone.inertia))  # the true, unbalanced Iris inertia
    assert model.body("ball").mass[0] == pytest.approx(P.ball.mass)
    assert model.geom("racket0").size[0] == pytest.approx(P.drone.racket_radius)


def test_ballistic_flight_agrees():
    phs = pair(ball_pos=(1.0, -2.0, 10.0), ball_vel=(2.0, 1.0, 3.0))
    tr = run_both(phs, [lambda s: HOVER.expand(1, 1, 4)] * 2)
    for a, b in zip(*tr, strict=True):
        assert (a.ball_pos - b.ball_pos).abs().max() < 1e-4
        assert (a.ball_vel - b.ball_vel).abs().max() < 1e-4
    t = STEPS * P.dt
    assert tr[1][-1].ball_pos[0, 2].item() == pytest.approx(10 + 3 * t - 0.5 * 9.81 * t * t, abs=0.03)


def test_hover_agrees_and_holds():
    phs = pair(**drone_state())
    tr = run_both(phs, [lambda s: HOVER.expand(1, 1, 4)] * 2)
    for a, b in zip(*tr, strict=True):
        assert max(max_diff(a, b).values()) < 1e-4
    assert (tr[1][-1].pos[0, 0] - torch.tensor([0.0, 0.0, 2.0])).norm() < 0.01


def test_rotor_command_step_agrees():
    """Unequal rotor commands from a tilted, moving, spinning start: thrust, torques, gyroscopic
    coupling, damping and the rotor lag all act; both backends follow the same trajectory."""
    quat = euler_to_quat(torch.tensor(0.2), torch.tensor(-0.1), torch.tensor(0.5)).tolist()
    phs = pair(**drone_state(quat=quat, vel=(1.0, -0.5, 0.3), omega=(0.4, -0.3, 1.0)))
    cmd = (HOVER + torch.tensor([0.08, -0.05, 0.03, -0.06])).expand(1, 1, 4)
    tr = run_both(phs, [lambda s: cmd] * 2)
    a, b = tr[0][-1], tr[1][-1]
    moved = (a.pos - torch.tensor([0.0, 0.0, 2.0])).norm().item()
    assert moved > 0.5  # the test exercises real motion
    d = max_diff(a, b)
    assert d["pos"] < 1e-3 and d["vel"] < 1e-3
    assert d["quat"] < 1e-4 and d["omega"] < 1e-3 and d["throttle"] < 1e-6


def test_multi_drone_downwash_agrees():
    """Two drones stacked 0.6 m apart: the lower one feels the upper one's wash in both backends."""
    pos = torch.tensor([[[0.0, 0.0, 3.0], [0.05, 0.0, 2.4]]])
    phs = pair(d=2, **drone_state(pos=pos))
    tr = run_both(phs, [lambda s: HOVER.expand(1, 2, 4)] * 2, steps=25)
    a, b = tr[0][-1], tr[1][-1]
    assert a.pos[0, 1, 2] < 2.4 - 0.05  # the wash pushes the lower drone down
    assert max_diff(a, b)["pos"] < 1e-3 and max_diff(a, b)["vel"] < 1e-3


def test_ctbr_rate_step_agrees():
    """A body-rate step through the PID rate controller, which reads ``state.omega`` every sub-step."""
    ctrls = [RateController(P.drone, 1, 1, P.sub_dt) for _ in range(2)]
    phs = pair(**drone_state())
    rates = torch.tensor([[[60.0, -40.0, 90.0]]])  # deg/s
    thrust = torch.tensor([[sum(P.drone.hover_thrusts) / (4 * P.drone.max_rotor_thrust)]])
    fns = [lambda s, c=c: c(s.omega, rates, thrust) for c in ctrls]
    tr = run_both(phs, fns, steps=25)
    b = tr[1][-1]
    achieved = b.omega[0, 0] * 180 / math.pi
    assert (achieved[:2] - rates[0, 0, :2]).abs().max() < 10.0  # roll and pitch track the step
    assert achieved[2] > 10.0  # yaw, with little authority (KF/KM = 62.5), turns the right way
    for x, y in zip(*tr, strict=True):
        assert (x.omega - y.omega).abs().max() < 2e-3
        assert (x.quat - y.quat).abs().max() < 1e-4


def rebound_height(ph, drop_from: float) -> tuple[float, list[tuple[bool, bool]]]:
    """Drop the ball onto a hovering drone's racket; return the apex of the first rebound above the
    racket contact height and the (racket, body) flags of the contact steps."""
    m = torch.ones(1, dtype=torch.bool)
    ph.set_state(
        m,
        **{
            k: torch.tensor(v, dtype=torch.float32).expand_as(getattr(ph.state, k))
            for k, v in drone_state(ball_pos=(0.0, 0.0, drop_from)).items()
        },
    )
    contact_z = 2.0 + P.drone.racket_offset + P.ball.radius
    flags, apex = [], None
    for _ in range(150):
        c = ph.step(lambda s: HOVER.expand(1, 1, 4))
        if c.racket.any() or c.body.any():
            flags.append((bool(c.racket[0, 0]), bool(c.body[0, 0])))
        if flags and ph.state.ball_vel[0, 2] > 0:
            apex = max(apex or 0.0, ph.state.ball_pos[0, 2].item())
        if apex is not None and ph.state.ball_vel[0, 2] < 0:
            break
    return apex - contact_z, flags


def test_ball_rebounds_from_level_racket_to_the_same_height():
    ratios = []
    for h in (3.3, 3.8, 4.3):
        (ht, ft), (hm, fm) = (rebound_height(ph, h) for ph in pair())
        assert ht == pytest.approx(0.64 * (h - 2.15), rel=0.05)  # torch: e = 0.8 exactly
        assert all(r and not b for r, b in ft + fm)  # a racket hit in both
        ratios.append(hm / ht)
    # MuJoCo's restitution depends a little on where in a 5 ms sub-step the contact begins
    assert all(abs(r - 1) < 0.08 for r in ratios), ratios
    assert sum(ratios) / len(ratios) == pytest.approx(1.0, abs=0.05), ratios


@pytest.mark.parametrize(
    "where,ball_pos,ball_vel,expect",
    [
        ("racket centre", (0.05, -0.05, 2.6), (0.0, 0.0, -3.0), "racket"),
        ("frame corner", (0.22, 0.22, 2.6), (0.0, 0.0, -3.0), "body"),
        ("side", (-0.6, 0.0, 2.0), (4.0, 0.0, 0.0), "body"),
        ("underneath", (0.0, 0.05, 1.5), (0.0, 0.0, 4.0), "body"),
    ],
)
def test_hit_classification_agrees(where, ball_pos, ball_vel, expect):
    got = []
    for ph in pair(**drone_state(ball_pos=ball_pos, ball_vel=ball_vel)):
        racket = body = False
        for _ in range(15):
            c = ph.step(lambda s: HOVER.expand(1, 1, 4))
            racket |= bool(c.racket[0, 0])
            body |= bool(c.body[0, 0])
        got.append(("racket" if racket else "") + ("body" if body else ""))
    assert got == [expect, expect], f"{where}: torch {got[0]!r}, mujoco {got[1]!r}"


def test_ground_contact_flag():
    for ph in pair(ball_pos=(30.0, 0.0, 0.6), ball_vel=(0.0, 0.0, -1.0)):
        grounds = [bool(ph.step(lambda s: HOVER.expand(1, 1, 4)).ground[0]) for _ in range(20)]
        assert any(grounds) and not grounds[0]
        assert ph.state.ball_pos[0, 2] > 0.05  # it bounced, did not sink through
