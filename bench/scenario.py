"""The benchmark scenario, shared by sotdrake and its peers (pink, placo).

TALOS (``talos_reduced``, free flyer) in half-sitting; the stack of the tutorial: both soles held
(6D), the CoM held, the right hand point (wrist + 0.1 m along its x axis, the tutorial's ``opmodif``)
driven to (0.5, -0.2, 1.0) m. Gains: 10 /s on feet and CoM, 4.9 /s on the hand (the tutorial's
adaptive gain at zero error, constant here so that every peer gets the same law). Joint position
and velocity limits on. Every peer loads the same URDF text: sotdrake's fixed TALOS plus a fixed
frame ``right_hand_point`` at the hand point, so that all three control the same point.
"""

from __future__ import annotations

import tempfile
from pathlib import Path

import numpy as np

from sotdrake.robots import load_talos
from sotdrake.robots.talos import fixed_urdf_text

TARGET = np.array([0.5, -0.2, 1.0])
HAND_FRAME = "right_hand_point"
FEET = ("left_sole_link", "right_sole_link")
GAIN_FEET, GAIN_COM, GAIN_HAND = 10.0, 10.0, 4.9
DT = 1e-3


def urdf_text() -> str:
    hand = (f'<link name="{HAND_FRAME}"/><joint name="{HAND_FRAME}_joint" type="fixed">'
            '<parent link="arm_right_7_link"/><child link="right_hand_point"/><origin xyz="0.1 0 0"/></joint>')
    return fixed_urdf_text("reduced", meshes=False).replace("</robot>", hand + "</robot>")


def urdf_file() -> Path:
    path = Path(tempfile.gettempdir()) / "sotdrake_bench_talos.urdf"
    path.write_text(urdf_text())
    return path


def pinocchio_half_sitting(model) -> np.ndarray:
    """Half-sitting in Pinocchio's coordinates (x, y, z, qx, qy, qz, qw, joints in its order)."""
    talos = load_talos()
    plant = talos.plant
    context = plant.CreateDefaultContext()
    plant.SetPositions(context, talos.half_sitting)
    q = np.zeros(model.nq)
    q[:3] = talos.half_sitting[4:7]
    q[3:7] = [0, 0, 0, 1]
    for j in range(2, model.njoints):
        name = model.names[j]
        if plant.HasJointNamed(name) and model.joints[j].nq == 1:
            q[model.joints[j].idx_q] = plant.GetJointByName(name).get_angle(context)
    return q


def load_compiled_paths() -> None:
    """Load the numba-compiled paths (the solvers', the 6D error, the curvature correction, the
    integration, the joint limits' bounds; or compile them, once after an install) before any timing:
    their first call is not a tick."""
    from sotdrake.configuration import Layout, integrate
    from sotdrake.features.feature6d import pose_error_and_jacobian
    from sotdrake.hqp.equality_hierarchy import solve_equality_hierarchy
    from sotdrake.hqp.solve import HierarchicalQP, LevelRows
    from sotdrake.solvers.limits import VelocityBounds
    from sotdrake.solvers.second_order import curvature_correction

    bounds = np.full(2, -1.0), np.full(2, 1.0)
    HierarchicalQP(2).solve_equalities([np.eye(1, 2)], [np.ones(1)], *bounds)  # the active bounds
    HierarchicalQP(2).solve([LevelRows(np.eye(1, 2), np.zeros(1), np.ones(1))], *bounds)  # a stage: its assembly and active set
    solve_equality_hierarchy([(np.eye(1, 2), np.ones(1))], *bounds)  # SolverDyn's QR path
    pose_error_and_jacobian(np.eye(4), np.zeros((6, 2)), np.eye(4))  # the 6D feature's error
    curvature_correction(np.eye(2), np.zeros(2), np.zeros(2))  # the tick-curvature correction
    talos = load_talos()
    layout = Layout.of(talos.plant)
    integrate(talos.half_sitting, np.zeros(talos.nv), DT, layout)  # the device's integration
    limits = talos.joint_limits()
    VelocityBounds(limits["position_lower"], limits["position_upper"], limits["velocity_lower"], limits["velocity_upper"],
                   layout)(talos.half_sitting, DT, 1e-3)  # the joint limits' velocity bounds
