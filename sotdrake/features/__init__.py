"""SoT features: an error ``e = s ⊖ s*`` and its Jacobian ``∂e/∂v``, selected rows only."""

from .feature6d import Feature6d, Feature6dDesired, pose_error_and_jacobian, shift_jacobian
from .generic import FeatureGeneric, FeatureGenericDesired

__all__ = [
    "Feature6d",
    "Feature6dDesired",
    "FeatureGeneric",
    "FeatureGenericDesired",
    "pose_error_and_jacobian",
    "shift_jacobian",
]
