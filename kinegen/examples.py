"""The example models shipped with kinegen: the repository's ``models/`` folder.

A wheel installs them as ``kinegen/models/*.yaml`` (package data, mapped in ``setup.py``); a clone
or an editable install has them in ``models/`` beside the ``kinegen`` package. Either way
:func:`models_folder` finds them, so the main job (``python -m kinegen.demo``) and
``kinegen models --copy DIR`` work outside a clone.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import kinegen
from kinegen.errors import KinegenError
from kinegen.files import write_atomic

#: A file every copy of the examples holds (the main job's model).
MARKER = "excavator.yaml"


def models_folder() -> Path:
    """The folder of the shipped example models: ``kinegen/models`` of an installed wheel, else
    the clone's ``models/`` beside the package (editable install)."""
    package = Path(kinegen.__file__).resolve().parent
    for candidate in (package / "models", package.parent / "models"):
        if (candidate / MARKER).is_file():
            return candidate
    raise KinegenError(
        f"kinegen's example models are not installed (no {package / 'models' / MARKER} and no "
        f"{package.parent / 'models' / MARKER}): reinstall kinegen, or use a clone's models/ folder"
    )


def example_models() -> list[Path]:
    """The shipped model files, sorted by name."""
    return sorted(models_folder().glob("*.yaml"))


def place_shipped_modules(destination: Path) -> int:
    """Copy the generated modules an installed wheel ships (``kinegen/generated``: the committed
    ones of the shipped models) into ``destination`` where it has none of that name, so that the
    main job outside a clone loads them instead of building them again (the runtime trusts them: see
    :func:`kinegen.integrity.shipped`; a stale one is rebuilt by the usual rule). Returns how many
    were copied (none in a clone, which ships nothing there)."""
    from kinegen.integrity import shipped_files

    copied = 0
    for source in shipped_files():
        target = destination / source.name
        if not target.exists():
            write_atomic(target, source.read_bytes())
            copied += 1
    return copied


@dataclass(frozen=True)
class Summary:
    """What ``kinegen models`` lists of a shipped model: read from its YAML as written (a shipped
    model is valid: the tests load every one), without parsing its expressions."""

    path: Path
    bodies: int
    cases: tuple[str, ...]
    description: str


def summary(path: Path) -> Summary:
    """The :class:`Summary` of the shipped model file at ``path`` (LibYAML's parser where installed)."""
    import yaml

    document = yaml.load(path.read_text(encoding="utf-8"), Loader=getattr(yaml, "CSafeLoader", yaml.SafeLoader))
    cases = document.get("cases") or {"default": None}
    return Summary(path, len(document.get("bodies") or {}), tuple(cases), " ".join(str(document.get("description", "")).split()))


@dataclass(frozen=True)
class Copied:
    """One file of :func:`copy_models`: where it went and what happened (``written``, ``same``:
    already there, identical; ``kept``: already there and different, left alone)."""

    path: Path
    outcome: str


def copy_models(destination: Path, overwrite: bool = False) -> list[Copied]:
    """Copy every shipped model into ``destination`` (created if missing). A file already there
    that differs is kept unless ``overwrite``: a user's edited model is never lost silently."""
    if destination.exists() and not destination.is_dir():
        raise KinegenError(f"{destination} is a file, not a folder: give a folder to copy the models into")
    copied = []
    for source in example_models():
        target = destination / source.name
        data = source.read_bytes()
        if target.is_file() and target.read_bytes() == data:
            copied.append(Copied(target, "same"))
        elif target.exists() and not overwrite:
            copied.append(Copied(target, "kept"))
        else:
            write_atomic(target, data)
            copied.append(Copied(target, "written"))
    return copied
