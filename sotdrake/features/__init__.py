"""SoT features: an error ``e = s ⊖ s*``, its Jacobian ``∂e/∂v`` and ``ė_ref``, selected rows only.

Each feature's maths is a pure function over numpy arrays (``…_error_and_jacobian``), which its
``LeafSystem`` calls with the values of its input ports.
"""

from .base import Feature, FeatureValue
from .feature1d import Feature1D, feature1d_error_and_jacobian
from .feature6d import Feature6d, Feature6dDesired, pose_error_and_jacobian, shift_jacobian
from .generic import FeatureGeneric, FeatureGenericDesired, generic_error_and_jacobian
from .joint_limits import FeatureJointLimits, joint_limits_error_and_jacobian
from .manipulability import FeatureManipulability, manipulability_error_and_jacobian
from .momentum import FeatureMomentum, momentum_error_and_jacobian
from .posture import FeaturePosture, posture_error_and_jacobian
from .relative import FeatureRelative6d, relative_pose_error_and_jacobian
from .visual_point import FeatureVisualPoint, visual_point_error_and_jacobian

__all__ = [
    "Feature",
    "Feature1D",
    "Feature6d",
    "Feature6dDesired",
    "FeatureGeneric",
    "FeatureGenericDesired",
    "FeatureJointLimits",
    "FeatureManipulability",
    "FeatureMomentum",
    "FeaturePosture",
    "FeatureRelative6d",
    "FeatureValue",
    "FeatureVisualPoint",
    "feature1d_error_and_jacobian",
    "generic_error_and_jacobian",
    "joint_limits_error_and_jacobian",
    "manipulability_error_and_jacobian",
    "momentum_error_and_jacobian",
    "pose_error_and_jacobian",
    "posture_error_and_jacobian",
    "relative_pose_error_and_jacobian",
    "shift_jacobian",
    "visual_point_error_and_jacobian",
]
