"""Every surface offers every operation the table gives it, with the table's arguments: the control endpoints'
handlers, the command line (``mlink-sim control``), the HTTP routes and their OpenAPI paths, the Python API (one
mixin for the embedded network, the harness and the plugin's fixture) and the config's timeline. A new operation in
the table fails here until each surface has it."""

from __future__ import annotations

import inspect

import pytest

from mlink_sim.aio.control.faults import ImpairmentOps
from mlink_sim.aio.control.slave import SlaveOps
from mlink_sim.config.model import _ACTIONS, TimelineStep
from mlink_sim.faults.spec import FAULT_ACTIONS
from mlink_sim.operations import OPERATIONS, NetworkOperations, served_by

NETWORK = [op for op in served_by("network") if op.name != "ping"]


def test_the_python_api_has_a_method_per_network_operation_with_its_arguments() -> None:
    for op in NETWORK:
        method = getattr(NetworkOperations, op.python)
        params = list(inspect.signature(method).parameters.values())[1:]
        assert [p.name for p in params] == [a.python for a in op.args], op.name
        for param, arg in zip(params, op.args):
            if arg.required:
                assert param.default is inspect.Parameter.empty, (op.name, arg.name)
            else:
                assert param.default == (arg.default if arg.default is not None else None) or (
                    arg.name == "station" and param.default == "all"), (op.name, arg.name)
        assert method.__doc__.startswith(op.summary)
    own = {name for name, fn in vars(NetworkOperations).items() if callable(fn) and not name.startswith("_")}
    assert own == {op.python for op in NETWORK}


@pytest.mark.parametrize("cls", ["mlink_sim.aio.run.embed:VirtualNetwork", "mlink_sim.testing:RunningNetwork",
                                 "mlink_sim.testing.virtual:VirtualRunningNetwork"])
def test_each_python_surface_derives_its_operations_from_the_one_mixin(cls: str) -> None:
    import importlib

    module, name = cls.split(":")
    surface = getattr(importlib.import_module(module), name)
    assert issubclass(surface, NetworkOperations)
    for op in NETWORK:
        if op.name != "report":  # each surface returns its final report once closed
            assert getattr(surface, op.python) is getattr(NetworkOperations, op.python), (cls, op.name)


def test_the_endpoints_handlers_are_the_tables() -> None:
    from mlink_sim.aio.run.embed import VirtualNetwork

    with VirtualNetwork("quickstart") as net:
        assert set(net.ops.handlers()) == {op.name for op in NETWORK}
    assert set(ImpairmentOps(None).handlers()) == {op.name for op in served_by("proxy")} - {"ping"}
    assert set(SlaveOps(None).handlers()) == {op.name for op in served_by("slave")} - {"ping"}


def test_the_command_line_has_a_command_per_operation() -> None:
    from mlink_sim.cli.control import control_cmd

    assert list(control_cmd.commands) == list(OPERATIONS)
    for op in OPERATIONS.values():
        params = {p.name for p in control_cmd.commands[op.name].params}
        assert {a.python for a in op.args if a.cli} <= params, op.name


def test_the_http_api_has_a_route_and_a_path_per_operation_with_one() -> None:
    from mlink_sim.web.api import Control
    from mlink_sim.web.openapi import openapi_document
    from mlink_sim.web.server import build_app

    app = build_app(Control("127.0.0.1", 9))
    routes = {(r.method, r.resource.canonical) for r in app.router.routes() if r.resource is not None}
    doc = openapi_document()
    for op in NETWORK:
        if op.http is None:
            continue
        method, path = op.http
        assert (method, path) in routes, op.name
        assert doc["paths"][path][method.lower()]["summary"] == op.summary


def test_the_timeline_offers_its_operations_with_their_arguments_as_fields() -> None:
    timeline_ops = [op for op in OPERATIONS.values() if op.timeline]
    assert set(_ACTIONS) == {op.name for op in timeline_ops} | set(FAULT_ACTIONS)
    fields = set(TimelineStep.model_fields)
    for op in [*timeline_ops, OPERATIONS["fault"]]:
        assert {a.python for a in op.args if a.name not in ("station", "spec")} <= fields, op.name
