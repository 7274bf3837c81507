"""The robots :func:`sotdrake.robots.load_robot` knows: where their files are, their variants, base,
reference posture and operational points.

Every robot comes from the example-robot-data wheel (``share/example-robot-data/robots/``).
Operational points (sot-core's ``robot.OperationalPointsMap``) map the seed's names to a joint
(the op point is the joint's child frame, as in sot-dynamic) or to a frame of the model:
``left-wrist``, ``right-wrist``, ``left-ankle``, ``right-ankle``, ``gaze``, ``waist``, ``chest``
for the humanoids (Romeo's are sot-romeo's), ``left-sole``/``right-sole`` where the model has soles;
``wrist`` and ``tool`` for a single arm; ``waist`` and the four feet for a quadruped.
``waist`` → ``root_joint`` names the floating base body (sot-talos' name of the free flyer).
"""

from __future__ import annotations

from dataclasses import dataclass, field

#: How the robot's root link is attached to the world.
#: ``free``: a 6-DOF floating base, ``q = (qw, qx, qy, qz, x, y, z)``, ``v = (ω_WB, v_WB)`` in world;
#: ``planar``: a ``PlanarJoint`` named ``root_joint``, ``q = (x, y, θ)``, ``v = (ẋ, ẏ, θ̇)`` in world;
#: ``fixed``: welded at the world origin.
BASES = ("free", "planar", "fixed")


@dataclass(frozen=True)
class RobotSpec:
    """What the loader needs to know about one robot of example-robot-data."""

    name: str
    kind: str  #: ``humanoid``, ``mobile manipulator``, ``arm`` or ``quadruped``
    package: str  #: directory under ``robots/``
    urdf_dir: str  #: directory of the URDFs under the package
    variants: dict[str, str]  #: variant → URDF file name; the first is the default
    base: str  #: the default base (one of :data:`BASES`)
    bases: tuple[str, ...]  #: the bases offered
    op_points: dict[str, str]
    srdf: str | dict[str, str] | None = None  #: SRDF file under ``srdf/`` (per variant if a dict)
    posture: tuple[str, ...] = ()  #: SRDF ``group_state`` names, applied in order
    soles: tuple[str, ...] = ()  #: frames put on the ground (z = 0) when the SRDF has no base pose
    fixed_base_variants: tuple[str, ...] = ()  #: variants welded whatever the robot's base
    #: sole op point → its contact rectangle ``(x_min, x_max, y_min, y_max)`` (m, in the sole frame),
    #: for the dynamic SoT's 6D contacts (TALOS' is the physics plant's sole box)
    sole_rectangles: dict[str, tuple[float, float, float, float]] = field(default_factory=dict)
    notes: str = ""

    @property
    def default_variant(self) -> str:
        return next(iter(self.variants))

    def srdf_file(self, variant: str) -> str | None:
        return self.srdf.get(variant) if isinstance(self.srdf, dict) else self.srdf


#: TALOS' gripper joints. Both start on their upper limit (0) in half-sitting, and the tutorial
#: leaves them out of the whole-body control: ``sot.setControlSelection(robot.velocity_selection(
#: excluding=TALOS_GRIPPERS))``.
TALOS_GRIPPERS: tuple[str, ...] = ("gripper_left_joint", "gripper_right_joint")

_HUMANOID_BASES = ("free", "fixed")
_QUADRUPED_FEET = {"front-left-foot": "FL", "front-right-foot": "FR", "hind-left-foot": "HL", "hind-right-foot": "HR"}


def _quadruped_feet(pattern: str, letters: dict[str, str] | None = None) -> dict[str, str]:
    """Foot op points from a frame-name pattern such as ``'{}_FOOT'`` (``{}``: FL, FR, HL, HR)."""
    letters = letters or {}
    return {name: pattern.format(letters.get(leg, leg)) for name, leg in _QUADRUPED_FEET.items()}


