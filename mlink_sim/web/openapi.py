"""The OpenAPI 3.1 document of the HTTP API (served as ``/api/openapi.json``): its operations' paths built from the
operations table (:data:`mlink_sim.operations.OPERATIONS`, those with an HTTP route), beside the parts that are the
API's own (``openapi.yaml``: the description, the routes that are not operations — the document itself, the event
stream — the security scheme, the schemas of the replies).

A path parameter is an argument the route names (``/api/stations/{station}/params/{param}``); the others are the
query (GET) or the JSON body (POST, PUT), each with its kind's schema and help.
"""

from __future__ import annotations

import functools
import re
from pathlib import Path
from typing import Any

from ..operations import ERROR_KINDS, Arg, Operation, served_by

__all__ = ["openapi_document", "path_args", "STATUS_OF_KIND"]

_STATIC = Path(__file__).parent / "openapi.yaml"

#: An operation's error ``kind`` → the HTTP status it is answered with (docs/web.md, "Errors").
STATUS_OF_KIND = dict(zip(ERROR_KINDS, (400, 404, 404, 422, 409, 409)))
_TAGS = {"get-param": "parameters", "set-param": "parameters", "impair": "faults", "heal": "faults",
         "fault": "faults", "faults": "faults", "recovery": "faults"}


def path_args(op: Operation) -> list[str]:
    """The arguments *op*'s route names in its path (``["station", "param"]``)."""
    assert op.http is not None
    return re.findall(r"{(\w+)}", op.http[1])


def _schema(arg: Arg) -> dict[str, Any]:
    schema = dict(arg.kind.schema)
    schema.pop("examples", None)
    schema["description"] = arg.help
    if arg.default is not None:
        schema["default"] = arg.default
    return schema


def _parameter(op: Operation, name: str) -> dict[str, Any]:
    if name == "station":
        return {"$ref": "#/components/parameters/" + ("address" if op.arg(name).required else "addressOrAll")}
    arg = op.arg(name)
    return {"name": name, "in": "path", "required": True, "description": arg.help,
            "schema": {"type": "string", "pattern": "^[A-Za-z][A-Za-z0-9]{0,3}(-[0-9A-Za-z]{1,4})?$"}}


def _reply(op: Operation) -> dict[str, Any]:
    if op.reply in ("StationFigures", "Param"):
        return {"$ref": f"#/components/responses/{op.reply}"}
    schema = {"$ref": f"#/components/schemas/{op.reply}"} if op.reply else {"type": "object"}
    return {"description": op.returns or "Done.", "content": {"application/json": {"schema": schema}}}


def _operation(op: Operation) -> dict[str, Any]:
    assert op.http is not None
    method, _ = op.http
    in_path = path_args(op)
    rest = [a for a in op.args if a.name not in in_path]
    out: dict[str, Any] = {
        "summary": op.summary,
        "description": f"The `{op.name}` operation (docs/control.md). Answers: {op.returns}."
                       + (f" ({op.cites})" if op.cites else ""),
        "operationId": re.sub(r"-(\w)", lambda m: m.group(1).upper(), op.name),
        "tags": [_TAGS.get(op.name, "stations" if "station" in in_path else "network")],
        "responses": {"200": _reply(op), **{str(code): {"$ref": "#/components/responses/Error"}
                                            for code in (400, 401, 404, 409, 415, 422, 503)}},
    }
    params = [_parameter(op, name) for name in in_path]
    if method == "GET":
        params += [{"name": a.name, "in": "query", "required": a.required, "description": a.help,
                    "schema": _schema(a)} for a in rest]
        del out["responses"]["415"]
    else:
        body: dict[str, Any] = {"type": "object", "additionalProperties": False,
                                "properties": {a.name: _schema(a) for a in rest}}
        required = [a.name for a in rest if a.required]
        if required:
            body["required"] = required
        out["requestBody"] = {"required": bool(required), "content": {"application/json": {"schema": body}}}
    if params:
        out["parameters"] = params
    return out


@functools.cache
def openapi_document() -> dict[str, Any]:
    """The whole document (read and built once)."""
    import yaml

    document: dict[str, Any] = yaml.safe_load(_STATIC.read_text(encoding="utf-8"))
    paths = document.setdefault("paths", {})
    for op in served_by("network"):
        if op.http is not None:
            method, path = op.http
            paths.setdefault(path, {})[method.lower()] = _operation(op)
    return document
