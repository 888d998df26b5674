"""Run the tutorial's shell blocks, in order, so that its commands cannot rot (`make tutorial`).

.venv/bin/python docs/run_tutorial.py [docs/tutorial.md] [--keep]

Every fenced ```sh block of the page runs, in the page's order, in one bash session (`set -e`,
`pipefail`) in a fresh temporary folder, as a user typing them into one terminal would: a `cd` or
a variable carries over to the next block. `REPO` is this checkout, and `workbench` on the PATH
runs this checkout's package (`python -m workbench` with the checkout first on PYTHONPATH), not
whatever an installed console script points at. The first command that fails stops the run: the
runner names the block by its line in the page and exits 1. ```text blocks are shown, not run.
"""

from __future__ import annotations

import argparse
import os
import re
import shlex
import shutil
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
FENCE = re.compile(r"^```(\S*)\s*$")


@dataclass(frozen=True)
class Block:
    """One runnable block: its first line's number in the page (1-based) and its code."""

    line: int
    code: str


def shell_blocks(text: str) -> list[Block]:
    """The page's fenced ``sh`` blocks, in order.

    text: the Markdown page. Returns each block with the line number of its first code line.
    A fence left open is an error: the page would render the rest of itself as code.
    """
    blocks: list[Block] = []
    lang, start, body = None, 0, []
    for n, line in enumerate(text.splitlines(), 1):
        m = FENCE.match(line)
        if lang is None:
            if m:
                lang, start, body = m.group(1), n + 1, []
        elif line.strip() == "```":
            if lang == "sh":
                blocks.append(Block(start, "\n".join(body)))
            lang = None
        else:
            body.append(line)
    if lang is not None:
        raise SystemExit(f"run_tutorial: the code block opened at line {start - 1} is never closed")
    return blocks


def script(blocks: list[Block], state: Path, name: str) -> str:
    """One bash script of the blocks, each first writing its line number into ``state``.

    name: the page's file name, for the line each block prints to stderr as it starts.
    """
    parts = ["set -eo pipefail"]
    for b in blocks:
        parts.append(f"printf '%s\\n' {b.line} > {shlex.quote(str(state))}")
        parts.append(f"echo {shlex.quote(f'+ {name}:{b.line}')} >&2")
        parts.append(b.code)
    return "\n".join(parts) + "\n"


def shim(bin_dir: Path) -> None:
    """A ``workbench`` command in ``bin_dir`` that runs this checkout's package."""
    exe = bin_dir / "workbench"
    exe.write_text(f'#!/bin/sh\nexec {shlex.quote(sys.executable)} -m workbench "$@"\n')
    exe.chmod(0o755)


def run(page: Path, keep: bool) -> int:
    """Run ``page``'s sh blocks in a temporary folder; 0 when all succeed, else 1 (the block named)."""
    blocks = shell_blocks(page.read_text(encoding="utf-8"))
    if not blocks:
        print(f"run_tutorial: {page}: no ```sh block to run", file=sys.stderr)
        return 1
    work = Path(tempfile.mkdtemp(prefix="workbench-tutorial-"))
    (work / "bin").mkdir()
    (work / "part").mkdir()
    shim(work / "bin")
    state = work / "block"
    env = dict(os.environ)
    env["PATH"] = f"{work / 'bin'}{os.pathsep}{env.get('PATH', '')}"
    env["PYTHONPATH"] = os.pathsep.join([str(ROOT), *filter(None, [env.get("PYTHONPATH")])])
    env["REPO"] = str(ROOT)
    t0 = time.perf_counter()
    proc = subprocess.run(["bash", "-c", script(blocks, state, page.name)], cwd=work / "part", env=env)
    seconds = time.perf_counter() - t0
    where = f" (kept: {work / 'part'})" if keep else ""
    if proc.returncode != 0:
        line = state.read_text().strip() if state.exists() else "?"
        print(
            f"run_tutorial: {page}:{line}: the block starting there failed (exit {proc.returncode}) "
            f"after {seconds:.0f} s{where}",
            file=sys.stderr,
        )
    else:
        print(f"run_tutorial: {len(blocks)} blocks of {page} ran in {seconds:.0f} s{where}")
    if not keep:
        shutil.rmtree(work, ignore_errors=True)
    return 0 if proc.returncode == 0 else 1


def main() -> None:
    ap = argparse.ArgumentParser(description="run the tutorial's ```sh blocks in a fresh folder")
    ap.add_argument("page", nargs="?", type=Path, default=ROOT / "docs" / "tutorial.md")
    ap.add_argument("--keep", action="store_true", help="keep the temporary folder")
    args = ap.parse_args()
    sys.exit(run(args.page, args.keep))


if __name__ == "__main__":
    main()
