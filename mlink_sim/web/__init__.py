"""The page and the HTTP API of a running network (``mlink-sim web``, ``mlink-sim up --web``): an aiohttp server in
a process of its own that sees the network only through the run's control endpoint (docs/web.md).

* :mod:`~mlink_sim.web.server`: the application, its routes and guards; ``openapi.yaml``: the API's OpenAPI 3.1
  document (``/api/openapi.json``);
* :mod:`~mlink_sim.web.feed`: the one status poller shared by every client (at most ten queries a second);
* :mod:`~mlink_sim.web.api`: the control endpoint's client, the errors' statuses;
* ``static/``: the page (HTML, CSS, JavaScript; no build step) and the vendored plotting library (uPlot, its
  licence in ``static/vendor/uplot/``).
"""

from __future__ import annotations

from .api import STATUS_OF_KIND, ApiError, Control
from .feed import Feed
from .server import build_app, openapi_document, start_server

__all__ = ["ApiError", "Control", "Feed", "STATUS_OF_KIND", "build_app", "openapi_document", "start_server"]
