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
    hand, the pelvis on the ground: the robot fell)."""

    def __init__(self, robot, name: str = "contact_monitor"):
        LeafSystem.__init__(self)
        self.set_name(name)
        plant = robot.plant
        # A foot: the sole's body and every link welded to it.
        self._bodies = {side: {b.index() for b in plant.GetBodiesWeldedTo(frame.body())}
                        for side, frame in robot.sole_frames.items()}
        self._world = plant.world_body().index()
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
        forces = {"left": np.zeros(3), "right": np.zeros(3)}
        moment, total = np.zeros(2), 0.0
        other = 0.0
        soles = set().union(*self._bodies.values())

        def add(body_a, body_b, force, torque, point):
            nonlocal total, other
            for side, bodies in self._bodies.items():
                sign = 1.0 if body_a in bodies else -1.0 if body_b in bodies else 0.0
                if sign:  # the force on the foot
                    f, tau = sign * force, sign * torque
                    forces[side] += f
                    moment[:] += [point[0] * f[2] - tau[1], point[1] * f[2] + tau[0]]
                    total += f[2]
            if body_a not in soles and body_b not in soles and self._world in (body_a, body_b):
                other += abs(force[2])

        for i in range(results.num_hydroelastic_contacts()):
            info = results.hydroelastic_contact_info(i)
            surface = info.contact_surface()
            F = info.F_Ac_W()  # on the body of geometry M, at the surface's centroid
            body_m, body_n = self._geometry_bodies[surface.id_M()], self._geometry_bodies[surface.id_N()]
            add(body_m, body_n, F.translational(), F.rotational(), surface.centroid())
        for i in range(results.num_point_pair_contacts()):
            info = results.point_pair_contact_info(i)  # force on body B at the contact point
            add(info.bodyB_index(), info.bodyA_index(), info.contact_force(), np.zeros(3), info.contact_point())
        cop = moment / total if total > 1e-9 else np.full(2, np.nan)
        value.set_value(np.concatenate([forces["left"], forces["right"], cop, [other]]))
