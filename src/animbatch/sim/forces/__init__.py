"""Force terms, one law per module, each with a numeric ``build_*`` constructor.

Which scene field ``type`` builds which term is written once, in :data:`animbatch.compile.forces.FIELD_TERMS`.
Springs come from the scene's ``springs`` list rather than from ``fields``, so :class:`SpringForces` is built
directly by the model builder.
"""

from animbatch.sim.forces.buoyancy import Buoyancy
from animbatch.sim.forces.drag import Drag
from animbatch.sim.forces.gravitation import Gravitation
from animbatch.sim.forces.gravity import UniformGravity
from animbatch.sim.forces.springs import SpringForces, SpringSet
from animbatch.sim.forces.term import BodyTable, ForceTerm, Kinematics, TermFactory

__all__ = ["BodyTable", "Buoyancy", "Drag", "ForceTerm", "Gravitation", "Kinematics", "SpringForces", "SpringSet",
           "TermFactory", "UniformGravity"]
