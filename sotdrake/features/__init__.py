"""SoT features: an error ``e = s ⊖ s*``, its Jacobian ``∂e/∂v`` and ``ė_ref``, selected rows only."""

from .base import Feature
from .feature1d import Feature1D
from .feature6d import Feature6d, Feature6dDesired, pose_error_and_jacobian, shift_jacobian
from .generic import FeatureGeneric, FeatureGenericDesired
from .joint_limits import FeatureJointLimits
from .posture import FeaturePosture
from .relative import FeatureRelative6d
from .visual_point import FeatureVisualPoint

__all__ = [
    "Feature",
    "Feature1D",
    "Feature6d",
    "Feature6dDesired",
    "FeatureGeneric",
    "FeatureGenericDesired",
    "FeatureJointLimits",
    "FeaturePosture",
    "FeatureRelative6d",
    "FeatureVisualPoint",
    "pose_error_and_jacobian",
    "shift_jacobian",
]
