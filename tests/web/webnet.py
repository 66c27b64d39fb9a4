"""Helpers of the web tests: a real network with its web server (``mlink-sim up --web``, or ``mlink-sim web`` against
``up --control``), an HTTP client on the standard library, and the OpenAPI document's schemas as validators."""

from __future__ import annotations

import json
import re
import signal
import subprocess
import sys
import threading
import time
import urllib.error
import urllib.request
from collections.abc import Iterator
from typing import Any

from jsonschema import Draft202012Validator

from mlink_sim.web import openapi_document

MLINK = [sys.executable, "-m", "mlink_sim"]
_URL = re.compile(r"^web: (http://\S+)")
_CONTROL = re.compile(r"^control: (\S+):(\d+) ")


class Proc:
    """A ``mlink-sim`` process whose stderr is read line by line in a thread (``lines``)."""

    def __init__(self, *args: str) -> None:
        self.proc = subprocess.Popen([*MLINK, *args], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        self.lines: list[str] = []
        self.stdout = ""
        threading.Thread(target=self._read, daemon=True).start()
        threading.Thread(target=self._drain, daemon=True).start()

    def _read(self) -> None:
        assert self.proc.stderr is not None
        for line in self.proc.stderr:
            self.lines.append(line.rstrip("\n"))

    def _drain(self) -> None:
        assert self.proc.stdout is not None
        self.stdout = self.proc.stdout.read()

    def wait_line(self, pattern: re.Pattern[str], timeout: float = 30.0) -> re.Match[str]:
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            for line in list(self.lines):
                if m := pattern.search(line):
                    return m
            if self.proc.poll() is not None:
                time.sleep(0.2)
                raise AssertionError(f"exited {self.proc.returncode}: " + "\n".join(self.lines[-20:]))
            time.sleep(0.05)
        raise AssertionError("not seen in time: " + pattern.pattern + "\n" + "\n".join(self.lines[-20:]))

    def stop(self, sig: signal.Signals = signal.SIGINT, timeout: float = 20.0) -> int:
        if self.proc.poll() is None:
            self.proc.send_signal(sig)
            try:
                self.proc.wait(timeout)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()
        return self.proc.returncode


def up_with_web(*extra: str, config: str = "quickstart", realtime: bool = False) -> tuple[Proc, str]:
    """``mlink-sim up CONFIG --no-timeline --web 127.0.0.1:0`` (until stopped): the process and the page's URL.
    *realtime*: the run's real-time scheduling where permitted (the pictures of docs/web.md, taken beside a
    browser on a small machine); else none (the tests)."""
    proc = Proc("up", config, "--no-timeline", "--duration", "600s", "--no-status",
                "--realtime" if realtime else "--no-realtime", "--web", "127.0.0.1:0", *extra)
    return proc, proc.wait_line(_URL).group(1)


def up_with_control(*extra: str) -> tuple[Proc, str]:
    """``mlink-sim up quickstart --no-timeline --control 127.0.0.1:0``: the process and its endpoint (HOST:PORT)."""
    proc = Proc("up", "quickstart", "--no-timeline", "--duration", "600s", "--no-status", "--no-realtime",
                "--control", "127.0.0.1:0", *extra)
    m = proc.wait_line(_CONTROL)
    return proc, f"{m.group(1)}:{m.group(2)}"


def web_server(*args: str) -> tuple[Proc, str]:
    """``mlink-sim web ARGS``: the process and its URL."""
    proc = Proc("web", *args)
    return proc, proc.wait_line(_URL).group(1)


class Http:
    """Requests to the server at *base* (``http://127.0.0.1:PORT/``), with *token* if given."""

    def __init__(self, base: str, token: str | None = None) -> None:
        self.base = base
        self.token = token

    def request(self, method: str, path: str, body: Any = None, *, content_type: str | None = "application/json",
                raw: bytes | None = None, headers: dict[str, str] | None = None,
                timeout: float = 15.0) -> tuple[int, Any]:
        """(status, the JSON body) of one request; *body* is sent as JSON, *raw* as given."""
        data = raw if raw is not None else None if body is None else json.dumps(body).encode()
        req = urllib.request.Request(self.base + path.lstrip("/"), data=data, method=method)
        if data is not None and content_type:
            req.add_header("Content-Type", content_type)
        if self.token:
            req.add_header("Authorization", f"Bearer {self.token}")
        for name, value in (headers or {}).items():
            req.add_header(name, value)
        try:
            with urllib.request.urlopen(req, timeout=timeout) as r:
                return r.status, json.loads(r.read() or b"null")
        except urllib.error.HTTPError as e:
            return e.code, json.loads(e.read() or b"null")

    def get(self, path: str, **kw: Any) -> tuple[int, Any]:
        return self.request("GET", path, **kw)

    def post(self, path: str, body: Any = None, **kw: Any) -> tuple[int, Any]:
        return self.request("POST", path, {} if body is None else body, **kw)

    def events(self, until: Any, timeout: float = 15.0) -> list[tuple[str, Any]]:
        """Read ``/api/events`` until *until(messages)* holds: the (event name, data) of each message."""
        req = urllib.request.Request(self.base + "api/events")
        if self.token:
            req.add_header("Authorization", f"Bearer {self.token}")
        messages: list[tuple[str, Any]] = []
        deadline = time.monotonic() + timeout
        with urllib.request.urlopen(req, timeout=timeout) as r:
            assert r.headers["Content-Type"].startswith("text/event-stream")
            name, data = "message", ""
            while time.monotonic() < deadline and not until(messages):
                line = r.readline().decode().rstrip("\n")
                if line.startswith("event:"):
                    name = line[6:].strip()
                elif line.startswith("data:"):
                    data += line[5:].strip()
                elif not line and data:
                    messages.append((name, json.loads(data)))
                    name, data = "message", ""
        return messages


def wait_for(check: Any, timeout: float = 20.0, what: str = "") -> Any:
    """Poll *check()* until it returns a true value (returned), or fail after *timeout* seconds."""
    deadline = time.monotonic() + timeout
    last = None
    while time.monotonic() < deadline:
        last = check()
        if last:
            return last
        time.sleep(0.1)
    raise AssertionError(f"{what or 'condition'} not reached in {timeout:g}s (last: {last!r})")


# ---- the OpenAPI document: every response is validated against it ------------------------------------------------

DOC = openapi_document()


def schema_validator(schema: dict[str, Any]) -> Draft202012Validator:
    """A JSON Schema 2020-12 validator of *schema*, its ``#/components/…`` references resolved in the document."""
    return Draft202012Validator({**schema, "components": DOC["components"]})


def _resolve(node: dict[str, Any]) -> dict[str, Any]:
    while "$ref" in node:
        target: Any = DOC
        for part in node["$ref"].removeprefix("#/").split("/"):
            target = target[part.replace("~1", "/").replace("~0", "~")]
        node = target
    return node


def check_response(template: str, method: str, status: int, body: Any) -> None:
    """*body* is what the document says *method* *template* answers with *status* (a status it does not list
    fails)."""
    responses = DOC["paths"][template][method.lower()]["responses"]
    assert str(status) in responses, f"{method} {template} answered {status}, not in the document: {body}"
    response = _resolve(responses[str(status)])
    schema = response["content"]["application/json"]["schema"]
    schema_validator(schema).validate(body)


def component(name: str) -> Draft202012Validator:
    return schema_validator({"$ref": f"#/components/schemas/{name}"})


def stations(http: Http) -> list[dict[str, Any]]:
    status, body = http.get("api/status")
    assert status == 200, body
    return list(body["stations"])


def by_name(rows: list[dict[str, Any]]) -> dict[str, dict[str, Any]]:
    return {row["name"]: row for row in rows}


def iter_phases(http: Http) -> Iterator[int]:
    for row in stations(http):
        yield row["phase"]
