"""The referee: hits, turns, violations and rally outcomes. Reads physics, knows nothing of rewards."""

from volleybots.rules.referee import COURTS, TURN_MODES, Court, Events, Outcome, Referee, RefereeConfig

__all__ = ["COURTS", "TURN_MODES", "Court", "Events", "Outcome", "Referee", "RefereeConfig"]
