"""Text as each medium can show it: a page or a figure, one line of a terminal, ASCII."""

from __future__ import annotations

import codecs
import unicodedata


def printable(text: str) -> str:
    """``text`` as a page, a figure or a terminal can show it.

    A file name whose bytes are not UTF-8 (``Teil \\xfc`` made under a Latin-1 locale) reaches
    Python with each such byte as a lone surrogate, which no encoder, font or PDF takes:
    each becomes U+FFFD, the replacement character.
    """
    if text.isascii():
        return text
    return text.encode("utf-8", "surrogateescape").decode("utf-8", "replace")


def one_line(text: str) -> str:
    """``text`` as one line: a newline, a tab or another control character (a file name may hold one) as its escape."""
    text = printable(text)
    if text.isprintable():
        return text
    return "".join(ch if ch.isprintable() else ch.encode("unicode_escape").decode("ascii") for ch in text)


# ASCII spellings of the characters the command's messages use, for a terminal that cannot show them
# fmt: off
_SPELLINGS = {
    "²": "2", "³": "3", "°": " deg", "×": "x", "·": ".", "±": "+/-", "µ": "u", "μ": "u",
    "Δ": "d", "σ": "sigma", "θ": "theta", "—": "-", "–": "-", "−": "-", "…": "...",
    "→": "->", "←": "<-", "≥": ">=", "≤": "<=", "≈": "~", "≠": "!=", "✓": "ok", "✗": "x",
    "‘": "'", "’": "'", "“": '"', "”": '"', "•": "*",
}
# fmt: on


def _ascii_spelling(exc: UnicodeError) -> tuple[str, int]:
    """``codecs`` error handler: each character the stream cannot encode, spelled in ASCII."""
    if not isinstance(exc, UnicodeEncodeError):
        raise exc
    out = []
    for ch in exc.object[exc.start : exc.end]:
        if ch in _SPELLINGS:
            out.append(_SPELLINGS[ch])
            continue
        # a letter with an accent keeps its letter (ü → u); anything else is a "?"
        plain = unicodedata.normalize("NFKD", ch).encode("ascii", "ignore").decode()
        out.append(plain or "?")
    return "".join(out), exc.end


# the name of the handler, for ``str.encode(..., errors=)`` and a stream's ``reconfigure``
ASCII_ERRORS = "workbench-ascii"
codecs.register_error(ASCII_ERRORS, _ascii_spelling)


def ascii_text(text: str) -> str:
    """``text`` in ASCII, each other character spelled (``mm²`` as ``mm2``, ``ü`` as ``u``), or ``?``.

    OpenCV's fonts draw ASCII only, and crash on a lone surrogate (a file name's undecodable byte).
    """
    return text if text.isascii() else text.encode("ascii", ASCII_ERRORS).decode("ascii")
