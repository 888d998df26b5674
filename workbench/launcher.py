"""The ``workbench`` launcher: the command's script, holding Ctrl-C and SIGTERM from its first instruction.

Python's own start, before any of the workbench's code runs, takes about 40 ms (the
interpreter, ``site``, an editable install's finder); a signal then ends the process in
Python's way (a ``KeyboardInterrupt`` traceback, or killed by SIGTERM with no word). Handlers
cannot be installed earlier than Python runs code, but signals can be *blocked* earlier, and a
blocked signal waits: the signal mask survives ``exec``. GNU coreutils' ``env`` blocks them
(``--block-signal``, coreutils 8.31 and newer) and then starts Python, so a signal in Python's
start waits until :func:`workbench.interrupts.take_signals_early` has its handler in place
and unblocks them: it is then reported as any interrupt is (exit 130, one line).

``make install`` rewrites the script pip made (``python -m workbench.launcher SCRIPT``) where
``env`` can do this; elsewhere pip's script stays as it is.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

ENV = "/usr/bin/env"
BLOCK = "--block-signal=INT --block-signal=TERM"
# Linux reads at most this many bytes of a script's first line (BINPRM_BUF_SIZE, 256 with the
# newline since 5.1; 128 before): a longer one is cut and names a program that does not exist
MAX_SHEBANG = 127


def env_blocks_signals(env: str = ENV) -> bool:
    """Whether ``env`` can start a program with signals blocked (GNU coreutils 8.31 or newer).

    Parameters
    ----------
    env : str
        Path of the ``env`` program.

    Returns
    -------
    bool
    """
    try:
        done = subprocess.run([env, "--block-signal=INT", "true"], capture_output=True, timeout=10, check=False)
    except (OSError, subprocess.SubprocessError):
        return False
    return done.returncode == 0


def launcher_text(python: str, body: str, env: str = ENV) -> str | None:
    """The script: a first line that starts ``python`` through ``env`` with Ctrl-C and SIGTERM blocked.

    Parameters
    ----------
    python : str
        Absolute path of the Python that runs the workbench.
    body : str
        The script's Python code (pip's script without its first line).
    env : str
        Path of the ``env`` program.

    Returns
    -------
    str or None
        The script's text; None where the first line cannot say it (a path that ``env -S``
        would read as more than a path, or a line longer than the kernel reads).
    """
    # env -S splits its argument at spaces and reads quotes, backslashes and ${...}: a path is
    # passed in double quotes, and one holding any of those characters is not written at all
    if any(c in python for c in "\"\\$\n'") or not python.startswith("/"):
        return None
    first = f'#!{env} -S {BLOCK} "{python}"'
    if len(first) > MAX_SHEBANG:
        return None
    return first + "\n" + body


def main(argv: list[str] | None = None) -> int:
    """Rewrite the script SCRIPT (pip's ``workbench``) as the launcher; nothing changes where it cannot be.

    Parameters
    ----------
    argv : list of str, optional
        ``[SCRIPT]``.

    Returns
    -------
    int
        0 (also when the script is left as it is, which the line printed says).
    """
    argv = sys.argv[1:] if argv is None else argv
    if len(argv) != 1:
        print("usage: python -m workbench.launcher SCRIPT", file=sys.stderr)
        return 2
    script = Path(argv[0])
    text = script.read_text(encoding="utf-8")
    first, _, body = text.partition("\n")
    if first.startswith(f"#!{ENV} -S {BLOCK}"):
        return 0  # (already the launcher)
    new = launcher_text(sys.executable, body) if env_blocks_signals() else None
    if new is None:
        print(f"{script}: left as pip wrote it (env cannot block signals here, or the path cannot be said)")
        return 0
    tmp = script.with_name(script.name + ".launcher-tmp")
    tmp.write_text(new, encoding="utf-8")
    tmp.chmod(script.stat().st_mode)
    tmp.replace(script)
    return 0


if __name__ == "__main__":
    sys.exit(main())
