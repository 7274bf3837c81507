"""Did the robot fall? One criterion for every script's summary (kinematic, physics, dynamic).

The robot *fell* at the first instant ``t`` where one of these holds:

* ``tilt``: its floating base leans more than :data:`FALL_TILT_DEG` (30°) from upright, the angle
  between the base's z axis and the world's, ``arccos(1 − 2(qx² + qy²))`` for Drake's unit
  quaternion ``(qw, qx, qy, qz)``. TALOS standing, swaying or walking stays within 5°, and recovers from pushes that tilt it by 21°;
* ``base drop``: the base is more than :data:`FALL_BASE_DROP_M` (0.25 m) below where it started (a
  15 cm squat stays above it; lying on the ground is about 0.8 m below);
* ``slip``: a sole that should hold slid more than :data:`FALL_SLIP_M` (5 cm) on the ground, in the
  horizontal plane, from where it was when the run started;
* ``contact``: a body other than the soles presses on the ground with more than
  :data:`FALL_CONTACT_FORCE` (10 N: a knee, a hand, the pelvis), when the plant measures it;
* ``non-finite``: the state is not finite any more.

:func:`fall_report` returns ``fell``, ``fell_at_s``, ``fall_reason`` (the first of the reasons
above, in this order, at that instant) and the margins (``max_base_tilt_deg``,
``max_base_drop_m``, and ``max_sole_slip_m`` / ``max_other_contact_n`` when given), the same keys
in every summary.
"""

from __future__ import annotations

import numpy as np

from .exceptions import InvalidInput, all_numbers
from .lie import MIN_QUATERNION_NORM

FALL_TILT_DEG = 30.0  # deg
FALL_BASE_DROP_M = 0.25  # m
FALL_SLIP_M = 0.05  # m
FALL_CONTACT_FORCE = 10.0  # N


def fall_thresholds() -> dict[str, float]:
    """The criterion's thresholds, as a summary records them."""
    return {"fall_tilt_deg": FALL_TILT_DEG, "fall_base_drop_m": FALL_BASE_DROP_M, "fall_slip_m": FALL_SLIP_M,
            "fall_contact_force_n": FALL_CONTACT_FORCE}


def _array(what: str, value, shape: str, ndim: int, last: tuple[int, ...]) -> np.ndarray:
    """``value`` as a float array of ``ndim`` dimensions whose last ones are ``last``, else
    :class:`InvalidInput` naming ``what`` and the ``shape`` expected."""
    try:
        if not all_numbers(value):
            raise TypeError("not numbers")
        array = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise InvalidInput(f"{what}: expected {shape} numbers, got {value!r:.80}") from None
    if array.ndim != ndim or array.shape[1:] != last:
        raise InvalidInput(f"{what}: expected {shape} numbers, got shape {array.shape}")
    return array


def tilt_of_quaternions(quaternion_wxyz: np.ndarray) -> np.ndarray:
    """Tilt (deg) from upright of each row of ``quaternion_wxyz`` (T × 4, Drake's order, normalised
    here): ``arccos(1 − 2(qx² + qy²))``. A finite row of norm below 1e-6 (``lie.MIN_QUATERNION_NORM``) is
    no rotation: :class:`InvalidInput` naming its index. A row that is not finite (a run that
    diverged) gives NaN, which :func:`fall_report` reads as a ``non-finite`` fall."""
    quaternion = _array("tilt_of_quaternions", quaternion_wxyz, "T × 4 (qw, qx, qy, qz)", 2, (4,))
    norm = np.linalg.norm(quaternion, axis=1, keepdims=True)
    finite = np.isfinite(quaternion).all(axis=1)
    small = np.flatnonzero(finite & (norm[:, 0] < MIN_QUATERNION_NORM))
    if small.size:
        raise InvalidInput(f"tilt_of_quaternions: row {int(small[0])} has norm {norm[small[0], 0]:g}, not a rotation "
                           f"(a unit quaternion (qw, qx, qy, qz) is expected): {quaternion[small[0]].tolist()}")
    with np.errstate(invalid="ignore"):  # (the non-finite rows: NaN)
        quaternion = np.where(finite[:, None], quaternion / np.where(finite[:, None], norm, 1.0), np.nan)
        return np.degrees(np.arccos(np.clip(1 - 2 * (quaternion[:, 1] ** 2 + quaternion[:, 2] ** 2), -1, 1)))


