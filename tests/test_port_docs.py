"""Every public ``LeafSystem`` of sotdrake states its ports in its docstring, as Drake's systems
do: each port name it declares (a literal name; ports named after a task or an op point aside)
appears, in double backquotes, in the docstring of the class, or of the class that declares it."""

from __future__ import annotations

import ast
import importlib
import importlib.util
import inspect
import pkgutil
import re
import textwrap

import pytest
from pydrake.systems.framework import LeafSystem

import sotdrake

DECLARE = re.compile(r"Declare\w*(Input|Output)Port$")


def declared_ports(cls: type) -> set[str]:
    """The literal names of the ports ``cls``'s own code declares."""
    tree = ast.parse(textwrap.dedent(inspect.getsource(cls)))
    names = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute) and DECLARE.search(node.func.attr):
            if node.args and isinstance(node.args[0], ast.Constant) and isinstance(node.args[0].value, str):
                names.add(node.args[0].value)
    return names


# Subpackages that need an optional extra: read only where the extra is installed.
OPTIONAL = {"sotdrake.ros": "rclpy"}


def public_systems() -> dict[str, type]:
    systems = {}
    for module in pkgutil.walk_packages(sotdrake.__path__, "sotdrake."):
        if module.name.endswith("__main__"):
            continue
        if any(module.name.startswith(package) and importlib.util.find_spec(needs) is None
               for package, needs in OPTIONAL.items()):
            continue
        for name, value in vars(importlib.import_module(module.name)).items():
            if (inspect.isclass(value) and issubclass(value, LeafSystem) and value.__module__ == module.name
                    and not name.startswith("_")):
                systems[f"{module.name}.{name}"] = value
    return systems


def undocumented_ports(cls: type, package: str = "sotdrake") -> list[str]:
    missing = []
    for base in inspect.getmro(cls):
        if issubclass(base, LeafSystem) and base.__module__.startswith(package):
            for port in declared_ports(base):
                pattern = re.compile(rf"``{re.escape(port)}``")
                if not any(pattern.search(c.__doc__ or "") for c in (cls, base)):
                    missing.append(port)
    return sorted(set(missing))


SYSTEMS = public_systems()


class _Undocumented(LeafSystem):
    """A system whose docstring names none of its ports."""

    def __init__(self):
        LeafSystem.__init__(self)
        self.DeclareVectorOutputPort("speed", 1, lambda c, o: None)


class _Documented(_Undocumented):
    """Output ``speed`` (m/s)."""


def test_the_systems_are_found_and_their_ports_read():
    assert {"sotdrake.solvers.sot.SOT", "sotdrake.solvers.solver_kine.SolverKine", "sotdrake.dynamics.solver_dyn.SolverDyn",
            "sotdrake.device.Device", "sotdrake.task.Task"} <= set(SYSTEMS)
    assert {"dynamics", "torque", "wrenches", "diagnostics", "stack"} <= declared_ports(SYSTEMS["sotdrake.dynamics.solver_dyn.SolverDyn"])
    assert undocumented_ports(_Undocumented, "tests") == ["speed"]
    assert undocumented_ports(_Documented, "tests") == []


@pytest.mark.parametrize("name", sorted(SYSTEMS))
def test_the_docstring_names_every_port(name):
    assert not undocumented_ports(SYSTEMS[name]), f"{name}: ports not named in the docstring"


@pytest.mark.parametrize("name", ["SolverDyn", "RobotDynSimu", "TaskDynPD", "Contact6d", "DynamicEntity", "MetaTaskDyn6d",
                                  "MetaTaskDynCom", "MetaTaskDynPosture", "MetaTaskDynMomentum", "RobotDyn", "ContactRows",
                                  "DynamicsTerms", "DynDiagnostics", "ContactNotFound"])
def test_the_dynamic_sots_names_are_exported(name):
    assert name in sotdrake.__all__ and (getattr(sotdrake, name).__doc__ or "").strip()
