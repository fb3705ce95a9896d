"""A model builder whose fields may be given as scene specs or dicts: :class:`SceneModelBuilder`."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from animbatch.compile.forces import field_term
from animbatch.sim.model.builder import ModelBuilder


class SceneModelBuilder(ModelBuilder):
    """:class:`animbatch.sim.model.builder.ModelBuilder` with ``add_field({"type": "drag", ...})``: a dict is
    validated with the scene's rules (a pydantic ValidationError names the bad key), a field spec is used as is, and
    a term factory is passed through."""

    def add_field(self, term: Any, bodies: Sequence[int] | np.ndarray | None = None) -> None:
        super().add_field(term if callable(term) else field_term(term), bodies)
