"""Loggers of the library: quiet unless the application configures logging.

Used as a library, mlink-sim must not print: structlog's defaults write every event to stdout. The package's
loggers (:func:`get_logger`) therefore follow structlog's configuration once an application (or the ``mlink-sim``
command line and the pytest plugin's host process, through :func:`configure_logging`) has called
``structlog.configure``; before that they hand their events to the
standard library's ``logging`` under the logger's name (``mlink_sim.…``), where the package's
``logging.NullHandler`` keeps them silent until the application configures ``logging``.
"""

from __future__ import annotations

import logging
import sys
from typing import Any

import structlog

__all__ = ["configure_logging", "get_logger"]

logging.getLogger("mlink_sim").addHandler(logging.NullHandler())


def _stdlib(name: str) -> Any:
    return structlog.wrap_logger(
        logging.getLogger(name),
        processors=[structlog.stdlib.filter_by_level, structlog.processors.KeyValueRenderer(key_order=["event"])],
        wrapper_class=structlog.stdlib.BoundLogger,
    )


class _Logger:
    """A structlog-style logger (``info``, ``warning``, ``bind`` …) choosing its output on each call: structlog's lazy
    proxy (which follows later reconfigurations) while structlog is configured, the standard library's ``logging``
    otherwise (before it is, and after ``structlog.reset_defaults()``)."""

    __slots__ = ("_name", "_ctx", "_target")

    def __init__(self, name: str, ctx: dict[str, Any]) -> None:
        self._name = name
        self._ctx = ctx
        self._target: Any = None

    def _resolve(self) -> Any:
        if structlog.is_configured():
            self._target = structlog.get_logger(self._name, **self._ctx)
            return self._target
        return _stdlib(self._name).bind(**self._ctx)

    def bind(self, **values: Any) -> _Logger:
        return _Logger(self._name, {**self._ctx, **values})

    def __getattr__(self, method: str) -> Any:
        target = self._target if structlog.is_configured() else None  # a reset configuration: the library's again
        return getattr(target or self._resolve(), method)


def get_logger(name: str, **initial: Any) -> Any:
    """The package's logger *name* with *initial* context (as ``structlog.get_logger(name, **initial)``)."""
    return _Logger(name, dict(initial))


class _Stderr:
    """The process's standard error as it is at each write, not as it was when logging was configured: a test
    runner or an application that swaps ``sys.stderr`` later (and closes the old stream) still gets every line."""

    def write(self, text: str) -> int:
        return sys.stderr.write(text)

    def flush(self) -> None:
        sys.stderr.flush()


def configure_logging(*, json: bool = False, level: str = "info") -> None:
    """Configure structlog once per process: key=value lines (or JSON) on stderr; stdout is kept for results and
    ready lines. Only the entry points call it (the ``mlink-sim`` commands, the pytest plugin's host process, the
    benchmarks): as a library the package prints nothing."""
    renderer: structlog.types.Processor = (
        structlog.processors.JSONRenderer() if json else structlog.dev.ConsoleRenderer(colors=False)
    )
    structlog.configure(
        processors=[
            structlog.contextvars.merge_contextvars,
            structlog.processors.add_log_level,
            structlog.processors.TimeStamper(fmt="iso", utc=True),
            structlog.processors.format_exc_info,
            renderer,
        ],
        wrapper_class=structlog.make_filtering_bound_logger(getattr(logging, level.upper(), logging.INFO)),
        logger_factory=structlog.PrintLoggerFactory(file=_Stderr()),  # type: ignore[arg-type]
        cache_logger_on_first_use=True,
    )
