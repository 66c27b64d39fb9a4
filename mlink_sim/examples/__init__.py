"""The example networks shipped with the package (``configs/`` in the source tree is a link to this folder).

``mlink-sim up quickstart`` and ``@pytest.mark.mlink_network("quickstart")`` name them without a path; see
:func:`mlink_sim.config.resolve_config_path`."""

from __future__ import annotations

from pathlib import Path

__all__ = ["EXAMPLES_DIR", "example_names", "example_path"]

#: The folder holding the ``*.toml`` examples (package data, installed with the package).
EXAMPLES_DIR = Path(__file__).resolve().parent


def example_names() -> list[str]:
    """The shipped examples by name (file name without ``.toml``), sorted."""
    return sorted(p.stem for p in EXAMPLES_DIR.glob("*.toml"))


def example_path(name: str) -> Path | None:
    """The shipped example called *name* (``quickstart`` or ``quickstart.toml``), or None."""
    stem = name[:-5] if name.endswith(".toml") else name
    if "/" in stem or "\\" in stem or stem not in example_names():
        return None
    return EXAMPLES_DIR / f"{stem}.toml"
