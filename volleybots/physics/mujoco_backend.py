"""MuJoCo backend: the same world as ``torch_backend`` stepped by MuJoCo (docs/backends.md).

The scene is generated as MJCF from the same ``WorldParams``: every drone is a free body carrying the
Iris mass and inertia, four rotor sites whose actuators push along the site z axis with a yaw reaction
in their gear, a racket cylinder whose top face is the racket plane and a body box around it; the ball is a
free sphere; the ground is a plane. All envs step together through ``mujoco.rollout`` on one
persistent thread pool.

What is shared with the torch backend, and why the step is split the way it is:

* ``command_fn(state)`` may read the state (the CTBR rate controller reads ``state.omega``), so the
  rollout is called with ``nstep=1`` once per sub-step, and the torch state is refreshed in between.
* The rotor lag closes ``lag_per_substep`` of the throttle error per sub-step and thrust is
  ``throttle**2 * KF``. MuJoCo's filter actuators could hold the lag but not the square, so throttles
  live in torch (the same functions as the torch backend) and MuJoCo receives thrusts in newtons.
* Velocity damping (dv/dt = -0.2 v, dw/dt = -0.2 w per body axis) and downwash are explicit forces in
  the torch backend. MuJoCo's joint damping is one coefficient per joint and integrated implicitly, so
  both go through ``xfrc_applied``, computed in torch exactly as the torch backend does (damping from
  each sub-step's initial state, downwash once per control step).
* MuJoCo's Euler integrator is semi-implicit like ``substep`` (velocity first, then position with the
  new velocity; quaternion by the exponential map of the body rate), and a free joint's angular
  velocity is in the body frame, the layout of ``PhysicsState.omega``.

Contacts are MuJoCo's own: soft, frictionless (``condim=1``, as the torch impulses have no friction),
with restitution set through ``solref`` in its direct (-stiffness, -damping) form, tuned for the
5 ms sub-step. Contact sensors report, per sub-step, whether the ball touches each drone's racket or
body geom and the ground; a racket contact counts as a racket hit only on the top face within the
disk (its normal along the drone's up axis), otherwise it is a body hit, as in the torch backend.
"""

from __future__ import annotations

import functools
import math

import mujoco
import numpy as np
import torch
from mujoco import rollout as mj_rollout

from volleybots.physics.math import quat_axes, quat_rotate
from volleybots.physics.params import WorldParams
from volleybots.physics.torch_backend import (
    CommandFn,
    Contacts,
    PhysicsState,
    TorchPhysics,
    control_step_downwash,
    rotor_thrusts,
    throttle_target,
)

CONTACT_STIFFNESS = 1.0e4  # 1/s^2 per unit constraint mass: a 31 ms contact, about 6 sub-steps, 5 cm deep at 5 m/s
FRAME_DROP = 0.01  # m the body frame's top sits below the racket plane, so a ball on the disk touches the racket only
TOP_FACE_COS = 0.98  # a racket contact whose normal is within ~11 deg of the drone's up axis is a racket hit

# collision filter bits: drones meet the ball and the ground but not each other (the torch backend has
# no drone-drone contact); the optional net stops the ball only
_DRONE, _BALL, _NET = 1, 2, 4


def unilateral_restitution(zeta: float) -> float:
    """Restitution of a spring-damper contact with damping ratio ``zeta`` that can push but not pull.

    The penetration is p = v/wd e^(-zeta w t) sin(wd t); the contact lets go when the force
    w^2 p + 2 zeta w p' reaches zero, at phase theta = pi - atan(2 zeta sqrt(1-zeta^2) / (1 - 2 zeta^2)),
    a little before the ball is back at the surface.
    """
    s = math.sqrt(1.0 - zeta * zeta)
    theta = math.pi - math.atan2(2.0 * zeta * s, 1.0 - 2.0 * zeta * zeta)
    return -math.exp(-zeta * theta / s) * (math.cos(theta) - zeta / s * math.sin(theta))


