"""Force terms, one law per module, registered by the field ``type`` they implement.

Importing this package registers every field type in :data:`FIELD_TERMS`. Springs come from the scene's ``springs``
list rather than from ``fields``, so :class:`SpringForces` is built directly by the model builder.
"""

from animbatch.forces import (aerodynamics, applied, buoyancy, drag, gravitation,  # noqa: F401  (registers the field types)
                              gravity)
from animbatch.forces.base import FIELD_TERMS, BodyTable, ForceTerm, Kinematics
from animbatch.forces.buoyancy import Buoyancy
from animbatch.forces.drag import Drag
from animbatch.forces.gravitation import Gravitation
from animbatch.forces.gravity import UniformGravity
from animbatch.forces.springs import SpringForces, SpringSet

__all__ = ["FIELD_TERMS", "BodyTable", "Buoyancy", "Drag", "ForceTerm", "Gravitation", "Kinematics", "SpringForces",
           "SpringSet", "UniformGravity"]
