"""The hierarchical 3 vs 3 policy: a rule-based, event-driven high level over drills (paper section
5.4 and appendix E; docs/hierarchical.md).

It acts for one team like any team policy (``("agents", "observation")`` [N, 3] in, ``("agents",
"action")`` out, the match's mirrored view, so either side). At every hit the high level assigns
each of its three drones a drill, and each drone then runs that drill's low-level policy on the
drill's observation, built from the drone's match observation by the layouts' part names
(tasks/layout.py: the drills observe the match's root, anchor, ball, ball_vel and may_hit; Hover's
target is the anchor part):

| event | front-left | front-right | back |
|---|---|---|---|
| the own team serves (a new rally, the ball at rest, the team's turn) | hover | hover | serve |
| the opponents serve (a new rally, not the team's turn) | hover | hover | hover |
| an opponent hits the ball | hover | hover | pass |
| the own first touch of a possession (the pass) | set | hover | hover |
| the own second touch (the set) | hover | attack, left or right at random | hover |
| the own serve, the third touch | hover | hover | hover |

A drill's touch is assigned to a drone that has not touched the ball in this possession (if the
pass was made by the front-left drone, say, the front-right sets and the back attacks), so the team
never touches twice in a row with one drone. Hover flies back to the drone's anchor; **decision**:
a hovering drone whose anchor is within ``room`` of a teammate playing the ball hovers that far
away from it instead (the back drone receiving a ball that comes down at a front anchor would
otherwise meet the teammate there: teammates closer than 0.8 m end the rally).

Events come from the observations alone (the high level keeps the previous step's ball velocity and
may-hit flags per env): a new rally is a ball at rest (it never is in play); a hit is a jump of the
ball's velocity away from free flight; an own touch is a teammate's may-hit flag falling without the
ball crossing the net, any other hit by the drone nearest the ball being an opponent's.

Who plays is a **choice** handed to a chooser (``RuleChooser``, the rules above, by default): who
receives an opponent's ball (``receive``: a role), who sets (``set``: a role that has not touched)
and who attacks on which side (``attack``: a role that has not touched, times left/right). A learned
chooser (volleybots/policies/high_level.py) makes the same choices from the same ``features``: the
HCSP route, a learned high level over the drills.

Low-level policies: the scripted drills (scripted/drills.py, Hover's scripted policy), or trained
checkpoints where given (``checkpoints``: drill name -> checkpoint file or run dir, trained on that
drill with the same action space). The decision log: the policy writes ``("agents", "drill")`` [N, 3]
(codes of ``DRILL_LABELS``), which replays show per drone (volleybots/replay/).
"""

from __future__ import annotations

import torch
from tensordict import TensorDict, TensorDictBase

from volleybots.keys import ACTION, AGENTS, DRILL, OBS, leaf
from volleybots.scripted.ballistics import crossing
from volleybots.tasks import TASKS
from volleybots.tasks.drills import BACK, CONTACT_Z, FRONT_LEFT, FRONT_RIGHT

HOVER, SERVE, PASS, SET, ATTACK = range(5)
DRILLS = ("hover", "serve", "pass", "set", "attack")  # the drill tasks, by index
# ("agents", "drill") codes: 0 for a drone no high level drives, then each drill (the attack per side)
DRILL_LABELS = ("none", "hover", "serve", "pass", "set", "attack left", "attack right")
TEAM = 3
HIT_JUMP = 0.5  # m/s: a change of the ball's velocity beyond free flight this large is a hit
SPACE = 1.3  # m: hovering drones steer away from teammates closer than this (0.8 m ends the rally) ...
SPACE_GAIN = 2.0  # ... by this many metres per metre inside it
NET_KEEP = 1.2  # m: a drone making room stays this far from the net
ROOM = 1.5  # m: a hovering drone keeps this far (horizontally) from a teammate playing the ball and from where it meets it
# the high level's choices and their options: a role; a role and an attack side (role * 2 + side)
CHOICES = {"receive": TEAM, "set": TEAM, "attack": 2 * TEAM}
FEATURES = 30  # the size of ``features``: what a chooser sees when it chooses