def solref_for(restitution: float, stiffness: float = CONTACT_STIFFNESS) -> tuple[float, float]:
    """MuJoCo's direct (-stiffness, -damping) ``solref`` whose contact has this restitution.

    The continuous-time model; on the 5 ms sub-step the restitution also depends on where in a sub-step
    the contact begins (within a few percent, docs/backends.md).
    """
    if not 0.0 < restitution < 1.0:
        raise ValueError(f"restitution must be in (0, 1), got {restitution}")
    lo, hi = 0.0, 0.999
    for _ in range(60):  # the restitution falls monotonically with the damping ratio
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if unilateral_restitution(mid) > restitution else (lo, mid)
    zeta = 0.5 * (lo + hi)
    return (-stiffness, -2.0 * zeta * math.sqrt(stiffness))


def build_model(params: WorldParams, n_drones: int, net: tuple[float, float] | None = None) -> mujoco.MjModel:
    """The compiled scene of ``build_mjcf`` with the drones' true diagonal inertia."""
    m = mujoco.MjModel.from_xml_string(build_mjcf(params, n_drones, net))
    for i in range(n_drones):
        m.body_inertia[mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, f"drone{i}")] = params.drone.inertia
    mujoco.mj_setConst(m, mujoco.MjData(m))
    return m


def _fmt(*xs: float) -> str:
    return " ".join(f"{x:.9g}" for x in xs)


