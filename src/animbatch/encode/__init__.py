"""Writers for rendered frames: H.264 MP4 through ffmpeg, and PNG sequences. Heavy imports stay inside."""

from animbatch.encode.images import PngSequenceWriter
from animbatch.encode.video import VIDEO_KINDS, Mp4Writer, VideoWriter

__all__ = ["VIDEO_KINDS", "Mp4Writer", "PngSequenceWriter", "VideoWriter"]