def features(parts: dict[str, torch.Tensor], touched: torch.Tensor, gravity: float = 9.81, landing=None) -> torch.Tensor:
    """[N, FEATURES] what a chooser sees, from a team's observation parts (drones in role order,
    the team's mirrored view: its own half is x > 0): the ball (position, velocity), where and when it
    comes down through the contact height (zeros and 0 s where it does not), the own drones' and the
    opponents' positions, and which drones touched in this possession. Scaled to about unit size.
    ``landing``: ``crossing`` of this ball through the contact height, where the caller has it."""
    ball = parts["root"][:, 0, :3] + parts["ball"][:, 0]
    vel = parts["ball_vel"][:, 0]
    fall, when = crossing(ball, vel, CONTACT_Z, gravity) if landing is None else landing
    ok = torch.isfinite(fall).all(-1, keepdim=True) & torch.isfinite(when).reshape(-1, 1)
    fall = torch.where(ok, fall, torch.zeros_like(fall))[:, :2]
    when = torch.where(ok, when.reshape(-1, 1), torch.zeros_like(ok, dtype=fall.dtype)).clamp(0.0, 3.0)
    everyone = parts["positions"][:, 0]  # [N, 18]: own team (by id), then the opponents
    return torch.cat((ball / 6.0, vel / 10.0, fall / 6.0, when, everyone / 6.0, touched.float()), -1)


