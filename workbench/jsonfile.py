"""Reading JSON input files with errors that name the file."""

from __future__ import annotations

import json
from pathlib import Path

from workbench.errors import WorkbenchError


def read_json(path: str | Path, what: str) -> dict:
    """A JSON object from a file.

    Parameters
    ----------
    path : str or Path
        The file.
    what : str
        What it should be ("camera file", "printer profile"), for messages.

    Returns
    -------
    dict

    Raises
    ------
    WorkbenchError
        Missing, not JSON, or not an object; names the file.
    """
    path = Path(path)
    if not path.is_file():
        raise WorkbenchError(f"{path}: no such {what}")
    try:
        data = json.loads(path.read_text())
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise WorkbenchError(f"{path}: not a JSON {what}: {exc}") from None
    if not isinstance(data, dict):
        raise WorkbenchError(f"{path}: a {what} is a JSON object")
    return data
