"""Check every command and option the docs name against the commands themselves (`make docs`).

.venv/bin/python docs/check_options.py

An option the docs give a command (`workbench validate ... --tolerance-mm`, on the same line or in
a synopsis's continuation lines) must be in that command's `--help`; any other `--option` in the
docs must be some command's, or a benchmark's or fixture script's (their sources are read). A
command the docs name must exist. Prints one line per finding and exits 1 if there is any.
"""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _commands() -> tuple[str, ...]:
    """Every command as the docs write it, from the command line's own list (the groups with their actions)."""
    from workbench.cli import COMMANDS as TOP

    groups = {"store": ("export",), "calibrate": ("camera", "printer", "check", "forming")}
    return tuple(c for c in TOP if c not in groups) + tuple(f"{c} {a}" for c in TOP if c in groups for a in groups[c])


COMMANDS = _commands()
# a command as the docs write it: the groups (calibrate, store) take their action's name after them
NAMED = re.compile(r"workbench (calibrate \w+|store \w+|calibrate|store|[a-z][a-z-]*[a-z])\b")
CODE_SPAN = re.compile(r"`([^`]+)`")
OPTION = re.compile(r"(?<![\w-])(--[a-z0-9][a-z0-9-]*)")
# options of the tools the docs also show (mkdocs, pytest, make's variables are not options)
TOOLS = {"--strict", "--site-dir", "--help", "--version"}


def help_options(command: str) -> set[str]:
    """The long options ``workbench COMMAND --help`` lists (``command``: e.g. "calibrate check")."""
    out = subprocess.run(
        [sys.executable, "-m", "workbench", *command.split(), "--help"],
        capture_output=True,
        text=True,
        cwd=ROOT,
        check=True,
    ).stdout
    return set(OPTION.findall(out)) | {"--help"}


def script_options() -> set[str]:
    """Every long option the benchmarks' and fixtures' scripts mention (their own command lines)."""
    found: set[str] = set()
    for path in [*ROOT.glob("benchmarks/*.py"), *ROOT.glob("fixtures/*.py"), *ROOT.glob("calib/*.py")]:
        found |= set(OPTION.findall(path.read_text(encoding="utf-8")))
    return found


def check_page(path: Path, options: dict[str, set[str]], known: set[str]) -> list[str]:
    """Findings on one Markdown page: ``options`` per command, ``known`` every option allowed at all."""
    findings = []
    rel = path.relative_to(ROOT)
    fence, last, prev = False, None, ""
    for n, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1):
        if line.startswith("```"):
            fence, last, prev = not fence, None, ""
            continue
        # commands are read where the docs show them as code: a code block's line, an inline span
        spans = [line] if fence else CODE_SPAN.findall(line)
        named_any = False
        for span in spans:
            named = list(NAMED.finditer(span))
            named_any = named_any or bool(named)
            for i, m in enumerate(named):
                command = m.group(1)
                if command in ("calibrate", "store"):  # the group itself, as in "workbench calibrate: ..."
                    continue
                if command not in options:
                    findings.append(f"{rel}:{n}: no command workbench {command}")
                    last = None
                    continue
                end = named[i + 1].start() if i + 1 < len(named) else len(span)
                for o in OPTION.findall(span[m.end() : end].split(" #")[0]):
                    if o not in options[command]:
                        findings.append(f"{rel}:{n}: workbench {command} has no option {o}")
                last = command if fence else None
        # a synopsis or a command continued on the next lines of its code block
        if fence and last and not named_any and (line.startswith(" ") or prev.rstrip().endswith("\\")):
            for o in OPTION.findall(line.split(" #")[0]):
                if o not in options[last]:
                    findings.append(f"{rel}:{n}: workbench {last} has no option {o}")
        for o in OPTION.findall(line):
            if o not in known:
                findings.append(f"{rel}:{n}: {o} is no option of any command or script")
        prev = line
    return findings


def main() -> None:
    options = {c: help_options(c) for c in COMMANDS}
    known = set().union(*options.values()) | script_options() | TOOLS
    pages = [ROOT / "README.md", *sorted((ROOT / "docs").rglob("*.md"))]
    findings = [f for page in pages for f in check_page(page, options, known)]
    for f in findings:
        print(f)
    print(f"check_options: {len(pages)} pages, {len(findings)} findings", file=sys.stderr)
    sys.exit(1 if findings else 0)


if __name__ == "__main__":
    main()
