"""Joints: constraints between bodies. So far the distance joint, a rigid rod between two particles or from a
particle to an anchor (pendulums, chains, linkages of point masses)."""

from __future__ import annotations

from typing import Annotated, Literal

import annotated_types as at

from animbatch.scene.schema.base import Name, SceneModel, key


class DistanceJointSpec(SceneModel):
    """A rigid, massless rod that keeps two particles (or a particle and an anchor) at a fixed distance; it pulls
    and pushes along itself and does no work."""

    type: Literal["distance"] = key(description="Joint type.")
    between: Annotated[list[Name], at.Len(2, 2)] = key(
        description="The two ends: particles, or a particle and an anchor.", example=["pivot", "bob"])
    length: float | None = key(None, "The rod's length (default: the ends' distance at the start).", "m", gt=0)
    name: Name | None = key(None, "Name used in messages and the ledger (default: 'first--second').")


JointSpec = DistanceJointSpec