def build_mjcf(params: WorldParams, n_drones: int, net: tuple[float, float] | None = None) -> str:
    """MJCF of one world: ``n_drones`` drones, the ball, the ground and optionally a net (width, height).

    The Iris inertia (0.035, 0.046, 0.098) breaks the triangle inequality A + B >= C that MuJoCo's
    compiler enforces for a rigid body; the MJCF lets the compiler balance it and ``build_model``
    writes the true values back into the compiled model.
    """
    d, b = params.drone, params.ball
    hx, hy, hz = d.body_half_extents
    top = d.racket_offset
    # A soft contact lets a 5 m/s ball sink about 5 cm into the racket, deeper than the racket is thick,
    # so nothing of the body may lie under the disk: the racket is a cylinder through the body's whole
    # height, and the body box is the frame of four boxes around it (the box with the disk carved out),
    # its top FRAME_DROP below the racket plane. The bottom of both stays where the torch backend rests
    # a drone on the ground.
    rr = d.racket_radius
    frame_top = top - FRAME_DROP
    fz, fcz = 0.5 * (frame_top + hz), 0.5 * (frame_top - hz)
    frame = []  # (half extents, centre) of the frame's boxes
    if hy > rr:
        frame += [((hx, 0.5 * (hy - rr), fz), (0.0, sgn * 0.5 * (hy + rr), fcz)) for sgn in (1, -1)]
    if hx > rr:
        frame += [((0.5 * (hx - rr), min(hy, rr), fz), (sgn * 0.5 * (hx + rr), 0.0, fcz)) for sgn in (1, -1)]
    rack_hz, rack_cz = 0.5 * (top + hz), 0.5 * (top - hz)
    rk_ball, rd_ball = solref_for(b.restitution)
    rk_body, rd_body = solref_for(d.body_restitution)
    rk_gnd, rd_gnd = solref_for(b.ground_restitution)
    kf = d.max_rotor_thrust
    bodies, actuators = [], []
    for i in range(n_drones):
        sites = []
        for j, (pos, direction) in enumerate(zip(d.rotor_positions, d.directions)):
            sites.append(f'<site name="rotor{j}_{i}" pos="{_fmt(*pos)}" size="0.02"/>')
            # ctrl is the rotor thrust in N; the gear adds the yaw reaction -dir * KM / KF per newton
            actuators.append(f'<general site="rotor{j}_{i}" gear="0 0 1 0 0 {-direction * d.max_rotor_moment / kf:.9g}"/>')
        bodies.append(
            f"""
    <body name="drone{i}" pos="{_fmt(0, 3 * i, 2)}">
      <freejoint name="drone{i}"/>
      <inertial pos="0 0 0" mass="{d.mass:.9g}" diaginertia="{_fmt(*d.inertia)}"/>
      <geom name="racket{i}" type="cylinder" size="{_fmt(rr, rack_hz)}" pos="{_fmt(0, 0, rack_cz)}" mass="0"
            contype="{_DRONE}" conaffinity="{_BALL}" priority="1" solref="{_fmt(rk_ball, rd_ball)}"/>
      {"".join(
          f'<geom name="body{i}_{k}" type="box" size="{_fmt(*size)}" pos="{_fmt(*centre)}" mass="0" contype="{_DRONE}"'
          f' conaffinity="{_BALL}" priority="1" solref="{_fmt(rk_body, rd_body)}"/>'
          for k, (size, centre) in enumerate(frame)
      )}
      {" ".join(sites)}
    </body>"""
        )
    net_xml = ""
    if net is not None:
        width, height = net
        net_xml = (
            f'<geom name="net" type="box" size="{_fmt(0.005, width / 2, height / 2)}" pos="{_fmt(0, 0, height / 2)}"'
            f' contype="{_NET}" conaffinity="{_BALL}" priority="1" solref="{_fmt(rk_body, rd_body)}"/>'
        )
    sensors = []
    for i in range(n_drones):
        sensors.append(f'<contact name="racket{i}" geom1="ball" geom2="racket{i}" num="1" reduce="mindist" data="found pos normal"/>')
        sensors += [f'<contact name="body{i}_{k}" geom1="ball" geom2="body{i}_{k}" num="1" data="found"/>' for k in range(len(frame))]
    sensors.append('<contact name="ground" geom1="ball" geom2="floor" num="1" data="found"/>')
    sensor_xml = "\n    ".join(sensors)
    return f"""<mujoco model="volleybots">
  <compiler balanceinertia="true"/>
  <option timestep="{params.sub_dt:.9g}" gravity="0 0 {-params.gravity:.9g}" integrator="Euler"/>
  <default><geom condim="1" solimp="0.95 0.95 0.001"/></default>
  <worldbody>
    <geom name="floor" type="plane" size="0 0 1" contype="{_DRONE | _BALL}" conaffinity="{_DRONE | _BALL}"
          priority="1" solref="{_fmt(rk_gnd, rd_gnd)}"/>
    {net_xml}
    {"".join(bodies)}
    <body name="ball" pos="0 0 1">
      <freejoint name="ball"/>
      <geom name="ball" type="sphere" size="{b.radius:.9g}" mass="{b.mass:.9g}"
            contype="{_BALL}" conaffinity="{_DRONE | _BALL | _NET}"/>
    </body>
  </worldbody>
  <actuator>
    {chr(10).join(actuators)}
  </actuator>
  <sensor>
    {sensor_xml}
  </sensor>
</mujoco>
"""


