"""Seals on generated files, and text from users made safe to stand inside generated code.

A generated Python module or model C file begins with one line that records the SHA-256 of
the rest of the file (its UTF-8 bytes, from the byte after that line's newline to the end)::

    # kinegen: sha256 of the rest of this file: 3f1c...          (Python)
    /* kinegen: sha256 of the rest of this file: 3f1c... */      (C)

The runtime reads a file's bytes, checks the seal and only then compiles exactly those bytes
(:func:`verified_text`), so an edited coefficient, a truncated file or a module planted by
hand is refused before anything in it runs.

Strings that come from a user (a model file's name, names, descriptions) reach generated code
only as escaped literals: :func:`comment_text` for docstrings and C comments (nothing that can
close them, start an escape of the language or form a C trigraph), :func:`c_string` for C string
literals. Python string literals are ``repr``, which is safe by construction.
"""

from __future__ import annotations

import hashlib
import re
from pathlib import Path

SEAL_TEXT = "kinegen: sha256 of the rest of this file: "
_SEAL = {
    ".py": (f"# {SEAL_TEXT}", ""),
    ".c": (f"/* {SEAL_TEXT}", " */"),
    ".h": (f"/* {SEAL_TEXT}", " */"),
}
_SEAL_LINE = re.compile(rb"^(?:# |/\* )" + SEAL_TEXT.encode() + rb"([0-9a-f]{64})(?: \*/)?$")
#: characters a comment or docstring may show as they are; every other one is escaped
_PLAIN = frozenset("abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789 _.,:;+-=()[]{}<>@#%&!~^|$")


class SealError(ValueError):
    """A generated file's seal is missing or does not match its text (the message says which)."""


def seal(name: str, text: str) -> str:
    """``text`` of the generated file ``name`` (``.py``, ``.c`` or ``.h``) with its seal line first."""
    before, after = _SEAL[Path(name).suffix]
    digest = hashlib.sha256(text.encode("utf-8")).hexdigest()
    return f"{before}{digest}{after}\n{text}"


def sealed(name: str) -> bool:
    """Whether kinegen seals files of this kind (by their suffix)."""
    return Path(name).suffix in _SEAL


def verified_text(data: bytes, where: str) -> str:
    """The text of a sealed file's bytes ``data`` (seal line included), after checking the seal;
    :class:`SealError` naming ``where`` when it is missing, malformed or does not match."""
    first, newline, rest = data.partition(b"\n")
    match = _SEAL_LINE.match(first.rstrip(b"\r"))
    if not newline or match is None:
        raise SealError(f"{where}: no kinegen seal on its first line (not written by this kinegen, or edited)")
    if hashlib.sha256(rest).hexdigest() != match.group(1).decode():
        raise SealError(f"{where}: its text does not match its seal (edited or truncated since kinegen wrote it)")
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as exc:  # cannot happen for a matching seal over kinegen's own UTF-8 output
        raise SealError(f"{where}: not UTF-8 text ({exc})") from None


def comment_text(text: object) -> str:
    """``text`` as it may stand in a Python docstring or a C block comment: letters, digits and
    harmless punctuation kept; everything else -- quotes, backslashes, ``*``, ``/``, ``?``, control
    characters, newlines, non-ASCII -- written as ``\\xHH``, ``\\uHHHH`` or ``\\UHHHHHHHH``."""
    out = []
    for character in str(text):
        if character in _PLAIN:
            out.append(character)
            continue
        code = ord(character)
        out.append(f"\\x{code:02x}" if code < 0x100 else f"\\u{code:04x}" if code < 0x10000 else f"\\U{code:08x}")
    return "".join(out)


def c_string(text: object) -> str:
    """A C string literal of ``text``: its UTF-8 bytes, printable ASCII kept except the quote, the
    backslash and ``?`` (trigraphs), every other byte as a three-digit octal escape (which, unlike
    ``\\x``, cannot run on into the next character)."""
    out = ['"']
    for byte in str(text).encode("utf-8"):
        character = chr(byte)
        out.append(character if 0x20 <= byte < 0x7F and character not in '"\\?' else f"\\{byte:03o}")
    out.append('"')
    return "".join(out)
