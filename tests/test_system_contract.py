"""The LeafSystem contract (drake_est/systems/contract.py, docs/conventions.md) checked on every LeafSystem.

Discovery: every module under ``drake_est.systems`` is imported and each ``LeafSystem`` subclass it defines
(public name, not a private base) must be covered by a case of the module's ``contract_cases()``.  The rest
of the package is scanned statically: a ``class X(LeafSystem)`` outside ``drake_est/systems`` is a failure
(deprecation aliases are assignments/imports, not classes).  For each case:

1. port names are lower_snake_case and each appears in the class docstring with a unit in brackets;
2. with the inputs fixed and the system simulated to ``t_final``, the outputs equal the plain algorithm's;
3. two Contexts of one system advanced interleaved give the same outputs as two separate runs.
"""
from __future__ import annotations

import ast
import importlib
import inspect
import pkgutil
import re
from pathlib import Path

import numpy as np
import pytest
from pydrake.common.value import AbstractValue
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import LeafSystem, PortDataType

import drake_est.systems

PKG = Path(drake_est.systems.__file__).resolve().parents[1]
SNAKE = re.compile(r"^[a-z][a-z0-9_]*$")


def _system_modules():
    out, errors = {}, {}
    for info in pkgutil.iter_modules(drake_est.systems.__path__):
        name = f"drake_est.systems.{info.name}"
        if info.name in ("contract",):
            continue
        try:
            out[name] = importlib.import_module(name)
        except Exception as e:                      # reported by a failing test, not a collection error
            errors[name] = f"{type(e).__name__}: {e}"
    return out, errors


MODULES, IMPORT_ERRORS = _system_modules()


def _leaf_classes(mod):
    return [c for _, c in inspect.getmembers(mod, inspect.isclass)
            if issubclass(c, LeafSystem) and c.__module__ == mod.__name__ and not c.__name__.startswith("_")]


def _collect_cases():
    cases, problems = [], []
    for name, mod in sorted(MODULES.items()):
        classes = _leaf_classes(mod)
        if not classes:
            continue
        fn = getattr(mod, "contract_cases", None)
        if fn is None:
            problems.append(f"{name} defines {', '.join(c.__name__ for c in classes)} but no contract_cases()")
            continue
        try:
            mod_cases = list(fn())
        except Exception as e:
            problems.append(f"{name}.contract_cases() raised {type(e).__name__}: {e}")
            continue
        covered = set()
        for k, case in enumerate(mod_cases):
            try:
                sys0 = case.make()
            except Exception as e:
                problems.append(f"{name} case {k} ({case.label}): make() raised {type(e).__name__}: {e}")
                continue
            covered.add(type(sys0))
            cases.append(pytest.param(case, id=f"{name.split('.')[-1]}.{type(sys0).__name__}[{case.label or k}]"))
        for c in classes:
            if c not in covered:
                problems.append(f"{name}.{c.__name__} has no contract case")
    return cases, problems


CASES, PROBLEMS = _collect_cases()


# ------------------------------------------------------------------------------------------ coverage
def test_every_systems_module_imports():
    assert not IMPORT_ERRORS, "; ".join(f"{k}: {v}" for k, v in IMPORT_ERRORS.items())


def test_every_leaf_system_has_a_contract_case():
    assert not PROBLEMS, "LeafSystems without a contract case: " + "; ".join(PROBLEMS)


def _leaf_systems_outside_systems():
    found = []
    for path in sorted(PKG.rglob("*.py")):
        rel = path.relative_to(PKG.parent)
        if rel.parts[1] == "systems":
            continue
        tree = ast.parse(path.read_text(), str(path))
        local = {"LeafSystem"}
        for node in ast.walk(tree):     # classes deriving from LeafSystem or from a local LeafSystem subclass
            if isinstance(node, ast.ClassDef):
                bases = {ast.unparse(b).split(".")[-1] for b in node.bases}
                if bases & local:
                    local.add(node.name)
                    found.append(f"{rel}:{node.lineno} {node.name}")
    return found


