"""How kinegen knows a file is its own, and text from users made safe to stand inside generated code.

**The trust store.** kinegen keeps, in a folder of the user's that is not beside the files
(``$KINEGEN_TRUST``, default ``$XDG_DATA_HOME/kinegen/trusted`` or ``~/.local/share/kinegen/trusted``),
the SHA-256 of every file it wrote or verified: generated modules and their C (written by
``kinegen build``), compiled libraries and object files (written by the runtime's compiler). A file
is kinegen's own when its bytes' digest is in the store, or -- a generated module from elsewhere,
e.g. a fresh clone's ``generated/`` -- when kinegen regenerates it from the model it names and gets
the same bytes (generation is byte-reproducible); the digest is then remembered, so each content is
verified once. Anything else is refused before a byte of it runs or is loaded: an edited or planted
module, C file or library, whatever hash stands beside it or inside it. The store also remembers,
per model version, parametrization and options, the digest of the module kinegen writes for them
(:func:`remember_expected`), so a second changed copy is refused without regenerating.

What it does not protect against: another program running as the same user (it can write the
store, the cache or kinegen itself), and a library swapped between its check and ``dlopen``.

Strings that come from a user (a model file's name, names, descriptions) reach generated code
only as escaped literals: :func:`comment_text` for docstrings and C comments (nothing that can
close them, start an escape of the language or form a C trigraph), :func:`c_string` for C string
literals. Python string literals are ``repr``, which is safe by construction.
"""

from __future__ import annotations

import fcntl
import functools
import hashlib
import os
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

#: digests this process knows to be kinegen's (the store read once per digest)
_KNOWN: set[str] = set()
#: characters a comment or docstring may show as they are; every other one is escaped
_PLAIN = frozenset("abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789 _.,:;+-=()[]{}<>@#%&!~^|$")


def trust_folder() -> Path:
    """The trust store: ``$KINEGEN_TRUST``, else ``$XDG_DATA_HOME/kinegen/trusted``, else ``~/.local/share/kinegen/trusted``."""
    if os.environ.get("KINEGEN_TRUST"):
        return Path(os.environ["KINEGEN_TRUST"])
    data = os.environ.get("XDG_DATA_HOME") or str(Path.home() / ".local" / "share")
    return Path(data) / "kinegen" / "trusted"


def digest(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


def _entry(name: str) -> Path:
    return trust_folder() / name[:2] / name


def remember(data: bytes) -> str:
    """Record ``data`` (a file's bytes) as kinegen's own; returns its digest. Where the store cannot
    be written (a read-only home) the digest is remembered for this process only."""
    key = digest(data)
    _KNOWN.add(key)
    _write(_entry(key), "")
    return key


def trusted(data: bytes) -> bool:
    """Whether ``data`` (a file's bytes) are kinegen's own: written or verified by it before, or
    shipped with the installed kinegen (:func:`shipped`)."""
    key = digest(data)
    if key in _KNOWN:
        return True
    if _entry(key).is_file() or key in shipped():
        _KNOWN.add(key)
        return True
    return False


def trusted_file(path: Path) -> bytes | None:
    """The bytes of a file kinegen keeps in its cache (compiled code, a model read before) when the
    store knows them: None for a missing or unreadable file and for bytes kinegen did not write."""
    try:
        data = path.read_bytes()
    except OSError:
        return None
    return data if trusted(data) else None


def keep_file(path: Path, data: bytes) -> None:
    """Write ``data`` to ``path`` in kinegen's cache, atomically, and record it as kinegen's own
    (:func:`trusted_file` then gives it back); a cache that cannot be written is passed by."""
    from kinegen.files import write_atomic

    try:
        write_atomic(path, data)
        remember(data)
    except OSError:
        pass


def shipped_folder() -> Path:
    """Where an installed wheel keeps the generated modules it ships (``kinegen/generated``; a clone
    has none there: its ``generated/`` is the user's, verified like any other)."""
    import kinegen

    return Path(kinegen.__file__).resolve().parent / "generated"


def shipped_files() -> list[Path]:
    """The generated modules and C files an installed wheel ships (:func:`shipped_folder`; none in a clone)."""
    folder = shipped_folder()
    if not folder.is_dir():
        return []
    return sorted(p for p in folder.iterdir() if p.suffix in (".py", ".c", ".h") and p.name != "__init__.py" and p.is_file())


@functools.cache
def shipped() -> frozenset[str]:
    """The digests of the generated files shipped inside the installed kinegen package: as much
    kinegen's own as its code beside them (whoever can change them can change kinegen)."""
    return frozenset(digest(p.read_bytes()) for p in shipped_files())


def expected_key(*parts: str) -> str:
    """The store's name for what kinegen writes for ``parts`` (model digest, parametrization, options, version)."""
    return "expected-" + digest("\n".join(parts).encode())


def remember_expected(key: str, module_digest: str) -> None:
    """Record that kinegen writes the module of digest ``module_digest`` for ``key`` (:func:`expected_key`)."""
    _write(_entry(key), module_digest)


def expected(key: str) -> str | None:
    """The digest of the module kinegen writes for ``key``, if recorded."""
    try:
        return _entry(key).read_text().strip() or None
    except OSError:
        return None


@contextmanager
def locked(name: str) -> Iterator[None]:
    """Hold the store's lock ``name`` (one process at a time verifies one thing; where the store
    cannot be written, no lock)."""
    try:
        folder = trust_folder()
        folder.mkdir(parents=True, exist_ok=True, mode=0o700)
        handle = open(folder / f".{name}.lock", "a")
    except OSError:
        yield
        return
    with handle:
        fcntl.flock(handle, fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(handle, fcntl.LOCK_UN)


def _write(path: Path, text: str) -> None:
    """Write a store entry atomically (a private temporary file, then a rename); silently nothing
    where the store cannot be written."""
    try:
        path.parent.mkdir(parents=True, exist_ok=True, mode=0o700)
        temporary = path.with_name(f".{path.name}.{os.getpid()}.tmp")
        temporary.write_text(text)
        os.replace(temporary, path)
    except OSError:
        pass


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