def tilt_of_rotations(R_WB: np.ndarray) -> np.ndarray:
    """Tilt (deg) from upright of each rotation matrix of ``R_WB`` (T × 3 × 3, or poses T × 4 × 4):
    ``arccos(R_zz)``."""
    R = np.asarray(R_WB, dtype=float) if all_numbers(R_WB) else None
    if R is None or R.ndim != 3 or R.shape[1:] not in ((3, 3), (4, 4)):
        raise InvalidInput(f"tilt_of_rotations: expected T × 3 × 3 rotations or T × 4 × 4 poses, got {R_WB!r:.80}"
                           if R is None else f"tilt_of_rotations: expected T × 3 × 3 rotations or T × 4 × 4 poses, "
                           f"got shape {R.shape}")
    return np.degrees(np.arccos(np.clip(R[:, 2, 2], -1, 1)))


def fall_report(time: np.ndarray, base_tilt_deg: np.ndarray, base_height: np.ndarray,
                sole_slip: np.ndarray | None = None, other_contact: np.ndarray | None = None) -> dict:
    """The criterion of the module docstring over a run sampled at ``time`` (T, s):
    ``base_tilt_deg`` (T, from :func:`tilt_of_quaternions` or :func:`tilt_of_rotations`),
    ``base_height`` (T, m, world z), optionally ``sole_slip`` (T, m: the largest horizontal
    displacement of a held sole at each instant, 0 for a sole meant to move) and
    ``other_contact`` (T, N). A non-finite sample is a fall (``non-finite``). Series of other
    lengths, or not numbers, or a first sample not finite: :class:`InvalidInput`."""
    time = _array("fall_report: time", time, "T", 1, ())
    series = {"base_tilt_deg": base_tilt_deg, "base_height": base_height, "sole_slip": sole_slip, "other_contact": other_contact}
    arrays = {name: _array(f"fall_report: {name}", value, f"{len(time)} (one per time)", 1, ())
              for name, value in series.items() if value is not None}
    if not len(time) or any(array.shape != time.shape for array in arrays.values()):
        raise InvalidInput(f"fall_report: every series has one sample per time (T = {len(time)} > 0), got "
                           f"{ {name: array.size for name, array in arrays.items()} }")
    tilt_in, height = arrays["base_tilt_deg"], arrays["base_height"]
    finite = np.isfinite(tilt_in) & np.isfinite(height) & np.isfinite(time)
    for name in ("sole_slip", "other_contact"):
        if name in arrays:
            finite &= np.isfinite(arrays[name])
    if not finite[0]:
        raise InvalidInput("fall_report: the run's first sample must be finite")
    tilt = np.where(finite, tilt_in, 0.0)
    drop = np.where(finite, height[0] - height, 0.0)
    reasons = [("non-finite", ~finite), ("tilt", tilt > FALL_TILT_DEG), ("base drop", drop > FALL_BASE_DROP_M)]
    report: dict = {"max_base_tilt_deg": float(tilt.max()), "max_base_drop_m": float(max(0.0, drop.max()))}
    if sole_slip is not None:
        slip = np.where(finite, arrays["sole_slip"], 0.0)
        reasons.append(("slip", slip > FALL_SLIP_M))
        report["max_sole_slip_m"] = float(slip.max())
    if other_contact is not None:
        contact = np.where(finite, arrays["other_contact"], 0.0)
        reasons.append(("contact", contact > FALL_CONTACT_FORCE))
        report["max_other_contact_n"] = float(contact.max())
    fell = np.zeros(len(time), dtype=bool)
    for _, flags in reasons:
        fell |= flags
    if not fell.any():
        return {"fell": False, "fell_at_s": None, "fall_reason": None, **report}
    k = int(np.argmax(fell))
    reason = next(name for name, flags in reasons if flags[k])
    return {"fell": True, "fell_at_s": float(time[k]), "fall_reason": reason, **report}
