#!/usr/bin/env python3
"""TALOS looks at a moving point while holding its feet and its CoM; a posture task below.

Stack (highest first): ``contactRF``, ``contactLF``, ``com`` (held), ``gaze`` (a
``FeatureVisualPoint``: the point's image in the head camera ``rgbd_rgb_optical_frame`` driven to
the image centre, with the point's velocity as feed-forward), ``posture`` (half-sitting, joints
only). The point circles in front of the robot, from Drake's ``Sine`` plus a constant::

    p(t) = (1.5, 0.35 sin(2π f t), 1.35 + 0.2 cos(2π f t)) m,   f = 0.25 Hz

    python diagrams/posture_gaze.py --duration 8 --out out/posture_gaze

The scenario (its diagram, run and summary) is :mod:`sotdrake.scenarios.posture_gaze`.
"""

from sotdrake import report
from sotdrake.scenarios.posture_gaze import build_diagram, main

__all__ = ["build_diagram", "main"]

if __name__ == "__main__":
    report(main())
