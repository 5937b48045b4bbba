"""The play layer: rollouts, episodes, seats, games and the payoff pool that train, population, replay
and eval all stand on.

Floor: above ``policies`` (what plays), below ``replay``, ``train``, ``population`` and ``eval``.
"""

from volleybots.play.episodes import collect, finished_stats, run_episodes, stat_keys, summarize
from volleybots.play.games import Games, play_games
from volleybots.play.seats import AllAgents, SelfPlay, Versus, default_seat, team_slice

__all__ = [
    "AllAgents", "Games", "SelfPlay", "Versus", "collect", "default_seat", "finished_stats", "play_games", "run_episodes",
    "stat_keys", "summarize", "team_slice",
]