class RuleChooser:
    """The paper's rules as a chooser: the back drone receives; the first free drone of (front-left,
    front-right, back) sets and of (front-right, front-left, back) attacks, on a random side."""

    def __init__(self, generator: torch.Generator | None = None):
        self.generator = generator

    def __call__(self, kind: str, feats: torch.Tensor, legal: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
        n = feats.shape[0]
        if kind == "receive":
            return torch.full((n,), BACK, dtype=torch.long, device=feats.device)
        taken = ~(legal[:, ::2] if kind == "attack" else legal)  # a role is legal when it has not touched
        order = (FRONT_LEFT, FRONT_RIGHT, BACK) if kind == "set" else (FRONT_RIGHT, FRONT_LEFT, BACK)
        role = HighLevel.free_drone(taken, order)
        if kind == "set":
            return role
        # one draw over the whole batch at every call, as the rules always did: a seed gives the same games
        gen_device = feats.device if self.generator is None else self.generator.device
        side = torch.randint(0, 2, (n,), generator=self.generator, device=gen_device).to(feats.device)
        return role * 2 + side


def drill_code(drill: torch.Tensor, side: torch.Tensor) -> torch.Tensor:
    """[N, 3] ``DRILL_LABELS`` codes of drills [N, 3] (the attack split by ``side`` [N])."""
    code = drill + 1
    return torch.where(drill == ATTACK, code + side.unsqueeze(-1), code)


class HighLevel:
    """The event-driven assignment of drills for one team, per env of a batch (roles: tasks/drills.py
    FRONT_LEFT, FRONT_RIGHT, BACK, the drones' ids within the team)."""

    def __init__(self, num_envs: int, device, generator: torch.Generator | None = None, dt: float = 0.02, gravity: float = 9.81,
                 chooser=None):
        n = num_envs
        self.generator = generator
        self.gravity = gravity
        # chooser(kind, features [N, F], legal [N, options], mask [N]) -> [N] option (rows outside mask ignored)
        self.chooser = chooser if chooser is not None else RuleChooser(generator)
        self.feats = torch.zeros(n, FEATURES, device=device)  # this step's features (``update`` sets them)
        # the chooser may ask that an opponent's hit call a receiver only when the ball comes down in the own
        # half (the 3v3 scripted team serves with a toss to itself first); the rules call one at every hit
        self.receive_coming = bool(getattr(self.chooser, "receive_coming", False))
        # ... and that a front drone it calls to receive returns the ball at once (the attack drill, on a
        # side it chooses) rather than pass it: the scripted team's serve comes down near the front drones
        self.receive_attack = bool(getattr(self.chooser, "receive_attack", False))
        self.fall = torch.tensor((0.0, 0.0, -gravity * dt), device=device)
        self.drill = torch.full((n, TEAM), HOVER, dtype=torch.long, device=device)
        self.side = torch.zeros(n, dtype=torch.long, device=device)  # of the attack: 0 left, 1 right
        self.touched = torch.zeros(n, TEAM, dtype=torch.bool, device=device)  # own touches this possession
        self.prev_vel = torch.zeros(n, 3, device=device)
        self.prev_may = torch.zeros(n, TEAM, dtype=torch.bool, device=device)
        self.prev_x = torch.zeros(n, device=device)

    # ------------------------------------------------------------------ the rules, per event
    def on_rally(self, mask: torch.Tensor, serving: torch.Tensor) -> None:
        """A new rally in the envs of ``mask``: the back drone serves where ``serving``; all hover."""
        rally = torch.full_like(self.drill, HOVER)
        rally[:, BACK] = torch.where(serving, SERVE, HOVER)
        self.drill = torch.where(mask.unsqueeze(-1), rally, self.drill)
        self.touched = self.touched & ~mask.unsqueeze(-1)

    def on_opponent_hit(self, mask: torch.Tensor) -> None:
        """The opponents hit: a new possession is coming; the chosen drone (the rules: the back one)
        receives it (Pass; with ``receive_attack`` a front drone returns it at once: Attack)."""
        if not bool(mask.any()):
            return
        legal = torch.ones(mask.shape[0], CHOICES["receive"], dtype=torch.bool, device=mask.device)
        who = self.chooser("receive", self.feats, legal, mask)
        play = torch.full_like(who, PASS)
        if self.receive_attack:
            front = mask & (who != BACK)
            own = torch.nn.functional.one_hot(who, TEAM).bool().repeat_interleave(2, 1)  # the receiver's two sides
            pick = self.chooser("attack", self.feats, own, front)
            play = torch.where(front, ATTACK, play)
            self.side = torch.where(front, pick % 2, self.side)
        rally = torch.where(torch.arange(TEAM, device=mask.device) == who.unsqueeze(-1), play.unsqueeze(-1), HOVER)
        self.drill = torch.where(mask.unsqueeze(-1), rally, self.drill)
        self.touched = self.touched & ~mask.unsqueeze(-1)

    def on_own_touch(self, mask: torch.Tensor, toucher: torch.Tensor) -> None:
        """Drone ``toucher`` [N] (a role) of the team touched the ball: after a pass a chosen drone sets,
        after a set a chosen drone attacks on a chosen side, after a serve or an attack all hover; a
        touch goes to a drone that has not touched in this possession (the legal options)."""
        # a serve or an attack (also a receive returned at once) ends the team's possession
        played = self.drill.gather(1, toucher.unsqueeze(1)).squeeze(1)
        served = (played == SERVE) | (played == ATTACK)
        touched = self.touched | (torch.nn.functional.one_hot(toucher, TEAM).bool() & mask.unsqueeze(-1))
        count = touched.sum(1)
        setting = ~served & (count == 1)
        attacking = ~served & (count == 2)
        legal = ~touched | touched.all(1, keepdim=True)  # all touched: any (never in a legal possession)
        setter = self.chooser("set", self.feats, legal, mask & setting)
        pick = self.chooser("attack", self.feats, legal.repeat_interleave(2, 1), mask & attacking)
        who = torch.where(setting, setter, torch.div(pick, 2, rounding_mode="floor"))
        what = torch.where(setting, SET, ATTACK)
        play = (setting | attacking).unsqueeze(-1) & (torch.arange(TEAM, device=who.device) == who.unsqueeze(-1))
        nxt = torch.where(play, what.unsqueeze(-1), torch.full_like(self.drill, HOVER))
        self.side = torch.where(mask & attacking, pick % 2, self.side)
        self.drill = torch.where(mask.unsqueeze(-1), nxt, self.drill)
        self.touched = torch.where(mask.unsqueeze(-1), touched, self.touched)

    @staticmethod
    def free_drone(touched: torch.Tensor, preference: tuple[int, ...]) -> torch.Tensor:
        """[N] the first role in ``preference`` that has not touched the ball (the first if all have)."""
        pick = torch.full(touched.shape[:1], preference[0], dtype=torch.long, device=touched.device)
        for role in reversed(preference):
            pick = torch.where(~touched[:, role], role, pick)
        return pick

    # ------------------------------------------------------------------ events from observations
    def update(self, parts: dict[str, torch.Tensor]) -> None:
        """Detect this step's events from the team's observation parts (each [N, 3, size], drones in
        role order) and apply the rules."""
        vel = parts["ball_vel"][:, 0]
        may = parts["may_hit"][..., 0] > 0.5
        turn = parts["turn"][:, 0, 0] > 0.5
        ball = (parts["root"][:, 0, :3] + parts["ball"][:, 0])  # ball minus drone, plus the drone
        fresh = vel.norm(dim=-1) < 1e-6  # a ball at rest: a new rally (in play it always moves)
        jump = (vel - (self.prev_vel + self.fall)).norm(dim=-1) > HIT_JUMP
        crossed = torch.sign(ball[:, 0]) != torch.sign(self.prev_x)
        fell = self.prev_may & ~may & ~crossed.unsqueeze(-1)  # a teammate's may-hit flag fell: it touched
        own = fell.any(1) & ~fresh
        team_pos = parts["positions"][:, 0].unflatten(-1, (2 * TEAM, 3))  # own team first
        nearest = (team_pos - ball.unsqueeze(1)).norm(dim=-1).argmin(1)
        # where and when the ball comes down through the contact height: the features and the hovering drones' room use it
        self.landing = crossing(ball, vel, CONTACT_Z, self.gravity)
        self.feats = features(parts, self.touched & ~fresh.unsqueeze(-1), self.gravity, self.landing)
        coming = self.feats[:, 6] > 0 if self.receive_coming else torch.ones_like(fresh)
        opponent = jump & ~own & ~fresh & (nearest >= TEAM) & coming
        self.on_rally(fresh, turn)
        self.on_opponent_hit(opponent)
        self.on_own_touch(own, fell.long().argmax(1))
        self.prev_vel, self.prev_may, self.prev_x = vel.clone(), may.clone(), ball[:, 0].clone()


class HierarchicalPolicy:
    """The high level and the drills' low-level policies, acting for one team of a 3 vs 3 env."""

    def __init__(self, env, lows: dict[str, callable], generator: torch.Generator | None = None, chooser=None):
        if env.name != "3v3":
            raise ValueError(f"the hierarchical policy plays 3v3 only, not {env.name!r}")
        self.env = env
        self.lows = lows
        self.match_layout = env.layout
        self.layouts = {d: TASKS[d].obs_layout(env.with_throttle) for d in DRILLS}
        self.high = HighLevel(env.num_envs, env.device, generator, env.params.dt, env.params.gravity, chooser)

    def drill_obs(self, drill: str, parts: dict[str, torch.Tensor], side: torch.Tensor, target: torch.Tensor) -> torch.Tensor:
        """The observations [..., obs] of ``drill`` from match parts [..., size]."""
        layout = self.layouts[drill]
        if drill == "hover":
            return layout.build(root=parts["root"], target=parts["anchor"] - target)
        values = {k: parts[k] for k in layout.names if k != "side"}
        if "side" in layout.names:
            values["side"] = torch.nn.functional.one_hot(side, 2).float()
        return layout.build(**values)

    def hover_offset(self, parts: dict[str, torch.Tensor]) -> torch.Tensor:
        """[N, 3, 3] how far from its anchor each drone hovers: ``ROOM`` (horizontally) away from where
        the ball comes down to a teammate playing it (the player flies there; a hovering drone that
        waited for it would be too late to get out of its way). The player comes from behind (the
        back drone receives), so the hovering drone makes room toward the net and its side line,
        never back, and stays ``NET_KEEP`` from the net."""
        pos = parts["root"][..., :3]
        anchor = pos - parts["anchor"]
        fall = self.high.landing[0]  # the high level's, from the same parts this step
        coming = (self.high.drill != HOVER).any(1) & torch.isfinite(fall).all(-1) & (fall[:, 0] > 0)
        d = anchor[..., :2] - torch.nan_to_num(fall[:, None, :2])  # [N, 3, 2]
        dist = d.norm(dim=-1, keepdim=True)
        # toward the net as far as the way from the ball says, the rest toward the own side line
        ax = torch.where(dist[..., 0] < 0.3, -(0.5**0.5), (d[..., 0] / dist[..., 0].clamp_min(1e-6)).clamp(max=0.0))
        ay = torch.where(anchor[..., 1] < 0, -1.0, 1.0) * (1.0 - ax * ax).sqrt()
        push = torch.stack((ax, ay), -1) * (ROOM - dist).clamp_min(0.0) * coming[:, None, None]
        # and away from teammates close by (a passer flying home passes the front drones)
        gap = pos[:, :, None, :2] - pos[:, None, :, :2]  # [N, me, other, 2]
        near = gap.norm(dim=-1, keepdim=True)
        others = ~torch.eye(TEAM, dtype=torch.bool, device=pos.device)[None, :, :, None]
        push = push + (gap / near.clamp_min(1e-6) * (SPACE - near).clamp_min(0.0) * SPACE_GAIN * others).sum(2)
        push[..., 0] = torch.maximum(push[..., 0], NET_KEEP - anchor[..., 0])
        return torch.cat((push, torch.zeros_like(push[..., :1])), -1)

    def __call__(self, td: TensorDictBase) -> TensorDictBase:
        obs = td.get(OBS)
        parts = self.match_layout.split(obs)
        order = parts["id"].argmax(-1)  # role of each agent
        by_role = {k: torch.gather(v, 1, order.argsort(1).unsqueeze(-1).expand_as(v)) for k, v in parts.items()}
        self.high.update(by_role)
        drill = self.high.drill.gather(1, order)  # per agent
        side = self.high.side.unsqueeze(1).expand_as(drill)
        target = self.hover_offset(by_role).gather(1, order.unsqueeze(-1).expand(-1, -1, 3))
        action = None
        for k, name in enumerate(DRILLS):
            sel = drill == k
            if not bool(sel.any()):
                continue
            sub = {p: v[sel] for p, v in parts.items()}
            o = self.drill_obs(name, sub, side[sel], target[sel])
            a = _act(self.lows[name], o)
            if action is None:
                action = torch.zeros(*drill.shape, a.shape[-1], dtype=a.dtype, device=a.device)
            action[sel] = a
        td.set(ACTION, action)
        td.set(DRILL, drill_code(self.high.drill, self.high.side).gather(1, order))
        return td


def _act(policy, obs: torch.Tensor) -> torch.Tensor:
    """A drill policy's actions [M, 4] for observations [M, obs] (as M envs of one drone)."""
    m = obs.shape[0]
    td = TensorDict({AGENTS: TensorDict({leaf(OBS): obs.unsqueeze(1)}, batch_size=(m, 1))}, batch_size=(m,))
    out = policy(td)
    out = td if out is None else out
    action = out if isinstance(out, torch.Tensor) else out.get(ACTION)
    return action.reshape(m, -1)


def make_hierarchical(env, learned: dict[str, object] | None = None, generator: torch.Generator | None = None,
                      chooser=None) -> HierarchicalPolicy:
    """The hierarchical policy for one team of ``env`` (3v3): each drill's low-level policy is
    ``learned[drill]`` where given (a trained drill policy acting on that drill's observations, built
    by ``volleybots.policies.learned_drill``), else the scripted one; ``chooser`` makes the high
    level's choices (None: ``RuleChooser``, the rules)."""
    from volleybots.scripted.policies import SCRIPTED_POLICIES

    learned = dict(learned or {})
    unknown = set(learned) - set(DRILLS)
    if unknown:
        raise ValueError(f"unknown drills {sorted(unknown)} in the hierarchical policy's checkpoints; allowed: {', '.join(DRILLS)}")
    if env.action_space_name not in ("prt", "ctbr"):
        raise ValueError(f"the hierarchical policy acts in env.action_space prt or ctbr, not {env.action_space_name!r}")
    lows = {name: learned[name] if name in learned else SCRIPTED_POLICIES[name](env.action_space_name, env.params) for name in DRILLS}
    return HierarchicalPolicy(env, lows, generator, chooser)


__all__ = ["CHOICES", "DRILLS", "DRILL_LABELS", "FEATURES", "HighLevel", "HierarchicalPolicy", "RuleChooser", "drill_code", "features",
           "make_hierarchical"]
