"""A page's examples write only into the page's temporary folder: its commands and its Python blocks run in a
working folder and with a home of their own there (tests/docs/shell.py, ``home_of``). docs/capture.md's
``mlink-sim wireshark --install`` so installs the dissector into that home, never into the home of whoever runs the
tests, where a second copy of the protocol makes tshark refuse the dissector the tests load."""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

from tests.docs.examples import SYBIL, STATE, Page
from tests.docs.shell import HOME_VARIABLES

PAGE = """\
# A page that keeps things for its user

```sh
mlink-sim wireshark --install
test -f ~/.local/lib/wireshark/plugins/mlink.lua
touch by-the-shell "$XDG_CONFIG_HOME/by-the-shell" "$TMPDIR/by-the-shell"
```

```python
import tempfile
from pathlib import Path

Path("by-python").touch()
(Path.home() / "by-python").touch()
with open(tempfile.mkstemp(prefix="by-python-")[1], "w") as f:
    f.write("kept in the page's tmp")
```
"""


def _stat(path: Path) -> tuple[int, int] | None:
    return (path.stat().st_mtime_ns, path.stat().st_size) if path.exists() else None


def test_what_a_page_keeps_for_its_user_lands_in_its_own_folder(tmp_path: Path) -> None:
    page_file = tmp_path / "page.md"
    page_file.write_text(PAGE, encoding="utf-8")
    real_plugin = Path.home() / ".local" / "lib" / "wireshark" / "plugins" / "mlink.lua"
    before, cwd, env = _stat(real_plugin), Path.cwd(), {name: os.environ.get(name) for name in HOME_VARIABLES}
    document = SYBIL.parse(page_file)
    examples = list(document)
    assert len(examples) == 2
    SYBIL.setup(document.namespace)
    page: Page = document.namespace[STATE]
    try:
        for example in examples:
            example.evaluate()
        home = page.root / "home"
        assert (home / ".local" / "lib" / "wireshark" / "plugins" / "mlink.lua").is_file()
        assert (page.workdir / "by-the-shell").is_file() and (page.workdir / "by-python").is_file()
        assert (home / ".config" / "by-the-shell").is_file() and (home / "by-python").is_file()
        assert (page.root / "tmp" / "by-the-shell").is_file()
        assert [p.name for p in (page.root / "tmp").glob("by-python-*")]
    finally:
        SYBIL.teardown(document.namespace)
    assert not page.root.exists()  # the page's folder goes with the page
    assert _stat(real_plugin) == before  # the tester's own plugin folder untouched, whether it has one or not
    assert Path.cwd() == cwd and {name: os.environ.get(name) for name in HOME_VARIABLES} == env
    assert not Path(tempfile.gettempdir()).is_relative_to(page.root)