def test_no_leaf_system_outside_drake_est_systems():
    found = _leaf_systems_outside_systems()
    assert not found, ("LeafSystems belong in drake_est/systems/ (keep an alias at the old path): "
                       + "; ".join(found))


# ------------------------------------------------------------------------------------------ the contract
def _fix_inputs(system, context, inputs):
    for i in range(system.num_input_ports()):
        port = system.get_input_port(i)
        name = port.get_name()
        if name not in inputs:
            continue
        value = inputs[name]
        if port.get_data_type() == PortDataType.kVectorValued:
            port.FixValue(context, np.asarray(value, float))
        else:
            port.FixValue(context, AbstractValue.Make(value) if not isinstance(value, AbstractValue) else value)


def _outputs(system, context) -> dict:
    out = {}
    for i in range(system.num_output_ports()):
        port = system.get_output_port(i)
        val = port.Eval(context)
        try:
            out[port.get_name()] = np.array(val, dtype=float, copy=True)
        except (TypeError, ValueError):
            out[port.get_name()] = repr(val)
    return out


def _same(a: dict, b: dict, rtol=0.0, atol=0.0):
    for k in a:
        if isinstance(a[k], np.ndarray):
            np.testing.assert_allclose(a[k], b[k], rtol=rtol, atol=atol, equal_nan=True, err_msg=k)
        else:
            assert a[k] == b[k], k


def _docstring(cls) -> str:
    return "\n".join(inspect.getdoc(c) or "" for c in cls.__mro__ if c.__module__.startswith("drake_est"))


@pytest.mark.parametrize("case", CASES)
def test_port_names_are_snake_case_and_documented_with_units(case):
    system = case.make()
    doc = _docstring(type(system))
    ports = [system.get_input_port(i) for i in range(system.num_input_ports())] + \
            [system.get_output_port(i) for i in range(system.num_output_ports())]
    for port in ports:
        name = port.get_name()
        assert SNAKE.match(name), f"{type(system).__name__}: port {name!r} is not lower_snake_case"
        hits = [m.end() for m in re.finditer(rf"\b{re.escape(name)}\b", doc)]
        assert hits, f"{type(system).__name__}: port {name!r} is not named in the class docstring"
        assert any("[" in doc[h:h + 160] for h in hits), \
            f"{type(system).__name__}: port {name!r} has no unit in brackets after it in the docstring"


@pytest.mark.parametrize("case", CASES)
def test_outputs_equal_the_plain_algorithm(case):
    if case.expected is None:
        pytest.skip(f"{case.label}: this case checks names and hidden state only")
    system = case.make()
    context = system.CreateDefaultContext()
    _fix_inputs(system, context, case.inputs)
    sim = Simulator(system, context)
    sim.AdvanceTo(case.t_final)
    got = _outputs(system, sim.get_context())
    expected = case.expected_outputs(system)
    assert expected, "expected() returned no outputs"
    for name, want in expected.items():
        np.testing.assert_allclose(got[name].ravel(), np.asarray(want, float).ravel(), rtol=case.rtol,
                                   atol=case.atol, equal_nan=True, err_msg=f"{type(system).__name__}.{name}")


@pytest.mark.parametrize("case", CASES)
def test_two_contexts_interleaved_equal_separate_runs(case):
    system = case.make()
    steps = np.linspace(0.0, case.t_final, 6)[1:]

    def new_sim():
        ctx = system.CreateDefaultContext()
        _fix_inputs(system, ctx, case.inputs)
        return Simulator(system, ctx)

    # separate: one context runs to the end, then the other
    separate = []
    for _ in range(2):
        sim = new_sim()
        trace = []
        for t in steps:
            sim.AdvanceTo(t)
            trace.append(_outputs(system, sim.get_context()))
        separate.append(trace)
    # interleaved: both advance step by step, alternately
    sims = [new_sim(), new_sim()]
    inter = [[], []]
    for t in steps:
        for k in (0, 1):
            sims[k].AdvanceTo(t)
            inter[k].append(_outputs(system, sims[k].get_context()))
    for k in (0, 1):
        for a, b in zip(separate[k], inter[k]):
            _same(a, b)
