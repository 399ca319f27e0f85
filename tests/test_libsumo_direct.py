"""The backend calls libsumo's compiled functions directly for the methods it lists as
pass-through: each must still be a static method that only hands its arguments on, in
order, to the function of the same name (a libsumo release that adds logic to one, as
``vehicle.getLeader`` has, would otherwise be skipped silently)."""

from __future__ import annotations

import ast
import inspect
import textwrap

import libsumo
import pytest

from platoon_sumo.sumo.backend import PASS_THROUGH, SumoBackend, SumoOptions

METHODS = [(domain, name) for domain, names in PASS_THROUGH.items() for name in names]


@pytest.mark.parametrize(("domain", "name"), METHODS)
def test_method_only_passes_its_arguments_on(domain: str, name: str) -> None:
    method = getattr(getattr(libsumo, domain), name)
    (function,) = ast.parse(textwrap.dedent(inspect.getsource(method))).body
    assert isinstance(function, ast.FunctionDef)
    signature = function.args
    (statement,) = function.body
    assert isinstance(statement, ast.Return) and isinstance(statement.value, ast.Call)
    call = statement.value
    assert ast.unparse(call.func) == f"_libsumo.{domain}_{name}"
    forwarded = [ast.unparse(a) for a in call.args] + [ast.unparse(k) for k in call.keywords]
    if signature.vararg is not None:  # def f(*args, **kwargs): return g(*args, **kwargs)
        assert not signature.args and signature.kwarg is not None
        assert forwarded == [f"*{signature.vararg.arg}", f"**{signature.kwarg.arg}"]
    else:
        assert forwarded == [a.arg for a in signature.args] and signature.kwarg is None


def test_not_listed_methods_stay_the_modules() -> None:
    """`getLeader` keeps its Python logic (None for no leader, on request)."""
    backend = SumoBackend(SumoOptions(net_file="unused.net.xml", step_s=0.1, seed=1))
    vehicle = backend._api.vehicle
    assert vehicle.getLeader is libsumo.vehicle.getLeader
    assert vehicle.getPosition is libsumo._libsumo.vehicle_getPosition
    assert backend._api.simulationStep is libsumo.simulationStep
