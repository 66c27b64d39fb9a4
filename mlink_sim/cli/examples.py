"""``mlink-sim examples`` (the shipped example networks, each with the first line of its comment) and
``mlink-sim examples copy NAME [DEST]`` (a copy to edit)."""

from __future__ import annotations

from pathlib import Path

import click

from .._files import write_atomically
from ..examples import example_names, example_path
from .inputs import InputError

__all__ = ["examples_cmd", "first_comment"]


def first_comment(path: Path) -> str:
    """The first sentence of the comment that opens *path* (the example's description): its ``#`` lines up to
    the first indented one (a command line) or the first sentence's end; ``""`` without a comment."""
    words: list[str] = []
    for line in path.read_text(encoding="utf-8").splitlines():
        stripped = line.strip()
        if not stripped.startswith("#"):
            break
        text = stripped[1:]
        if text.startswith("  ") or not text.strip():
            break
        words.append(text.strip())
        if text.rstrip().endswith("."):
            break
    sentence = " ".join(words)
    end = sentence.find(". ")
    return (sentence[: end + 1] if end >= 0 else sentence).rstrip(":")


@click.group("examples", invoke_without_command=True,
             short_help="List the shipped example networks; 'examples copy NAME' copies one to edit.")
@click.pass_context
def examples_cmd(ctx: click.Context) -> None:
    """List the example networks shipped with mlink-sim: name and what it shows. Any command that takes a
    CONFIG takes one of these names too (mlink-sim up quickstart).

    \b
      mlink-sim examples
      mlink-sim examples copy quickstart my-net.toml"""
    if ctx.invoked_subcommand is not None:
        return
    names = example_names()
    width = max(len(n) for n in names)
    for name in names:
        path = example_path(name)
        assert path is not None
        click.echo(f"{name:<{width}}  {first_comment(path)}")


@examples_cmd.command("copy")
@click.argument("name", metavar="NAME")
@click.argument("dest", metavar="[DEST]", required=False)
@click.option("--force", is_flag=True, help="Overwrite DEST if it exists.")
def copy_cmd(name: str, dest: str | None, force: bool) -> None:
    """Copy the example NAME to DEST (a file, or a folder to put NAME.toml in; default: NAME.toml here)."""
    source = example_path(name)
    if source is None:
        raise InputError(f"examples copy {name}: no such example (examples: {', '.join(example_names())})")
    target = Path(dest) if dest else Path(source.name)
    if target.is_dir():
        target = target / source.name
    if not target.parent.is_dir():
        raise InputError(f"examples copy {name}: folder {str(target.parent)!r} does not exist")
    if target.exists() and not force:
        raise InputError(f"examples copy {name}: {target} exists; add --force to overwrite it")
    try:
        write_atomically(target, source.read_bytes(), mode=0o644)
    except OSError as exc:
        raise InputError(f"examples copy {name}: cannot write {target}: {exc.strerror or exc}") from None
    click.echo(f"wrote {target} (run it: mlink-sim up {target})")
