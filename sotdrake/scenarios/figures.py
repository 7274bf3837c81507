"""The summary figures of the longer scenario scripts (``talos_dynamics``, ``planche``, ``sot_concept``):
each takes a run's trace and summary and saves one PNG (matplotlib, imported on the first figure)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from sotdrake import save_figure
from sotdrake.dynamics.robot_dyn import RobotDyn
from sotdrake.dynamics.station import sole_rectangle


def support_box(path: dict, sides: list[str], margin_rectangle) -> tuple[np.ndarray, np.ndarray]:
    """The ground-plane box ``(low, high)`` (m, world x, y) around the soles ``sides`` (keys of ``path``, each
    sole's poses; the first is used) at their rectangle ``margin_rectangle`` ``(x_min, x_max, y_min, y_max)``
    (m, sole frame)."""
    x_min, x_max, y_min, y_max = margin_rectangle
    corners = np.array([path[s][0, :3, 3] + path[s][0, :3, :3] @ np.array([x, y, 0.0])
                        for s in sides for x in (x_min, x_max) for y in (y_min, y_max)])
    return corners[:, :2].min(axis=0), corners[:, :2].max(axis=0)


def dynamics_figure(robot: RobotDyn, com0: np.ndarray, trace: dict, summary: dict, path: Path) -> Path:
    """``talos_dynamics``: the CoM from ``com0`` (its initial value) against its reference, the soles'
    normal forces, the CoP in the support box and each joint's torque over its bound, saved to ``path``."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.patches import Rectangle

    t = trace["time"]
    fig, axes = plt.subplots(2, 2, figsize=(13, 8))
    ax = axes[0, 0]
    for i, axis in enumerate("xyz"):
        ax.plot(t, trace["com"][:, i] - com0[i], label=f"CoM {axis}")
        if "com_reference" in trace:
            ax.plot(t, trace["com_reference"][:, i] - com0[i], "--", color=ax.lines[-1].get_color(), label=f"ref {axis}")
    ax.set_ylabel("CoM − initial CoM (m)")
    ax.legend(fontsize=7, ncol=2)
    ax = axes[0, 1]
    if "feet" in trace:
        ax.plot(t, trace["feet"][:, 2], label="left sole (plant)")
        ax.plot(t, trace["feet"][:, 5], label="right sole (plant)")
    ax.plot(t, trace["wrenches"][:, 5], ":", label="left sole (solver)")
    ax.plot(t, trace["wrenches"][:, 11], ":", label="right sole (solver)")
    ax.set_ylabel("normal force (N)")
    ax.legend(fontsize=7)
    ax = axes[1, 0]
    if "feet" in trace:
        nq = robot.model.nq
        poses = robot.dynamic.trajectory(["contactLF", "contactRF"], np.nan_to_num(trace["x"][:1, :nq]))
        low, high = support_box(poses, ["contactLF", "contactRF"], sole_rectangle())
        ax.add_patch(Rectangle(tuple(low), *(high - low), fill=False, color="k", label="support polygon (both soles)"))
        for side in ("contactLF", "contactRF"):
            lo, hi = support_box(poses, [side], sole_rectangle())
            ax.add_patch(Rectangle(tuple(lo), *(hi - lo), fill=False, color="gray", ls=":"))
        ax.plot(trace["feet"][:, 6], trace["feet"][:, 7], ".", ms=1, label="CoP (plant)")
    ax.plot(trace["com"][:, 0], trace["com"][:, 1], "-", lw=0.8, label="CoM (ground projection)")
    ax.set_aspect("equal")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.legend(fontsize=7)
    ax = axes[1, 1]
    ratio = trace["torque"] / robot.sot.effort
    ax.plot(t, ratio, lw=0.6)
    ax.axhline(1, color="r", ls="--")
    ax.axhline(-1, color="r", ls="--")
    scale = robot.sot.effort_scale
    ax.set_ylabel("τ / effort limit (each joint)" if scale == 1 else f"τ / bound (each joint; {scale:g} × effort limit)")
    for a in (axes[0, 0], axes[0, 1], axes[1, 1]):
        a.set_xlabel("time (s)")
    fig.suptitle(f"{summary['scenario']} on {summary['device']}: fell = {summary['fell']}")
    return save_figure(fig, path)


def planche_figure(trace: dict, summary: dict, path: Path, T: dict, support: tuple[float, float, float, float]) -> Path:
    """``planche``: the CoM over the left foot within ``support`` ``(x_min, x_max, y_min, y_max)`` (m, from
    the left ankle), the chest's lean and the right ankle, the task errors and the constraints' margins,
    the sequence's times ``T`` (s) marked; saved to ``path``."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.patches import Rectangle

    t = trace["time"]
    fig, axes = plt.subplots(2, 2, figsize=(13, 8))
    ax = axes[0, 0]
    x_min, x_max, y_min, y_max = support
    ax.add_patch(Rectangle((x_min, y_min), x_max - x_min, y_max - y_min, fill=False, color="k", label="shrunken support (6 × 3 cm)"))
    single = (t >= T["lift"]) & (t < T["contact"])
    ax.plot(trace["com_in_support"][:, 0], trace["com_in_support"][:, 1], lw=0.6, color="0.6", label="CoM, whole run")
    ax.plot(trace["com_in_support"][single, 0], trace["com_in_support"][single, 1], lw=1.2, label="CoM, on the left foot")
    ax.set_xlim(-0.06, 0.06)
    ax.set_ylim(-0.12, 0.03)
    ax.set_aspect("equal")
    ax.set_xlabel("x − left ankle x (m)")
    ax.set_ylabel("y − left ankle y (m)")
    ax.set_title("CoM over the left foot (ground projection)")
    ax.legend(fontsize=7)
    ax = axes[0, 1]
    ax.plot(t, np.degrees(trace["chest_lean"]), label="chest lean from vertical (°)")
    ax.plot(t, trace["right_ankle"][:, 0] * 100, label="right ankle x (cm)")
    ax.plot(t, trace["right_ankle"][:, 2] * 100, label="right ankle z (cm)")
    ax.set_ylabel("° or cm")
    ax.set_title("the planche")
    ax.legend(fontsize=7)
    ax = axes[1, 0]
    for name in sorted(k for k in trace if k.startswith("error_")):
        ax.semilogy(t, np.maximum(trace[name][:, 0], 1e-12), label=f"‖e‖ {name[6:]}")
    ax.set_ylabel("task error norm (m, rad or both)")
    ax.set_title("task errors (the inequality's: distance to its reference)")
    ax.legend(fontsize=7, ncol=2)
    ax = axes[1, 1]
    ax.plot(t, trace["com_margin"] * 100, label="CoM margin in the shrunken support (cm)")
    ax.plot(t, np.degrees(trace["joint_limit_margin"]), label="min joint-limit margin (°)")
    ax.plot(t, trace["left_ankle_drift"] * 1000, label="left ankle drift (mm)")
    ax.axhline(0, color="r", lw=0.8, ls="--")
    ax.set_ylabel("cm, ° or mm")
    ax.set_title("constraints")
    ax.legend(fontsize=7)
    for a in (axes[0, 1], axes[1, 0], axes[1, 1]):
        a.set_xlabel("time (s)")
        for when in T.values():
            if when <= t[-1]:
                a.axvline(when, color="0.8", lw=0.6)
    fig.suptitle(f"planche on Romeo ({summary['solver']}): chest lean up to {summary['max_chest_lean_deg']:.0f}°, "
                 f"CoM within {-(summary['min_com_margin_single_support_m'] or 0) * 1e3:.4f} mm of the shrunken support on one foot")
    return save_figure(fig, path)


def concept_figure(traces: dict[str, dict], path: Path, robot_name: str = "talos") -> Path:
    """``sot_concept``: per configuration (``traces``, by name), the hand's distance to the ball, the CoM's
    margin in the support polygon, the joints' velocity ratio and joint-limit margin; saved to ``path``."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(2, 2, figsize=(12, 8), sharex=True)
    for name, trace in traces.items():
        t = trace["time"]
        axes[0, 0].semilogy(t, np.maximum(trace["hand_error"], 1e-16), label=name)
        axes[0, 1].plot(t, trace["com_support_margin"], label=name)
        axes[1, 0].semilogy(t, np.maximum(trace["velocity_ratio"], 1e-16), label=name)
        axes[1, 1].plot(t, trace["min_margin"], label=name)
    axes[0, 0].set_ylabel("hand to ball (m)")
    axes[0, 1].set_ylabel("CoM margin in the support polygon (m)")
    axes[0, 1].axhline(0.0, color="grey", ls=":")
    axes[1, 0].set_ylabel("max |v| / velocity limit")
    axes[1, 0].axhline(1.0, color="grey", ls=":")
    axes[1, 1].set_ylabel("min joint-limit margin (rad)")
    axes[1, 1].axhline(0.0, color="grey", ls=":")
    for axis in axes[1]:
        axis.set_xlabel("time (s)")
    axes[0, 0].legend(fontsize=7)
    fig.suptitle(f"sot-concept on {'TALOS' if robot_name == 'talos' else 'Romeo'}: the right hand grasps a ball")
    return save_figure(fig, path)
