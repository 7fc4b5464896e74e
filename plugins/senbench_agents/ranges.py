"""The ranges the agents' config fields are declared with. A suite value outside one is
reported at its own line, with pydantic's message; a plain ``int`` field takes any value of
its type, and no number field takes an infinite or NaN one (refused at validation)."""

from typing import Annotated

from pydantic import Field

PositiveInt = Annotated[int, Field(ge=1)]
NonNegativeInt = Annotated[int, Field(ge=0)]
PositiveFloat = Annotated[float, Field(gt=0, allow_inf_nan=False)]
NonNegativeFloat = Annotated[float, Field(ge=0, allow_inf_nan=False)]
Probability = Annotated[float, Field(ge=0, le=1, allow_inf_nan=False)]
"""A probability, a discount or a trace decay: in [0, 1]."""
