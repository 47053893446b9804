"""phonesim: drop-test clips as phones film them, with the ground truth beside them.

Independent of dropfit: the ball's physics comes from :mod:`refsim`, the
pictures from numpy/OpenCV, the file from a real encoder through PyAV.  See
``phonesim/README.md``.
"""

from .config import (BallStyle, CameraSetup, Checkerboard, ClipConfig, FrameTiming, HandStyle, Marker, Ruler,
                     SceneStyle, SensorEffects)
from .presets import PRESET_SUFFIX, PRESETS
from .render import Truth, iter_frames, render_clip, truth_paths
from .sound import SoundTrack

__all__ = [
    "BallStyle", "CameraSetup", "Checkerboard", "ClipConfig", "FrameTiming", "HandStyle", "Marker", "Ruler",
    "SceneStyle", "SensorEffects", "PRESETS", "PRESET_SUFFIX", "Truth", "iter_frames", "render_clip", "truth_paths",
    "SoundTrack",
]
