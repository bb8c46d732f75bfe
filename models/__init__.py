"""The physical description of a tippe top: parameters, friction, initial state, scenes."""

from tippetop.models.errors import TippetopError
from tippetop.models.params import FRICTION_LAWS, FrictionParams, InitialState, TopParams

__all__ = ["FRICTION_LAWS", "FrictionParams", "InitialState", "TippetopError", "TopParams"]
