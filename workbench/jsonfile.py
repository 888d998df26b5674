"""Reading JSON input files against a declared schema, with errors that name the file and the key.

Every JSON the workbench reads (camera profiles and files, printer profiles, board
definitions, ``fixture.json``, ``design.json``, render truths) is declared as a mapping
of key to :class:`Field` and checked by :func:`read_json` before any value is used: a
missing key, a wrong type, a wrong shape or a value out of range is one line,
``FILE: KEY: must be ..., got ...``, and later code can index the data without guards.
Keys a schema does not declare are left alone (files written by newer versions still
read).
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from workbench.errors import WorkbenchError

KINDS = ("number", "integer", "string", "bool", "array", "object", "list")


@dataclass(frozen=True)
class Field:
    """One key of a JSON object.

    Attributes
    ----------
    kind : {'number', 'integer', 'string', 'bool', 'array', 'object', 'list'}
        ``array``: numbers of a given ``shape``; ``object``: a nested object with
        ``fields``; ``list``: a list whose items are ``items``.
    required : bool
        A missing required key is an error; a missing optional one takes ``default``.
    default : object
        Value of a missing optional key.
    lo, hi : float, optional
        Inclusive bounds of a number, or of every entry of an array.
    shape : tuple, optional
        Shape of an array; ``None`` entries take any length (at least ``min_len``).
    integer : bool
        Every entry of an array must be a whole number.
    min_len : int
        Smallest length of a ``None`` axis of an array, or of a list.
    choices : tuple, optional
        Allowed values of a string.
    fields : mapping of str to Field, optional
        The keys of an ``object`` (and of each item of a ``list`` of objects).
    items : Field, optional
        The items of a ``list``.
    hint : str
        What the value means, added to messages ("printed length / intended length").
    """

    kind: str
    required: bool = True
    default: object = None
    lo: float | None = None
    hi: float | None = None
    shape: tuple | None = None
    integer: bool = False
    min_len: int = 0
    choices: tuple | None = None
    fields: Mapping[str, Field] | None = None
    items: Field | None = None
    hint: str = ""

    def __post_init__(self):
        if self.kind not in KINDS:
            raise ValueError(f"unknown field kind {self.kind!r}")


def _short(value: object) -> str:
    text = repr(value)
    return text if len(text) <= 60 else text[:57] + "..."


def _range(field: Field) -> str:
    if field.lo is not None and field.hi is not None:
        return f" from {field.lo:g} to {field.hi:g}"
    if field.lo is not None:
        return f" of at least {field.lo:g}"
    if field.hi is not None:
        return f" of at most {field.hi:g}"
    return ""


def _describe(field: Field) -> str:
    hint = f" ({field.hint})" if field.hint else ""
    if field.kind in ("number", "integer"):
        return f"{'an integer' if field.kind == 'integer' else 'a number'}{_range(field)}{hint}"
    if field.kind == "array":
        what = "whole numbers" if field.integer else "finite numbers"
        shape = field.shape or (None,)
        if shape == (None,):
            return f"a list of {what}{_range(field)}{hint}"
        dims = "x".join("n" if s is None else str(s) for s in shape)
        return f"{'an' if dims[0] == 'n' else 'a'} {dims} array of {what}{_range(field)}{hint}"
    if field.kind == "string" and field.choices:
        return f"one of {', '.join(field.choices)}{hint}"
    return {"string": "a string", "bool": "true or false", "object": "an object", "list": "a list"}[field.kind] + hint


def _in_range(values: np.ndarray, field: Field) -> bool:
    return bool((field.lo is None or (values >= field.lo).all()) and (field.hi is None or (values <= field.hi).all()))


def _shape_ok(shape: tuple, want: tuple, min_len: int) -> bool:
    return len(shape) == len(want) and all(
        (w is None and s >= min_len) or s == w for s, w in zip(shape, want, strict=True)
    )


def _check_value(value: object, field: Field, fail) -> object:
    """The value, checked against ``field``; ``fail(message)`` raises."""
    kind = field.kind
    if kind in ("number", "integer"):
        ok = isinstance(value, int | float) and not isinstance(value, bool)
        try:
            ok = ok and math.isfinite(float(value)) and (kind == "number" or float(value).is_integer())
        except OverflowError:  # an integer beyond any float
            ok = False
        if not ok or not _in_range(np.asarray(float(value)), field):
            fail(f"must be {_describe(field)}, got {_short(value)}")
        return int(value) if kind == "integer" else value
    if kind == "array":
        try:
            arr = np.asarray(value, dtype=np.float64)
        except (TypeError, ValueError, OverflowError):
            arr = None
        if (
            arr is None
            or isinstance(value, str | bool)
            or not _shape_ok(arr.shape, field.shape or (None,), field.min_len)
            or not np.isfinite(arr).all()
            or not _in_range(arr, field)
            or (field.integer and not (arr == np.round(arr)).all())
        ):
            fail(f"must be {_describe(field)}, got {_short(value)}")
        return value
    if kind == "string":
        if not isinstance(value, str) or (field.choices and value not in field.choices):
            fail(f"must be {_describe(field)}, got {_short(value)}")
        return value
    if kind == "bool":
        if not isinstance(value, bool):
            fail(f"must be {_describe(field)}, got {_short(value)}")
        return value
    if kind == "object":
        if not isinstance(value, dict):
            fail(f"must be {_describe(field)}, got {_short(value)}")
        return value
    # a list
    if not isinstance(value, list) or len(value) < field.min_len:
        fail(f"must be a list of at least {field.min_len} items, got {_short(value)}")
    return value


def check(data: dict, fields: Mapping[str, Field], path: str | Path, where: str = "") -> dict:
    """Check a JSON object against its fields, filling in the defaults of missing optional keys.

    Parameters
    ----------
    data : dict
        The object (changed in place: defaults are added).
    fields : mapping of str to Field
        Its declared keys.
    path : str or Path
        The file, for messages.
    where : str
        The object's own key path in the file ("print", "views[1].camera"), for messages.

    Returns
    -------
    dict
        ``data``.

    Raises
    ------
    WorkbenchError
        ``FILE: KEY: message`` for the first key at fault.
    """
    for key, field in fields.items():
        at = f"{where}.{key}" if where else key

        def fail(message: str, at: str = at):
            raise WorkbenchError(f"{path}: {at}: {message}")

        if key not in data or data[key] is None:
            if field.required:
                fail(f"missing ({_describe(field)})")
            data[key] = field.default
            continue
        value = _check_value(data[key], field, fail)
        data[key] = value
        if field.kind == "object" and field.fields:
            check(value, field.fields, path, at)
        elif field.kind == "list" and field.items is not None:
            for i, item in enumerate(value):
                item_at = f"{at}[{i}]"
                checked = _check_value(item, field.items, lambda m, a=item_at: fail(m, a))
                if field.items.kind == "object" and field.items.fields:
                    check(checked, field.items.fields, path, item_at)
    return data


def read_json(path: str | Path, what: str, fields: Mapping[str, Field] | None = None) -> dict:
    """A JSON object from a file, checked against its schema.

    Parameters
    ----------
    path : str or Path
        The file.
    what : str
        What it should be ("camera file", "printer profile"), for messages.
    fields : mapping of str to Field, optional
        The schema; without it only "a JSON object" is checked.

    Returns
    -------
    dict

    Raises
    ------
    WorkbenchError
        Missing, a directory, not JSON, not an object, or a key at fault; names the file (and key).
    """
    path = Path(path)
    if path.is_dir():
        raise WorkbenchError(f"{path}: is a directory, not a {what}")
    if not path.is_file():
        raise WorkbenchError(f"{path}: no such {what}")
    try:
        # NaN and Infinity are not JSON; Python's reader takes them, so the schema refuses them as not finite
        data = json.loads(path.read_bytes().decode("utf-8"))
    except (UnicodeDecodeError, json.JSONDecodeError, RecursionError) as exc:
        raise WorkbenchError(f"{path}: not a JSON {what}: {exc}") from None
    except OSError as exc:
        raise WorkbenchError(f"{path}: cannot read {what}: {exc.strerror or exc}") from None
    if not isinstance(data, dict):
        raise WorkbenchError(f"{path}: a {what} is a JSON object, got {type(data).__name__}")
    return check(data, fields, path) if fields else data


def recorded_path(path: str | Path, folder: str | Path) -> str:
    """``path`` as an output file in ``folder`` records it: relative to that folder, with ``/``.

    Relative, so that a folder moved or copied elsewhere (with its inputs beside it, or
    to another machine with the hashes recorded next to each path) still says what it was
    made from; absolute paths of the machine that made it would point nowhere.
    """
    return Path(os.path.relpath(os.path.realpath(path), os.path.realpath(folder))).as_posix()


def resolve_recorded(text: str, json_file: str | Path) -> Path:
    """A path recorded in a JSON file: relative to the file's folder, or absolute (older files)."""
    path = Path(text)
    return path if path.is_absolute() else Path(json_file).parent / path
