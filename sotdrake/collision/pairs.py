"""Which pairs of collision bodies are checked: the robot's SRDF and its kinematic tree decide.

A pair is named by two body names (the URDF link names, e.g. ``("arm_right_7_link",
"torso_2_link")``) or a link and an obstacle name (:func:`~sotdrake.collision.add_obstacle`). The
self-collision pairs of a robot are every pair of its bodies that carry collision geometry, less

* the pairs its SRDF lists as ``<disable_collisions link1=… link2=…>`` (MoveIt's setup assistant
  writes those that are adjacent, always in contact or never able to touch: example-robot-data
  ships them for its humanoids), and
* the adjacent pairs: a parent and a child body of one joint overlap at the joint by design (Drake
  filters those itself), and any two bodies welded together (through a chain of welds: a reduced
  model's locked gripper links and their wrist) move as one, so their distance never changes and
  no command could change it.
"""

from __future__ import annotations

import itertools
from collections.abc import Iterable
from pathlib import Path

from pydrake.multibody.plant import MultibodyPlant

from ..exceptions import FrameNotFound, InvalidInput
from ..robots.srdf import srdf_root

#: A pair of body (or obstacle) names, in no particular order.
Pair = frozenset[str]


def srdf_disabled_pairs(srdf_path: Path | None) -> set[Pair]:
    """The pairs of links the SRDF's ``<disable_collisions>`` elements exclude (empty without an SRDF)."""
    if srdf_path is None:
        return set()
    root = srdf_root(srdf_path)
    return {frozenset((e.get("link1", ""), e.get("link2", ""))) for e in root.iter("disable_collisions")}


def adjacent_pairs(plant: MultibodyPlant) -> set[Pair]:
    """The (parent, child) body pairs of every joint of ``plant`` (welds included) and every two
    bodies welded together through a chain of welds, the world's bodies aside."""
    world = plant.world_body()
    welded_to_world = {body.name() for body in plant.GetBodiesWeldedTo(world)}
    pairs = set()
    for index in plant.GetJointIndices():
        joint = plant.get_joint(index)
        parent, child = joint.parent_body().name(), joint.child_body().name()
        if world.name() not in (parent, child):
            pairs.add(frozenset((parent, child)))
        if joint.num_velocities() == 0 and child not in welded_to_world:
            group = sorted(body.name() for body in plant.GetBodiesWeldedTo(joint.child_body()))
            pairs.update(frozenset(pair) for pair in itertools.combinations(group, 2))
    return pairs


def check_pairs(pairs: object, links: Iterable[str], obstacles: Iterable[str], adjacent: set[Pair]) -> list[tuple[str, str]]:
    """``pairs`` as a list of ``(name, name)`` after checking each: two names of ``links`` (bodies
    with collision geometry) or of ``obstacles``, not twice the same body, not an adjacent pair, not
    two obstacles, not a pair given before (in either order). Raises
    :class:`~sotdrake.exceptions.FrameNotFound` for an unknown name (listing the names that exist)
    and :class:`~sotdrake.exceptions.InvalidInput` otherwise; nothing is kept."""
    links, obstacles = list(links), list(obstacles)
    known = set(links) | set(obstacles)
    if isinstance(pairs, (str, bytes)) or not isinstance(pairs, Iterable):
        raise InvalidInput(f"pairs must be a list of (link, link) or (link, obstacle) name pairs, got {pairs!r:.100}")
    checked: list[tuple[str, str]] = []
    given: dict[Pair, tuple[str, str]] = {}
    for pair in pairs:
        if isinstance(pair, (str, bytes)) or not isinstance(pair, Iterable) or len(names := tuple(pair)) != 2:
            raise InvalidInput(f"pairs: each pair must be two names, (link, link) or (link, obstacle); got {pair!r:.100}")
        for name in names:
            if not isinstance(name, str) or name not in known:
                raise FrameNotFound(str(name), [*links, *obstacles]).but(f"pairs: {pair!r:.100} names no collision body or obstacle")
        a, b = names
        if a == b:
            raise InvalidInput(f"pairs: ({a!r}, {b!r}) is the same body twice: a body never collides with itself")
        if frozenset(names) in adjacent:
            raise InvalidInput(f"pairs: {a!r} and {b!r} are joined by a joint (they overlap there by design) or welded "
                               "together (their distance never changes): leave this pair out")
        if a in obstacles and b in obstacles:
            raise InvalidInput(f"pairs: ({a!r}, {b!r}) are two obstacles: a pair needs a link of the robot")
        if frozenset(names) in given:
            raise InvalidInput(f"pairs: ({a!r}, {b!r}) is given twice (as {given[frozenset(names)]!r} before)")
        given[frozenset(names)] = (a, b)
        checked.append((a, b))
    if not checked:
        raise InvalidInput("pairs: an empty list checks nothing; give at least one pair, or None for every pair")
    return checked
