"""A still picture of a recorded episode (matplotlib, headless): court, net, the ball's flight with
its touches and faults, each drone's path in its team colour and the drones where the ball was last
touched. Drawn from the ``Episode`` the recorder kept, so it shows the same data as the ``.rrd``."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from volleybots.files import write_atomic
from volleybots.replay.recorder import BALL_COLOUR, FAULT_COLOUR, HIT_COLOUR, TEAM_COLOURS, TEAM_NAMES, Episode


def _rgb(c) -> tuple[float, ...]:
    return tuple(x / 255 for x in c)


def key_step(ep: Episode) -> int:
    """The moment the drones are drawn at: the last touch of the ball, else the last step."""
    return ep.hits[-1] if ep.hits else len(ep.ball) - 1


def check_plotting() -> None:
    """Raise ``ConfigError`` naming the extra when matplotlib is missing (asked before recording, so a
    failed still leaves no recording behind either)."""
    try:
        import matplotlib  # noqa: F401
    except ImportError:
        from volleybots.errors import ConfigError

        raise ConfigError("--still needs matplotlib: pip install 'volleybots[plot]'") from None


def _figure(ep: Episode, title: str, k: int, dpi: int):
    """The matplotlib figure of ``ep`` with the drones drawn at step ``k``."""
    check_plotting()
    import matplotlib

    matplotlib.use("Agg")  # headless: no display is needed, and none is opened
    import matplotlib.pyplot as plt

    length, width, net = ep.court
    lx, ly = length / 2, width / 2
    fig = plt.figure(figsize=(8, 4.6), dpi=dpi)
    ax = fig.add_subplot(projection="3d", computed_zorder=False)
    for team, sign in ((0, 1.0), (1, -1.0)):  # each half tinted in the colour of the team that defends it
        xs = np.array([[0.0, sign * lx], [0.0, sign * lx]])
        ax.plot_surface(xs, np.array([[-ly, -ly], [ly, ly]]), np.zeros((2, 2)), color=_rgb(TEAM_COLOURS[team]), alpha=0.08, shade=False)
    ax.plot([-lx, lx, lx, -lx, -lx], [-ly, -ly, ly, ly, -ly], [0] * 5, color="0.45", lw=1.2)
    ax.plot([0, 0], [-ly, ly], [0, 0], color="0.45", lw=1.0)
    ax.plot_surface(
        np.zeros((2, 2)), np.array([[-ly, ly], [-ly, ly]]), np.array([[0, 0], [net, net]]), color="0.6", alpha=0.35, shade=False
    )
    ax.plot([0, 0], [-ly, ly], [net, net], color="0.3", lw=1.5)
    for d, team in enumerate(ep.teams):
        colour = _rgb(TEAM_COLOURS[team % len(TEAM_COLOURS)])
        path = ep.pos[: k + 1, d]
        ax.plot(path[:, 0], path[:, 1], path[:, 2], color=colour, lw=0.8, alpha=0.45)
        ax.scatter(*ep.pos[k, d], color=colour, s=70, marker="s", edgecolors="black", linewidths=0.6, depthshade=False)
    ball = ep.ball
    ax.plot(ball[:, 0], ball[:, 1], ball[:, 2], color=_rgb(BALL_COLOUR), lw=2.0)
    ax.plot(ball[:, 0], ball[:, 1], np.zeros(len(ball)), color="0.75", lw=0.8, ls="--")  # its shadow on the floor
    for steps, colour, label in ((ep.hits, HIT_COLOUR, "touch"), (ep.faults, FAULT_COLOUR, "fault")):
        if steps:
            pts = ball[steps]
            ax.scatter(
                pts[:, 0], pts[:, 1], pts[:, 2], color=_rgb(colour), s=30, edgecolors="black", linewidths=0.4, depthshade=False, label=label
            )
    for t in sorted(set(ep.teams)):
        ax.scatter([], [], [], color=_rgb(TEAM_COLOURS[t]), marker="s", label=f"team {t} ({TEAM_NAMES[t]})")
    ax.plot([], [], color=_rgb(BALL_COLOUR), lw=2.0, label="ball")
    # a frame of a task without a ball has NaN for it (volleybots.integrations.render): nothing drawn, no height
    top = max(float(np.max(ball[:, 2], initial=0.0, where=np.isfinite(ball[:, 2]))), float(ep.pos[..., 2].max()), net) * 1.05
    pad = 0.5  # so the court's lines stand clear of the axes' edges
    ax.set(xlim=(-lx - pad, lx + pad), ylim=(-ly - pad, ly + pad), zlim=(0, top), xlabel="x (m)", ylabel="y (m)", zlabel="z (m)")
    ax.set_box_aspect((length + 2 * pad, width + 2 * pad, top))
    ax.view_init(elev=22, azim=-62)
    ax.tick_params(labelsize=7)
    ax.legend(loc="upper left", fontsize=8, frameon=False)
    if title:
        ax.set_title(title, fontsize=10)
    fig.subplots_adjust(left=0, right=1, bottom=0, top=0.94)
    return fig


def draw_still(ep: Episode, out: Path, title: str = "") -> Path:
    """Write the picture of ``ep`` to the PNG ``out`` (written whole: ``volleybots.files.write_atomic``)."""
    fig = _figure(ep, title, key_step(ep), dpi=100)
    import matplotlib.pyplot as plt

    out = Path(out)
    try:  # written whole or not at all; a full disk is one line
        write_atomic(out, lambda fh: fig.savefig(fh, format="png"), "the still picture")
    finally:
        plt.close(fig)
    return out


def still_frame(ep: Episode, title: str = "", dpi: int = 80) -> np.ndarray:
    """The picture of ``ep`` with the drones at its last step, as an RGB array [H, W, 3] uint8 (a
    video frame: 640 x 368 at the default ``dpi``, even sides as video encoders want)."""
    fig = _figure(ep, title, len(ep.ball) - 1, dpi=dpi)
    import matplotlib.pyplot as plt

    try:
        fig.canvas.draw()
        return np.asarray(fig.canvas.buffer_rgba())[..., :3].copy()
    finally:
        plt.close(fig)
