"""Compiled models: the immutable Model, its state layout, the builder, the compiler and the equations of motion."""

from animbatch.model.builder import ModelBuilder, frame_times
from animbatch.model.compile import compile_scene
from animbatch.model.dynamics import Dynamics
from animbatch.model.layout import StateBlock, StateLayout
from animbatch.model.model import Model
from animbatch.model.rigid_set import RigidBodySet

__all__ = ["Dynamics", "Model", "ModelBuilder", "RigidBodySet", "StateBlock", "StateLayout", "compile_scene",
           "frame_times"]
