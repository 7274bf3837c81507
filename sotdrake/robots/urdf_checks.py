"""Checks of a robot description's text before Drake parses it.

Drake stops the whole process (an assertion, not an exception) on some inconsistent URDFs, e.g. a
joint whose lower position limit is above its upper one. :func:`check_urdf_limits` finds them first
and raises :class:`~sotdrake.exceptions.RobotDescriptionError` naming the joint, the attribute and
the accepted range:

* the text must be well-formed XML with a ``<robot>`` root;
* each ``<limit>`` attribute present (``lower``, ``upper``, ``effort``, ``velocity``) is a number,
  not NaN; ``lower ≤ upper`` (rad or m); ``effort ≥ 0`` (N·m or N) and ``velocity ≥ 0`` (rad/s or m/s).

:func:`check_other_limits` checks an SDF's ``<axis><limit>`` (``lower``, ``upper``) and an MJCF's
``range`` the same way (numbers, not NaN, ``lower ≤ upper``).

:func:`check_masses` checks the masses of a URDF, SDF or MJCF file: finite numbers ≥ 0 (kg); Drake
would take another mass for a negative one, with only a log warning. A zero mass (a massless link)
and an inertia Drake finds non-physical (many robots' files have one) are accepted.
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET

from ..exceptions import RobotDescriptionError


def check_urdf_limits(urdf_text: str, source: str = "URDF") -> None:
    """Raise :class:`RobotDescriptionError` if ``urdf_text`` is not XML or a joint's ``<limit>`` is
    inconsistent (see the module docstring); ``source`` names the file in the message."""
    try:
        root = ET.fromstring(urdf_text)
    except ET.ParseError as error:
        raise RobotDescriptionError(f"{source}: not well-formed XML ({error})") from None
    if root.tag != "robot":
        raise RobotDescriptionError(f"{source}: the root element must be <robot>, got <{root.tag}>")
    for joint in root.iter("joint"):
        limit = joint.find("limit")
        if limit is None:
            continue
        name = joint.get("name", "?")
        values = {}
        for attribute in ("lower", "upper", "effort", "velocity"):
            text = limit.get(attribute)
            if text is None:
                continue
            try:
                values[attribute] = float(text)
            except ValueError:
                raise RobotDescriptionError(f"{source}: joint {name!r}: limit {attribute}={text!r} is not a number") from None
            if math.isnan(values[attribute]):
                raise RobotDescriptionError(f"{source}: joint {name!r}: limit {attribute} is NaN")
        for attribute in ("effort", "velocity"):
            if values.get(attribute, 0.0) < 0:
                raise RobotDescriptionError(
                    f"{source}: joint {name!r}: limit {attribute}={values[attribute]} must be ≥ 0")
        if "lower" in values and "upper" in values and values["lower"] > values["upper"]:
            raise RobotDescriptionError(
                f"{source}: joint {name!r}: limit lower={values['lower']} must be ≤ upper={values['upper']}")


def check_other_limits(root: ET.Element, source: str) -> None:
    """:class:`RobotDescriptionError` naming the joint of an SDF (``root``'s tag ``sdf``) ``<limit>``
    or an MJCF (``mujoco``) ``range`` whose bounds are not numbers, are NaN or are in the wrong order."""
    for joint in root.iter("joint"):
        name = joint.get("name", "?")
        if root.tag == "mujoco":
            if joint.get("range") is not None:
                bounds = _numbers(joint.get("range"), f"{source}: joint {name!r}: range")
                if len(bounds) != 2:
                    raise RobotDescriptionError(f"{source}: joint {name!r}: range = {joint.get('range')!r} must be two numbers")
                _check_order(bounds[0], bounds[1], f"{source}: joint {name!r}: range")
            continue
        for axis in joint:
            for limit in axis.findall("limit") if axis.tag in ("axis", "axis2") else ():
                where = f"{source}: joint {name!r}: <{axis.tag}><limit>"
                lower, upper = (limit.find(side) for side in ("lower", "upper"))
                low = _numbers(lower.text, f"{where} lower") if lower is not None else None
                high = _numbers(upper.text, f"{where} upper") if upper is not None else None
                if low is not None and high is not None:
                    _check_order(low[0], high[0], where)


def check_masses(root: ET.Element, source: str) -> None:
    """:class:`RobotDescriptionError` naming the link (an MJCF body) whose mass is not a finite number
    ≥ 0 (kg): a URDF's ``<inertial><mass value=…>``, an SDF's ``<inertial><mass>``, an MJCF body's
    ``<inertial mass=…>`` or ``<geom mass=…>`` (``root``: the file's root element, ``robot``,
    ``sdf`` or ``mujoco``). Zero is accepted (a massless link)."""
    for link in root.iter("body" if root.tag == "mujoco" else "link"):
        if root.tag == "mujoco":
            masses = [(f" (<{e.tag}>)", e.get("mass")) for e in (*link.findall("inertial"), *link.findall("geom"))]
        else:  # a URDF's <mass value="…"/>, an SDF's <mass>…</mass>
            masses = [("", e.get("value") if root.tag == "robot" else e.text) for e in link.findall("inertial/mass")]
        for where, text in masses:
            if text is None:
                continue
            try:
                mass = float(text)
            except ValueError:
                mass = math.nan
            if not 0.0 <= mass < math.inf:
                kind = "body" if root.tag == "mujoco" else "link"
                raise RobotDescriptionError(f"{source}: {kind} {link.get('name', '?')!r}: mass {text.strip()}{where} must be a "
                                            "finite number ≥ 0 (kg; 0 for a massless link)")


def _numbers(text: str | None, where: str) -> list[float]:
    try:
        numbers = [float(word) for word in (text or "").split()]
    except ValueError:
        numbers = []
    if not numbers or any(math.isnan(x) for x in numbers):
        raise RobotDescriptionError(f"{where} = {text!r} is not a number (or is NaN)")
    return numbers


def _check_order(lower: float, upper: float, where: str) -> None:
    if lower > upper:
        raise RobotDescriptionError(f"{where}: lower = {lower} must be ≤ upper = {upper}")


def positive_lengths(text: str | None) -> bool:
    """True if ``text`` is one or more whitespace-separated positive finite numbers (a shape's sizes,
    m, in a URDF attribute or an SDF element); False for anything else (NaN, a word, nothing)."""
    words = [] if text is None else text.split()
    try:
        return bool(words) and all(0 < float(word) < math.inf for word in words)
    except ValueError:
        return False
