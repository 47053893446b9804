"""Analysis of a trajectory: segment → fit the flights → impacts → uncertainty.

The modules follow the data: :mod:`.segmentation` finds the release and the bounces, :mod:`.flights` fits
the flights, :mod:`.impacts` computes every impact quantity from the fit, :mod:`.uncertainty` their
covariance, and :mod:`.bounces` runs the steps with their defaults (:func:`analyse_bounces`).
"""

from .bounces import NOMINAL_DRAG_RELATIVE_SE, BounceAnalysis, analyse_bounces
from .flights import MIN_SAMPLES_PER_FLIGHT, SharedAcceleration, shared_acceleration, shared_acceleration_with_drag
from .segmentation import Segmentation, estimate_noise, find_impacts, segment, up_direction, vertical_sign
from .tables import se_column_name

__all__ = [
    "MIN_SAMPLES_PER_FLIGHT",
    "NOMINAL_DRAG_RELATIVE_SE",
    "BounceAnalysis",
    "SharedAcceleration",
    "analyse_bounces",
    "Segmentation",
    "estimate_noise",
    "find_impacts",
    "segment",
    "up_direction",
    "vertical_sign",
    "se_column_name",
    "shared_acceleration",
    "shared_acceleration_with_drag",
]
