"""``mlink-sim wireshark``: where the shipped dissector is (``--path``) and copying it into Wireshark's personal
plugin folder (``--install``)."""

from __future__ import annotations

import os
import sys
from pathlib import Path

import click

__all__ = ["wireshark_cmd", "personal_plugin_dir"]


def personal_plugin_dir() -> Path:
    """Wireshark's personal Lua plugin folder: ``%APPDATA%\\Wireshark\\plugins`` on Windows,
    ``~/.local/lib/wireshark/plugins`` elsewhere (Wireshark User's Guide, "Plugin folders")."""
    if sys.platform == "win32" and os.environ.get("APPDATA"):
        return Path(os.environ["APPDATA"]) / "Wireshark" / "plugins"
    return Path.home() / ".local" / "lib" / "wireshark" / "plugins"


@click.command("wireshark")
@click.option("--install", is_flag=True, help="Copy the dissector into Wireshark's personal plugin folder.")
@click.option("--path", "show_path", is_flag=True, help="Print where the shipped dissector (mlink.lua) is.")
@click.option("--dest", type=click.Path(file_okay=False, path_type=Path),
              help="With --install: this folder instead of the personal plugin folder.")
def wireshark_cmd(install: bool, show_path: bool, dest: Path | None) -> None:
    """The Wireshark dissector for mlink-sim's datagrams (Lua, Wireshark 4.0 or later)."""
    from .._files import write_atomically
    from ..wireshark.generate import shipped_path

    source = shipped_path()
    if not install and not show_path:
        raise click.UsageError("give --install (copy it into the plugin folder) or --path (print where it is)")
    if dest is not None and not install:
        raise click.UsageError("--dest goes with --install")
    if show_path:
        click.echo(str(source))
    if install:
        target_dir = dest or personal_plugin_dir()
        target = target_dir / source.name
        try:
            target_dir.mkdir(parents=True, exist_ok=True)
            write_atomically(target, source.read_bytes())
        except OSError as exc:
            click.echo(f"mlink-sim wireshark: cannot install into {target_dir}: {exc.strerror or exc}", err=True)
            sys.exit(2)
        click.echo(f"installed {target}; restart Wireshark (or Analyze > Reload Lua Plugins) to load it")
