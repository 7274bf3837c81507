"""A diagram's floor: its twin whose Python callbacks do no maths.

``twin(diagram, context)`` rebuilds ``diagram`` system by system. Each of sotdrake's systems (a
Python ``LeafSystem``) becomes a twin with the same input and output ports (the same names, sizes
and value types), the same direct feedthrough, the same discrete state groups and the same
periodic discrete update: its output callbacks evaluate the inputs that output reads through and
set the value the real system gave at ``context`` (precomputed once), and its updates evaluate
every connected input and keep the state. Drake's own systems (trajectory sources, multiplexers,
log sinks) are cloned as they are. The wiring is the diagram's.

Ticking the twin with ``Simulator.AdvanceTo`` costs what Drake's port evaluations, caching, events
and Python callbacks cost for that exact graph before any maths: no tick of the real diagram can go
below it. ``bench/floor.py`` builds the same kind of floor for the basic stack from a synthetic
topology; this module takes any built diagram (e.g. the dynamic SoT's).
"""

from __future__ import annotations

from pydrake.systems.framework import Context, Diagram, DiagramBuilder, InputPortIndex, LeafSystem, PortDataType, System


def _is_python_system(system: System) -> bool:
    return isinstance(system, LeafSystem) and type(system).__module__.split(".")[0] != "pydrake"


class _Twin(LeafSystem):
    """The ports, feedthrough, discrete state and periodic discrete update of ``real``, with
    callbacks that evaluate their inputs and set ``real``'s values at ``real_context``."""

    def __init__(self, real: LeafSystem, real_context: Context, connected: set[int], calls: dict | None = None):
        super().__init__()
        self._calls = calls
        self.set_name(real.get_name())
        self._connected = sorted(connected)
        for i in range(real.num_input_ports()):
            port = real.get_input_port(i)
            if port.get_data_type() == PortDataType.kVectorValued:
                self.DeclareVectorInputPort(port.get_name(), port.size())
            else:
                self.DeclareAbstractInputPort(port.get_name(), port.Allocate())
        for o in range(real.num_output_ports()):
            self._declare_output(real, real_context, o)
        groups = real_context.num_discrete_state_groups()
        for g in range(groups):
            self.DeclareDiscreteState(real_context.get_discrete_state(g).get_value().copy())
        attribute = real.GetUniquePeriodicDiscreteUpdateAttribute() if groups else None
        if attribute is not None:
            self.DeclarePeriodicDiscreteUpdateEvent(attribute.period_sec(), attribute.offset_sec(), self._update)

    def _declare_output(self, real: LeafSystem, real_context: Context, o: int) -> None:
        port, key = real.get_output_port(o), (real.get_name(), o)
        reads = [i for i in self._connected if real.HasDirectFeedthrough(i, o)]
        tickets = {self.all_sources_except_input_ports_ticket()} | {self.input_port_ticket(InputPortIndex(i)) for i in reads}
        inputs = [self.get_input_port(i) for i in reads]
        vector = port.get_data_type() == PortDataType.kVectorValued
        value = port.Eval(real_context).copy() if vector else port.EvalAbstract(real_context).Clone()
        content = value if vector else value.get_value()

        def calc(context, output, inputs=inputs, content=content, key=key, vector=vector):
            if self._calls is not None:
                self._calls[key] = self._calls.get(key, 0) + 1
            for p in inputs:
                p.Eval(context)
            if vector:
                output.SetFromVector(content)
            else:
                output.set_value(content)

        if vector:
            self.DeclareVectorOutputPort(port.get_name(), port.size(), calc, prerequisites_of_calc=tickets)
        else:
            self.DeclareAbstractOutputPort(port.get_name(), lambda value=value: value.Clone(), calc, prerequisites_of_calc=tickets)

    def _update(self, context, discrete_state) -> None:
        for i in self._connected:
            self.get_input_port(i).Eval(context)
        for g in range(context.num_discrete_state_groups()):
            discrete_state.get_mutable_vector(g).SetFromVector(context.get_discrete_state(g).get_value())


def twin(diagram: Diagram, context: Context, calls: dict | None = None) -> Diagram:
    """The floor's twin of ``diagram`` (see the module docstring), its values taken at ``context``
    (a context of ``diagram``, e.g. after ``Simulator.Initialize``). Exported ports are not kept.
    ``calls``: a dict in which each twin output's calls are counted, keyed by (system, port index)."""
    connections = diagram.connection_map()
    connected: dict[System, set[int]] = {}
    for (system, i), _ in connections.items():
        connected.setdefault(system, set()).add(int(i))
    builder = DiagramBuilder()
    twins: dict[System, System] = {}
    for system in diagram.GetSystems():
        if _is_python_system(system):
            sub = diagram.GetSubsystemContext(system, context)
            twins[system] = builder.AddSystem(_Twin(system, sub, connected.get(system, set()), calls))
        else:
            clone = system.Clone()
            clone.set_name(system.get_name())
            twins[system] = builder.AddSystem(clone)
    for (system, i), (source, o) in connections.items():
        builder.Connect(twins[source].get_output_port(int(o)), twins[system].get_input_port(int(i)))
    return builder.Build()
