"""What touches the ground: the force on each sole, the centre of pressure, and any other link."""

from __future__ import annotations

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.multibody.plant import ContactResults
from pydrake.systems.framework import Context, LeafSystem, ValueProducer


class ContactMonitor(LeafSystem):
    """From the plant's contact results: output ``feet`` = ``(f_left (3), f_right (3), cop (2))``,
    the total contact force on each sole (N, world) and the centre of pressure of the soles' contacts
    on the ground (z = 0): with each contact's force ``f`` at point ``c`` and moment ``τ`` about it,
    ``cop = (Σ c_x f_z - τ_y, Σ c_y f_z + τ_x) / Σ f_z`` (m; NaN when nothing touches). Output
    ``other_contact`` (1-vector): the normal force (N) on every body that is not a sole (a knee, a
    hand, the pelvis on the ground: the robot fell).

    Input: ``contact_results`` (the plant's ``ContactResults``).
    """

    def __init__(self, robot, name: str = "contact_monitor"):
        LeafSystem.__init__(self)
        self.set_name(name)
        plant = robot.plant
        # A foot: the sole's body and every link welded to it.
        self._bodies = {side: {b.index() for b in plant.GetBodiesWeldedTo(frame.body())}
                        for side, frame in robot.sole_frames.items()}
        self._world = plant.world_body().index()
        # Each foot body → the offset of its side's force in the summary (a body welded to both
        # soles counts for the first, as before).
        self._side_of = {}
        for offset, side in ((3, "right"), (0, "left")):
            self._side_of.update(dict.fromkeys(self._bodies[side], offset))
        inspector = robot.scene_graph.model_inspector()
        self._geometry_bodies = {
            geometry: plant.GetBodyFromFrameId(inspector.GetFrameId(geometry)).index()
            for geometry in inspector.GetAllGeometryIds()
            if plant.GetBodyFromFrameId(inspector.GetFrameId(geometry)) is not None
        }
        self.contact_results = self.DeclareAbstractInputPort("contact_results", AbstractValue.Make(ContactResults()))
        self._results = self.DeclareCacheEntry(
            "contact_summary", ValueProducer(allocate=lambda: AbstractValue.Make(np.zeros(9)), calc=self._summarize),
            prerequisites_of_calc={self.input_port_ticket(self.contact_results.get_index())},
        )
        self.DeclareVectorOutputPort("feet", 8, lambda c, o: o.SetFromVector(self._results.Eval(c)[:8]))
        self.DeclareVectorOutputPort("other_contact", 1, lambda c, o: o.SetAtIndex(0, self._results.Eval(c)[8]))

    def _summarize(self, context: Context, value: AbstractValue) -> None:
        results = self.contact_results.Eval(context)
        out = [0.0] * 9  # f_left, f_right, (Σ c_x f_z − τ_y, Σ c_y f_z + τ_x), Σ f_z, other
        side_of, world = self._side_of, self._world

        def add(body_a, body_b, force, torque, point) -> None:
            fx, fy, fz = force
            side, sign = side_of.get(body_a), 1.0
            if side is None:
                side, sign = side_of.get(body_b), -1.0
            if side is not None:  # the force on the foot
                fx, fy, fz = sign * fx, sign * fy, sign * fz
                out[side] += fx
                out[side + 1] += fy
                out[side + 2] += fz
                if torque is not None:
                    out[6] += point[0] * fz - sign * torque[1]
                    out[7] += point[1] * fz + sign * torque[0]
                else:
                    out[6] += point[0] * fz
                    out[7] += point[1] * fz
                out[8] += fz
            elif world in (body_a, body_b):
                other[0] += abs(fz)

        other = [0.0]
        for i in range(results.num_hydroelastic_contacts()):
            info = results.hydroelastic_contact_info(i)
            surface = info.contact_surface()
            F = info.F_Ac_W()  # on the body of geometry M, at the surface's centroid
            add(self._geometry_bodies[surface.id_M()], self._geometry_bodies[surface.id_N()],
                F.translational().tolist(), F.rotational().tolist(), surface.centroid().tolist())
        for i in range(results.num_point_pair_contacts()):
            info = results.point_pair_contact_info(i)  # force on body B at the contact point
            add(info.bodyB_index(), info.bodyA_index(), info.contact_force().tolist(), None, info.contact_point().tolist())
        total = out[8]
        cop = [out[6] / total, out[7] / total] if total > 1e-9 else [np.nan, np.nan]
        value.set_value(np.array([*out[:6], *cop, other[0]]))
