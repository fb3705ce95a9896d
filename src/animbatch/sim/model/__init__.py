"""Compiled models: the immutable Model, its state layout, the builder and the equations of motion.

The scene compiler that fills a builder from a scene spec is :func:`animbatch.compile.model.compile_scene`.
"""

from animbatch.sim.model.builder import ModelBuilder
from animbatch.sim.model.dynamics import Dynamics
from animbatch.sim.model.layout import StateBlock, StateLayout
from animbatch.sim.model.model import Model
from animbatch.sim.model.rigid_set import RigidBodySet

__all__ = ["Dynamics", "Model", "ModelBuilder", "RigidBodySet", "StateBlock", "StateLayout"]