class MujocoPhysics(TorchPhysics):
    """Same interface and state as ``TorchPhysics``; the integration and the contacts are MuJoCo's.

    ``compile`` is accepted for interface parity and has no effect: the stepping is MuJoCo's native
    code. ``nthread`` sizes the rollout thread pool (0 steps on the calling thread; default: torch's
    intra-op thread count, the cores this process was given; ``set_threads`` changes it); ``net`` =
    (width, height) adds a physical net at x = 0 that stops the ball (the torch backend has none, so it
    is off by default).
    """

    name = "mujoco"

    def __init__(
        self,
        params: WorldParams,
        num_envs: int,
        n_drones: int,
        device="cpu",
        dtype=torch.float32,
        compile: bool = False,
        *,
        nthread: int | None = None,
        net: tuple[float, float] | None = None,
    ):
        # the torch backend's state, constants and state setters; only the stepping differs
        super().__init__(params, num_envs, n_drones, device=device, dtype=dtype)
        self.model = build_model(params, n_drones, net)
        self._models = [self.model] * num_envs  # the rollout's unchecked path wants one model per env
        self.set_threads(torch.get_num_threads() if nthread is None else nthread)
        m = self.model
        self.nstate = mujoco.mj_stateSize(m, mujoco.mjtState.mjSTATE_FULLPHYSICS)
        self.control_spec = int(mujoco.mjtState.mjSTATE_CTRL) | int(mujoco.mjtState.mjSTATE_XFRC_APPLIED)
        self.ncontrol = mujoco.mj_stateSize(m, self.control_spec)
        assert self.ncontrol == m.nu + 6 * m.nbody
        # the full physics state is time, qpos, qvel (the model has no actuator state or plugins)
        assert self.nstate == 1 + m.nq + m.nv, "unexpected MuJoCo state layout"
        self._qpos0, self._qvel0 = 1, 1 + m.nq
        self._drone_body = np.array([mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, f"drone{i}") for i in range(n_drones)])
        self._ball_body = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, "ball")
        adr = lambda name: int(m.sensor_adr[mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_SENSOR, name)])  # noqa: E731
        self._s_racket = np.array([adr(f"racket{i}") for i in range(n_drones)])
        n_frame = sum(1 for k in range(m.ngeom) if mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_GEOM, k).startswith("body0_"))
        self._s_body = np.array([[adr(f"body{i}_{k}") for k in range(n_frame)] for i in range(n_drones)]).reshape(n_drones, n_frame)
        self._s_ground = adr("ground")
        # output buffers reused by every rollout call (float64, contiguous: rollout can skip its checks)
        self._x = np.zeros((num_envs, self.nstate))
        self._out = np.zeros((num_envs, 1, self.nstate))
        self._sens = np.zeros((num_envs, 1, m.nsensordata))
        self._ctrl = np.zeros((num_envs, 1, self.ncontrol))
        # start the bodies apart (drones in a row at 2 m, the ball above the ground) until a task places them
        self.state.pos[..., 1] = 3.0 * torch.arange(n_drones, device=self.device, dtype=dtype)
        self.state.pos[..., 2] = 2.0
        self.state.ball_pos[:, 2] = 1.0

    def set_threads(self, nthread: int) -> None:
        """Size the rollout's thread pool (0: step on the calling thread), with one MjData per thread."""
        close = getattr(getattr(self, "_pool", None), "close", None)
        if close is not None:
            close()
        self.nthread = nthread
        self.datas = [mujoco.MjData(self.model) for _ in range(max(nthread, 1))]
        self._pool = mj_rollout.Rollout(nthread=nthread)

    # ------------------------------------------------------------------ state <-> MuJoCo vectors
    def _pack(self, s: PhysicsState) -> None:
        """Write the torch state into the MuJoCo state rows ``self._x`` (ball spin stays zero)."""
        n, d = self.num_envs, self.n_drones
        x = torch.from_numpy(self._x)
        x.zero_()
        qpos = x[:, self._qpos0 : self._qpos0 + 7 * (d + 1)].view(n, d + 1, 7)
        qvel = x[:, self._qvel0 : self._qvel0 + 6 * (d + 1)].view(n, d + 1, 6)
        qpos[:, :d, :3] = s.pos.detach().to("cpu", torch.float64)
        qpos[:, :d, 3:] = s.quat.detach().to("cpu", torch.float64)
        qpos[:, d, :3] = s.ball_pos.detach().to("cpu", torch.float64)
        qpos[:, d, 3] = 1.0
        qvel[:, :d, :3] = s.vel.detach().to("cpu", torch.float64)
        qvel[:, :d, 3:] = s.omega.detach().to("cpu", torch.float64)
        qvel[:, d, :3] = s.ball_vel.detach().to("cpu", torch.float64)

    def _unpack(self, x: np.ndarray, throttle: torch.Tensor) -> PhysicsState:
        n, d = self.num_envs, self.n_drones
        t = torch.from_numpy(x).to(self.device, self.dtype)
        qpos = t[:, self._qpos0 : self._qpos0 + 7 * (d + 1)].view(n, d + 1, 7)
        qvel = t[:, self._qvel0 : self._qvel0 + 6 * (d + 1)].view(n, d + 1, 6)
        return PhysicsState(
            pos=qpos[:, :d, :3].clone(),
            quat=qpos[:, :d, 3:].clone(),
            vel=qvel[:, :d, :3].clone(),
            omega=qvel[:, :d, 3:].clone(),
            throttle=throttle,
            ball_pos=qpos[:, d, :3].clone(),
            ball_vel=qvel[:, d, :3].clone(),
        )

    def _controls(self, s: PhysicsState, throttle: torch.Tensor, wash: torch.Tensor | None) -> None:
        """Fill ``self._ctrl``: rotor thrusts (N) then the external wrench of every body (world frame);
        ``wash`` is the control step's downwash acceleration, as in the torch backend."""
        c = self.consts
        n, d = self.num_envs, self.n_drones
        thrust = rotor_thrusts(throttle, c.kf)
        force = -c.lin_damp * c.mass * s.vel
        if wash is not None:
            force = force + c.mass * wash
        torque = quat_rotate(s.quat, -c.ang_damp * c.inertia * s.omega)
        ctrl = torch.from_numpy(self._ctrl).view(n, self.ncontrol)
        m = self.model
        ctrl[:, : m.nu] = thrust.detach().reshape(n, d * 4).to("cpu", torch.float64)
        xfrc = ctrl[:, m.nu :].view(n, m.nbody, 6)
        xfrc[:, self._drone_body, :3] = force.detach().to("cpu", torch.float64)
        xfrc[:, self._drone_body, 3:] = torque.detach().to("cpu", torch.float64)
        if c.drag > 0:
            bv = s.ball_vel
            xfrc[:, self._ball_body, :3] = (-c.drag * c.ball_m * bv.norm(dim=-1, keepdim=True) * bv).detach().to("cpu", torch.float64)

    def _hits(self, sens: np.ndarray, s: PhysicsState) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """Racket / body flags [N, D] and ground flag [N] of one sub-step's contact sensors."""
        t = torch.from_numpy(sens).to(self.device)
        found_r = t[:, self._s_racket] > 0
        normal = torch.stack([t[:, a + 4 : a + 7] for a in self._s_racket], 1).to(self.dtype)  # ball -> racket
        _, up = quat_axes(s.quat)
        top = (-(normal * up).sum(-1)) > TOP_FACE_COS
        racket = found_r & top
        body = (t[:, self._s_body] > 0).any(-1) | (found_r & ~top)
        # one drone answers per env and sub-step, as in the torch backend: the first racket, else the first body
        any_racket = racket.any(1, keepdim=True)
        racket = racket & (torch.cumsum(racket.int(), 1) == 1)
        body = body & ~any_racket & (torch.cumsum(body.int(), 1) == 1)
        return racket, body, t[:, self._s_ground] > 0

    # ------------------------------------------------------------------ interface of TorchPhysics
    def step(self, command_fn: CommandFn) -> Contacts:
        """Advance one control step (``substeps`` MuJoCo steps); ``command_fn(state)`` gives rotor commands."""
        c = self.consts
        s = self.state
        self._pack(s)
        flags = []
        wash = control_step_downwash(c, s)
        for _ in range(self.params.substeps):
            cmd = command_fn(s)
            throttle = s.throttle + (throttle_target(cmd) - s.throttle) * c.lag
            self._controls(s, throttle, wash)
            self._pool.rollout(
                self._models, self.datas, self._x, self._ctrl, control_spec=self.control_spec, skip_checks=True,
                nstep=1, state=self._out, sensordata=self._sens,
            )
            self._x[:] = self._out[:, 0]
            # contact sensors describe the contacts MuJoCo resolved during this sub-step (at its start)
            flags.append(self._hits(self._sens[:, 0], s))
            s = self._unpack(self._x, throttle)
        self.state = s
        racket, body, ground = (functools.reduce(torch.logical_or, f) for f in zip(*flags))
        return Contacts(racket=racket, body=body, ground=ground)

    def close(self) -> None:
        self._pool.close()

    def __del__(self):
        pool = getattr(self, "_pool", None)
        if pool is not None:
            pool.close()
