"""Friction simulators (thesis chapter 6): the laws of 6.1 driven along a prescribed position
(``dahl``, ``lugre``, ``gms``: position -> force, the cross-prediction of 6.2 / 6.3) and the
closed-loop ``friction-plant`` of 6.4 (mass, friction, noise, P-controller, random reference),
which ``dynmodel control`` drives with a model's feed-forward. SI units throughout.
"""

from .sources import Dahl, FrictionPlant, Gms, LuGre

__all__ = ["Dahl", "LuGre", "Gms", "FrictionPlant"]