ROBOTS: dict[str, RobotSpec] = {
    spec.name: spec
    for spec in [
        RobotSpec(
            name="talos",
            kind="humanoid",
            package="talos_data",
            urdf_dir="robots",
            variants={"reduced": "talos_reduced.urdf", "full_v2": "talos_full_v2.urdf", "left_arm": "talos_left_arm.urdf"},
            base="free",
            bases=_HUMANOID_BASES,
            fixed_base_variants=("left_arm",),
            srdf="talos.srdf",
            posture=("half_sitting",),
            op_points={
                "left-wrist": "arm_left_7_joint",
                "right-wrist": "arm_right_7_joint",
                "left-ankle": "leg_left_6_joint",
                "right-ankle": "leg_right_6_joint",
                "gaze": "head_2_joint",
                "waist": "root_joint",
                "chest": "torso_2_joint",
                "left-sole": "left_sole_link",
                "right-sole": "right_sole_link",
            },
            notes="PAL Robotics; sot-talos' op points",
        ),
        RobotSpec(
            name="romeo",
            kind="humanoid",
            package="romeo_description",
            urdf_dir="urdf",
            variants={"full": "romeo.urdf", "small": "romeo_small.urdf"},
            base="free",
            bases=_HUMANOID_BASES,
            srdf={"full": "romeo.srdf", "small": "romeo_small.srdf"},
            posture=("half_sitting",),
            soles=("l_sole", "r_sole"),
            op_points={
                "left-wrist": "LWristPitch",
                "right-wrist": "RWristPitch",
                "left-ankle": "LAnkleRoll",
                "right-ankle": "RAnkleRoll",
                "gaze": "HeadRoll",
                "waist": "root_joint",
                "chest": "TrunkYaw",
                "left-sole": "l_sole",
                "right-sole": "r_sole",
            },
            # sot-dyninv's supports for Romeo (ros-dynromeo.py), inside the foot's collision mesh
            # (x from -0.089 to 0.155 m, y from -0.056 m inside to 0.071 m outside)
            sole_rectangles={"left-sole": (-0.08, 0.11, -0.045, 0.07), "right-sole": (-0.08, 0.11, -0.07, 0.045)},
            notes="Aldebaran; sot-romeo's op points; `full` has the 22 finger joints",
        ),
        RobotSpec(
            name="icub",
            kind="humanoid",
            package="icub_description",
            urdf_dir="robots",
            variants={"full": "icub.urdf", "reduced": "icub_reduced.urdf"},
            base="free",
            bases=_HUMANOID_BASES,
            srdf="icub.srdf",
            posture=("half_sitting",),
            soles=("l_sole", "r_sole"),
            op_points={
                "left-wrist": "l_wrist_yaw",
                "right-wrist": "r_wrist_yaw",
                "left-ankle": "l_ankle_roll",
                "right-ankle": "r_ankle_roll",
                "gaze": "neck_yaw",
                "waist": "root_joint",
                "chest": "torso_yaw",
                "left-sole": "l_sole",
                "right-sole": "r_sole",
            },
            notes="IIT; `reduced` has the neck fixed",
        ),
        RobotSpec(
            name="g1",
            kind="humanoid",
            package="g1_description",
            urdf_dir="urdf",
            variants={"29dof": "g1_29dof_rev_1_0.urdf", "29dof_with_hand": "g1_29dof_with_hand_rev_1_0.urdf"},
            base="free",
            bases=("free",),
            soles=("left_ankle_roll_link", "right_ankle_roll_link"),
            op_points={
                "left-wrist": "left_wrist_yaw_joint",
                "right-wrist": "right_wrist_yaw_joint",
                "left-ankle": "left_ankle_roll_joint",
                "right-ankle": "right_ankle_roll_joint",
                "gaze": "d435_joint",
                "waist": "pelvis",
                "chest": "waist_pitch_joint",
            },
            notes="Unitree; no SRDF: all joints at 0, ankles on the ground; `gaze` is the D435 head camera",
        ),
        RobotSpec(
            name="pr2",
            kind="mobile manipulator",
            package="pr2_description",
            urdf_dir="urdf",
            variants={"default": "pr2.urdf"},
            base="planar",
            bases=("planar", "free", "fixed"),
            srdf="pr2.srdf",
            posture=("tuck_left_arm", "tuck_right_arm"),
            op_points={
                "left-wrist": "l_wrist_roll_joint",
                "right-wrist": "r_wrist_roll_joint",
                "left-gripper": "l_gripper_tool_frame",
                "right-gripper": "r_gripper_tool_frame",
                "gaze": "head_tilt_joint",
                "waist": "base_link",
                "chest": "torso_lift_joint",
            },
            notes="Willow Garage; casters and wheels are joints of their own (leave them out of the control)",
        ),
        RobotSpec(
            name="tiago",
            kind="mobile manipulator",
            package="tiago_description",
            urdf_dir="robots",
            variants={"default": "tiago.urdf", "no_hand": "tiago_no_hand.urdf"},
            base="planar",
            bases=("planar", "free", "fixed"),
            op_points={
                "wrist": "arm_7_joint",
                "tool": "arm_tool_link",
                "gaze": "head_2_joint",
                "waist": "base_link",
                "chest": "torso_lift_joint",
            },
            notes="PAL Robotics; `default` has the five-finger hand",
        ),
        *[
            RobotSpec(
                name=f"ur{size}",
                kind="arm",
                package="ur_description",
                urdf_dir="urdf",
                variants={
                    "default": f"ur{size}_robot.urdf",
                    "limited": f"ur{size}_joint_limited_robot.urdf",
                    **({"gripper": f"ur{size}_gripper.urdf"} if size != 10 else {}),
                },
                base="fixed",
                bases=("fixed",),
                op_points={"wrist": "wrist_3_joint", "tool": "tool0"},
                notes="Universal Robots; all joints at 0 (no SRDF posture)",
            )
            for size in (3, 5, 10)
        ],
        RobotSpec(
            name="panda",
            kind="arm",
            package="panda_description",
            urdf_dir="urdf",
            variants={"default": "panda.urdf"},
            base="fixed",
            bases=("fixed",),
            srdf="panda.srdf",
            posture=("default",),
            op_points={"wrist": "panda_joint7", "tool": "panda_hand_tcp"},
            notes="Franka Emika",
        ),
        RobotSpec(
            name="z1",
            kind="arm",
            package="z1_description",
            urdf_dir="urdf",
            variants={"default": "z1.urdf"},
            base="fixed",
            bases=("fixed",),
            srdf="z1.srdf",
            posture=("arm_up",),
            op_points={"wrist": "joint6", "tool": "gripperStator"},
            notes="Unitree",
        ),
        RobotSpec(
            name="anymal",
            kind="quadruped",
            package="anymal_b_simple_description",
            urdf_dir="robots",
            variants={"default": "anymal.urdf"},
            base="free",
            bases=("free",),
            srdf="anymal.srdf",
            posture=("standing",),
            op_points={"waist": "root_joint", **_quadruped_feet("{}_FOOT", {"FL": "LF", "FR": "RF", "HL": "LH", "HR": "RH"})},
            notes="ANYbotics ANYmal B",
        ),
        RobotSpec(
            name="go1",
            kind="quadruped",
            package="go1_description",
            urdf_dir="urdf",
            variants={"default": "go1.urdf"},
            base="free",
            bases=("free",),
            srdf="go1.srdf",
            posture=("standing",),
            op_points={"waist": "root_joint", **_quadruped_feet("{}_foot", {"HL": "RL", "HR": "RR"})},
            notes="Unitree",
        ),
        RobotSpec(
            name="solo12",
            kind="quadruped",
            package="solo_description",
            urdf_dir="robots",
            variants={"default": "solo12.urdf"},
            base="free",
            bases=("free",),
            srdf="solo.srdf",
            posture=("standing",),
            op_points={"waist": "root_joint", **_quadruped_feet("{}_FOOT")},
            notes="ODRI",
        ),
    ]
}
