"""Joints: constraints between bodies. So far between particles: the distance joint, a rigid rod between two
particles or from a particle to an anchor (pendulums, chains, linkages of point masses), and the pulley joint, a
rope over two fixed pulleys (an Atwood machine)."""

from __future__ import annotations

from typing import Annotated, Literal, Union

import annotated_types as at
from pydantic import Field

from animbatch.scene.schema.base import Name, SceneModel, key


class DistanceJointSpec(SceneModel):
    """A rigid, massless rod that keeps two particles (or a particle and an anchor) at a fixed distance; it pulls
    and pushes along itself and does no work."""

    type: Literal["distance"] = key(description="Joint type.")
    between: Annotated[list[Name], at.Len(2, 2)] = key(
        description="The two ends: particles, or a particle and an anchor.", example=["pivot", "bob"])
    length: float | None = key(None, "The rod's length (default: the ends' distance at the start).", "m", gt=0)
    name: Name | None = key(None, "Name used in messages and the ledger (default: 'first--second').")


class PulleyJointSpec(SceneModel):
    """A light, inextensible rope from one particle up over a fixed pulley, across to a second pulley and down to a
    second particle: |x₁ − p₁| + |x₂ − p₂| stays ``length`` (the rope between the pulleys is fixed and not counted).
    It is always taut (a rope that can go slack is not modelled yet)."""

    type: Literal["pulley"] = key(description="Joint type.")
    between: Annotated[list[Name], at.Len(2, 2)] = key(description="The two particles at the rope's ends.",
                                                       example=["left", "right"])
    over: Annotated[list[Name], at.Len(2, 2)] = key(
        description="The fixed anchors the rope runs over: the first particle's pulley, then the second's (the same "
                    "anchor twice for a single pulley).", example=["pulley", "pulley"])
    length: float | None = key(None, "The rope's length from each end to its pulley, summed (default: at the "
                                     "start).", "m", gt=0)
    name: Name | None = key(None, "Name used in messages and the ledger (default: 'first--second').")


JointSpec = Annotated[Union[DistanceJointSpec, PulleyJointSpec], Field(discriminator="type")]
