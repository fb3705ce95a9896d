"""The simulation: numbers only.

Everything below this package works on arrays and the frozen :class:`~animbatch.sim.model.Model`; nothing here
imports the scene format (``animbatch.scene``), the compiler, rendering, the farm or the API. The compiler
(:mod:`animbatch.compile`) is the one place that turns a scene spec into these numbers; CI checks the wall with an
import-linter contract (``.importlinter``).
"""
