"""The tutorial's runner: which blocks it runs, in what order, and where it says a run failed."""

from __future__ import annotations

import importlib.util
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
RUNNER = ROOT / "docs" / "run_tutorial.py"


def load_runner():
    spec = importlib.util.spec_from_file_location("run_tutorial", RUNNER)
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # its dataclass resolves its annotations through sys.modules
    spec.loader.exec_module(module)
    return module


PAGE = """# A page

```sh
echo one > first.txt
```

```text
false
```

Prose between.

```sh
cd sub 2>/dev/null || mkdir sub
echo two
```
"""


def test_only_sh_blocks_in_order_with_their_first_line():
    blocks = load_runner().shell_blocks(PAGE)
    assert [(b.line, b.code) for b in blocks] == [
        (4, "echo one > first.txt"),
        (14, "cd sub 2>/dev/null || mkdir sub\necho two"),
    ]


def test_a_fence_left_open_is_an_error():
    with pytest.raises(SystemExit, match="line 3 is never closed"):
        load_runner().shell_blocks("text\n\n```sh\necho\n")


def run_page(tmp_path: Path, text: str) -> subprocess.CompletedProcess:
    page = tmp_path / "page.md"
    page.write_text(text)
    return subprocess.run([sys.executable, str(RUNNER), str(page)], capture_output=True, text=True)


def test_the_first_failing_block_is_named_by_its_line(tmp_path):
    text = "```sh\ncd /\nmkdir -p x\n```\n\n```sh\ntrue\nfalse\necho never\n```\n\n```sh\necho later\n```\n"
    proc = run_page(tmp_path, text)
    assert proc.returncode == 1
    assert "never" not in proc.stdout and "later" not in proc.stdout
    assert f"{tmp_path / 'page.md'}:7: the block starting there failed (exit 1)" in proc.stderr


def test_blocks_share_one_session_and_run_this_checkout(tmp_path):
    # a variable set in one block is seen by the next; `workbench` runs this checkout's package
    text = f"""```sh
VALUE=kept
```

```sh
test "$VALUE" = kept
test "$REPO" = "{ROOT}"
case "$PYTHONPATH" in "{ROOT}"*) ;; *) exit 3 ;; esac
grep -q -- "-m workbench" "$(command -v workbench)"
workbench --version
```
"""
    proc = run_page(tmp_path, text)
    assert proc.returncode == 0, proc.stderr
    assert "workbench" in proc.stdout and "2 blocks" in proc.stdout
