"""Render-farm stages: bake the simulation once into a cache, render frame ranges from it (idempotently, in
parallel), then encode the frames into videos."""

from animbatch.farm.cache import BakeResult, bake, bake_key, cache_file
from animbatch.farm.frame_files import FrameRange, frame_is_complete, parse_frames, render_frames

__all__ = ["BakeResult", "FrameRange", "bake", "bake_key", "cache_file", "frame_is_complete", "parse_frames",
           "render_frames"]
