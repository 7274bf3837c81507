"""``SolverDyn``'s contacts: one input per declared :class:`~.contact.Contact6d` (``contact<name>``,
its :class:`~.contact.ContactRows`), the commands that hold and release them (the contact set and
the release durations are settings, in the solver's Context), and the contacts in force at a tick
(a released contact's normal force ramps to 0: :mod:`.contact_memory` keeps the ramp)."""

from __future__ import annotations

import logging
from typing import Any

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.systems.framework import Context, InputPort

from ..exceptions import InvalidInput, StackError, check_number
from .checks import MAX_RELEASE, unconnected_input
from .contact import Contact6d, ContactRows
from .contact_memory import ContactMemory
from .dyn_types import ContactNotFound, DynSettings
from .formulation import ActiveContact

log = logging.getLogger("sotdrake.solver_dyn")


class DynContacts:
    """The contacts of ``system`` (a ``SolverDyn``, ``nv`` velocities, at most ``max_contacts``)."""

    def __init__(self, system: Any, nv: int, max_contacts: int):
        self.system, self.nv, self.max_contacts = system, nv, max_contacts
        self.ports: dict[str, InputPort] = {}
        self.index: dict[str, int] = {}  # the declaration order of the contacts
        self.contacts: dict[str, Contact6d] = {}  # the contact entity read by each port

    @property
    def name(self) -> str:
        return self.system.name

    def declare_input(self, contact: Contact6d) -> InputPort:
        """The input port of ``contact`` (its ``contact`` output goes there)."""
        if contact.name in self.ports:
            return self.ports[contact.name]
        if len(self.ports) == self.max_contacts:
            raise InvalidInput(f"{self.name} was built for {self.max_contacts} contacts (max_contacts)")
        if contact.nv != self.nv:
            raise InvalidInput(f"contact {contact.name} has nv = {contact.nv}, solver {self.name} has nv = {self.nv}")
        port = self.system.DeclareAbstractInputPort(
            "contact" + contact.name if not contact.name.startswith("contact") else contact.name,
            AbstractValue.Make(ContactRows(np.zeros((6, self.nv)), np.zeros(6), np.eye(3), np.zeros((0, 6)), 0.0, 1.0)),
        )
        self.index[contact.name] = len(self.ports)
        self.ports[contact.name] = port
        self.contacts[contact.name] = contact
        return port

    def name_of(self, contact: object) -> str:
        """The declared contact's name of a name or a :class:`~.contact.Contact6d`, which must be
        the one this solver reads (not another robot's contact of the same name)."""
        name = getattr(contact, "name", contact)
        if not isinstance(name, str) or name not in self.ports:
            raise ContactNotFound(name if isinstance(name, str) else repr(name), list(self.ports))
        if not isinstance(contact, str) and self.contacts[name] is not contact:
            raise StackError(f"{self.name}: the contact {name!r} given is not the one this solver reads (a contact of "
                             "another robot or diagram?): give this robot's contact, or its name")
        return name

    def names_of(self, what: str, names: object) -> list[str]:
        """``names`` as a list if it is a list (or tuple) of declared contacts' names: a string or
        another value is an :class:`InvalidInput`, an unknown name a :class:`ContactNotFound` naming it."""
        if isinstance(names, (str, bytes)) or not isinstance(names, (list, tuple)):
            raise InvalidInput(f"{self.name}.{what}: names must be a list of contact names, got {names!r:.60}")
        for name in names:
            if not isinstance(name, str) or name not in self.ports:
                raise ContactNotFound(name if isinstance(name, str) else repr(name), list(self.ports))
        return list(names)

    def raise_if_unconnected(self, error: RuntimeError) -> None:
        """A :class:`StackError` naming the input of the solver that Drake's ``error`` says is not
        connected (``dynamics``, or a contact's) and what to connect to it; nothing for another error."""
        port = unconnected_input(error, self.name)
        if port == "dynamics":
            raise StackError(f"{self.name}: its input 'dynamics' is not connected: connect the dynamic entity's output to "
                             "it, builder.Connect(dynamic.GetOutputPort('dynamics'), sot.GetInputPort('dynamics')), or "
                             "build the robot with RobotDyn, which does") from None
        contact = next((name for name, p in self.ports.items() if p.get_name() == port), None)
        if contact is not None:
            raise StackError(f"{self.name}: the input {port!r} of the contact {contact!r} is not connected: connect the "
                             "contact's output to it, builder.Connect(contact.GetOutputPort('contact'), "
                             "sot.declare_contact_input(contact)), or make the contact with RobotDyn.add_contact, which "
                             "does") from None

    def addContact(self, contact: object, context: Context | None = None, priority: str = "top") -> None:
        """Hold ``contact`` (a name or a :class:`~.contact.Contact6d`); a contact being released is
        held again. A dynamic contact is a constraint of every level: ``priority`` is ``"top"`` only."""
        if priority != "top":
            raise InvalidInput(f"{self.name}.addContact: a dynamic contact constrains every level (priority 'top'), "
                               f"got priority={priority!r}")
        name = self.name_of(contact)

        def change(s: DynSettings) -> None:
            if name in s.contacts and name not in s.releasing:
                raise StackError(f"{self.name}.addContact: {name!r} is already a contact")
            s.releasing.pop(name, None)
            s.release_numbers.pop(name, None)
            if name not in s.contacts:
                s.contacts.append(name)

        self.system._command(context, change)

    def rmContact(self, contact: object, duration: float = 0.3, context: Context | None = None) -> None:
        """Release ``contact``: its normal force ramps to 0 over ``duration`` s (≥ 0), then it is
        removed. Removing the last held contact is refused."""
        name = self.name_of(contact)
        duration = check_number(f"{self.name}.rmContact: duration", duration, 0.0, MAX_RELEASE, " s")

        def change(s: DynSettings) -> None:
            held = [c for c in s.contacts if c not in s.releasing]
            if name not in held:
                raise StackError(f"{self.name}.rmContact: {name!r} is not a held contact {held}")
            if len(held) == 1:
                raise StackError(f"{self.name}.rmContact: {name!r} is the last contact; the robot would lose its support")
            if duration == 0:
                log.warning("%s.rmContact(%r, 0): released at once, its load drops in one tick (the robot may tip); "
                            "give a duration > 0 to ramp its force down", self.name, name)
                s.contacts.remove(name)
            else:
                s.releases += 1
                s.releasing[name], s.release_numbers[name] = float(duration), s.releases

        self.system._command(context, change)

    def active(self, context: Context, s: DynSettings, memory: ContactMemory) -> list[ActiveContact]:
        """The held contacts, and the released ones whose ramp has not ended (with their bound)."""
        out = []
        for name in s.contacts:
            f_max, fraction = np.inf, 1.0
            if name in s.releasing:
                t0, f0 = memory.ramp(context, self.index[name])
                if not np.isnan(t0):
                    fraction = 1.0 - (context.get_time() - t0) / s.releasing[name]
                    if fraction <= 1e-9:
                        continue  # released: the foot is free
                    f_max = max(0.0, f0 * fraction)
            rows = self.ports[name].Eval(context)
            out.append(ActiveContact(name, rows, f_max, rows.f_min * fraction))
        return out
