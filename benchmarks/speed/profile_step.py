"""Where the time of one compiled env step goes (docs/performance.md "Profile").

    python benchmarks/speed/profile_step.py task=3v3 num_envs=4096

Times, in CPU ms per call of this process (one torch thread; robust to a shared machine, unlike wall
time), the compiled pieces of a step at the same shapes: the physics alone (one control step, the
ceiling of the env), the whole step graph (physics, referee, rewards, statistics, observations), the
reset graph (a masked reset of about 2% of the envs), and ``step_and_maybe_reset`` with its
tensordict plumbing; then, compiled on their own for comparison, the observation and the referee with
the task's evaluation.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import torch

import volleybots
from volleybots.config.args import option, script_options
from volleybots.physics.torch_backend import compile_options


def cpu_ms(fn, reps: int) -> float:
    fn()
    fn()
    start = time.process_time()
    for _ in range(reps):
        fn()
    return (time.process_time() - start) / reps * 1e3


@dataclass
class Args:
    task: str = option("3v3", "the task profiled")
    num_envs: int = option(4096, "worlds stepped together", ge=1)
    reps: int = option(20, "timed calls per piece", ge=1)


def main(argv=None) -> None:
    args = script_options(Args, argv, __doc__)
    torch.set_num_threads(1)
    n = args.num_envs
    env = volleybots.make_env(args.task, num_envs=n, compile=True, seed=0)
    env.reset()
    td = env.reset()
    action = env.full_action_spec.rand()
    gen = torch.Generator().manual_seed(0)
    mask = torch.rand(n, generator=gen) < 0.02
    a = action["agents", "action"]
    physics = torch.compile(lambda: env.physics.step(env.actions.command_fn(a)), **compile_options())
    s = env.physics.state
    c = env.physics.step(env.actions.command_fn(a))

    def referee_and_rewards():
        return env.evaluate(env.referee.update(s.pos, s.ball_pos, c.racket, c.body)).terminated

    rows = [
        ("physics only (one control step)", physics),
        ("whole step graph", lambda: env._step_fn(a)),
        ("reset graph (2% of envs)", lambda: env._reset_envs(mask)),
        ("step_and_maybe_reset (+ tensordicts, + reset)", lambda: env.step_and_maybe_reset(td.update(action))),
        ("observation alone", torch.compile(env.observe, **compile_options())),
        ("referee + rewards alone", torch.compile(referee_and_rewards, **compile_options())),
    ]
    print(f"{args.task}, {n} envs, {env.n_drones} drones, compiled, 1 thread")
    print("| piece | CPU ms per call | env-steps per CPU-s at that cost |")
    for name, fn in rows:
        ms = cpu_ms(fn, args.reps)
        print(f"| {name} | {ms:.2f} | {n / ms:.0f}k |", flush=True)


if __name__ == "__main__":
    main()
