"""The physical description of a tippe top: parameters, friction, initial state, scenes."""

from models.errors import TippetopError
from models.params import FRICTION_LAWS, FrictionParams, InitialState, TopParams

__all__ = ["FRICTION_LAWS", "FrictionParams", "InitialState", "TippetopError", "TopParams"]
