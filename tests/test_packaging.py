"""kinegen as a user installs it: the wheel carries the example models, and the package runs
from the wheel in a folder that is not a clone (no models/, no generated/ there)."""

from __future__ import annotations

import hashlib
import os
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

from kinegen.examples import copy_models, example_models, models_folder
from tests.conftest import MODELS

ROOT = MODELS.parent


@pytest.fixture(scope="module")
def wheel(tmp_path_factory) -> Path:
    """kinegen's wheel, built by pip from this clone's files (the build backend as `pip install` gets it)."""
    folder = tmp_path_factory.mktemp("wheel")
    source = folder / "source"
    files = subprocess.run(["git", "ls-files", "-z", "--cached", "--others", "--exclude-standard"], cwd=ROOT, capture_output=True, check=True).stdout.decode().split("\0")
    for name in filter(None, files):  # the clone's files, not what .gitignore leaves out (.venv/, out/, caches)
        if (ROOT / name).is_file():
            (source / name).parent.mkdir(parents=True, exist_ok=True)
            (source / name).write_bytes((ROOT / name).read_bytes())
    done = subprocess.run(
        [sys.executable, "-m", "pip", "wheel", "--no-deps", "--quiet", "--wheel-dir", str(folder / "dist"), str(source)],
        capture_output=True, text=True, timeout=600,
    )  # fmt: skip
    assert done.returncode == 0, done.stderr[-3000:]
    (built,) = (folder / "dist").glob("kinegen-*.whl")
    return built


def test_the_wheel_carries_every_model_and_the_code_generator_templates(wheel):
    names = set(zipfile.ZipFile(wheel).namelist())
    for path in (ROOT / "generated").iterdir():  # the main job's committed modules too
        if path.suffix in (".py", ".c", ".h"):
            assert zipfile.ZipFile(wheel).read(f"kinegen/generated/{path.name}") == path.read_bytes()
    for path in MODELS.glob("*.yaml"):
        assert f"kinegen/models/{path.name}" in names
        assert zipfile.ZipFile(wheel).read(f"kinegen/models/{path.name}") == path.read_bytes()
    packages = {p.relative_to(ROOT).as_posix() for p in (ROOT / "kinegen").rglob("*.py") if "__pycache__" not in p.parts}
    assert packages <= names, sorted(packages - names)
    for template in ("kinegen/codegen/backends/c/solver/kinegen_solver.c", "kinegen/codegen/backends/python/templates"):
        assert any(n.startswith(template) for n in names), template


def test_the_installed_package_finds_its_models_and_solves_outside_a_clone(wheel, tmp_path):
    """The wheel unpacked on the import path, run in an empty folder: the main job's folders are
    the shipped models and out/generated; `kinegen models` lists them; `kinegen solve` builds and
    solves the paper's boom from the shipped file."""
    site = tmp_path / "site"
    zipfile.ZipFile(wheel).extractall(site)
    work = tmp_path / "elsewhere"
    work.mkdir()
    env = dict(os.environ, PYTHONPATH=str(site))

    def python(code: str) -> str:
        done = subprocess.run([sys.executable, "-c", code], cwd=work, env=env, capture_output=True, text=True, timeout=600)
        assert done.returncode == 0, done.stdout + done.stderr
        return done.stdout

    where = python(
        "from pathlib import Path; import kinegen; from kinegen.demo import folders\n"
        "models, generated = folders(None, None, Path('out'))\n"
        "print(kinegen.__file__); print(models); print(generated)"
    ).splitlines()
    assert Path(where[0]).is_relative_to(site) and Path(where[1]) == site / "kinegen" / "models"
    assert where[2] == os.path.join("out", "generated")
    listing = python("from kinegen.cli import main; main(['models'], standalone_mode=False)")
    assert str(site / "kinegen" / "models") in listing and "excavator.yaml" in listing and "cases: digging" in listing
    boom = site / "kinegen" / "models" / "boom.yaml"
    python(
        "from kinegen.cli import main\n"
        f"main(['solve', {str(boom)!r}, '--generated-dir', 'out/generated', '--out', 'out/boom.csv', '--no-compile'], standalone_mode=False)"
    )
    assert (work / "out" / "generated" / "boom_quaternion.py").is_file()
    rows = (work / "out" / "boom.csv").read_text().splitlines()
    assert len(rows) > 10 and not (work / "models").exists() and not (work / "generated").exists()
    # the main job's modules travel with the wheel: placed in out/generated and loaded as they are, not built
    # again (a fresh trust store: the runtime trusts them as kinegen's own because the installed package ships them)
    env["KINEGEN_TRUST"], env["KINEGEN_CACHE"] = str(tmp_path / "trust"), str(tmp_path / "cache")
    placed = python(
        "from pathlib import Path; from kinegen.examples import place_shipped_modules; from kinegen.api import Session\n"
        "out = Path('out/shipped'); n = place_shipped_modules(out)\n"
        "module = Session(out).module(Path(" + repr(str(site / "kinegen" / "models" / "excavator.yaml")) + "), 'quaternion')\n"
        "print(n, module.__file__)"
    ).split()
    shipped = sorted(p.name for p in (ROOT / "generated").iterdir() if p.suffix in (".py", ".c", ".h"))
    assert int(placed[0]) == len(shipped) and Path(placed[1]).name == "excavator_quaternion.py"
    assert (work / "out" / "shipped" / "excavator_quaternion.py").read_bytes() == (ROOT / "generated" / "excavator_quaternion.py").read_bytes()
    # nothing built or verified by building it again: either would have recorded the module's digest (or what a
    # build writes) in the trust store; the store holds only the digests of what the cache keeps: the module's
    # compiled code and the model as read (kinegen.model.kept)
    recorded = {p.name for p in (tmp_path / "trust").rglob("*") if p.is_file() and not p.name.startswith(".")}
    code = {hashlib.sha256(p.read_bytes()).hexdigest() for p in (tmp_path / "cache" / "bytecode").rglob("*.marshal")}
    models = {hashlib.sha256(p.read_bytes()).hexdigest() for p in (tmp_path / "cache" / "models").rglob("*.pickle")}
    assert recorded == code | models and len(code) == 1 and len(models) == 1


def test_the_main_job_finds_the_models_of_the_clone_or_says_where_they_must_be(tmp_path, monkeypatch, capsys):
    from kinegen.demo import folders
    from kinegen.demo import main as demo

    assert models_folder() == MODELS.resolve()  # an editable install: the clone's models/
    monkeypatch.chdir(ROOT)
    assert folders(None, None, Path("out")) == (Path("models"), Path("generated"))
    monkeypatch.chdir(tmp_path)
    assert folders(None, None, Path("out")) == (MODELS.resolve(), Path("out") / "generated")
    with pytest.raises(SystemExit) as exit_:
        demo(["--models", str(tmp_path / "models"), "--generated", str(tmp_path / "generated")])
    assert exit_.value.code == 2
    assert "kinegen models --copy DIR" in capsys.readouterr().err
    assert not (tmp_path / "generated").exists()


def test_copying_the_models_never_replaces_an_edited_file_unless_asked(tmp_path):
    target = tmp_path / "mine"
    assert {c.outcome for c in copy_models(target)} == {"written"}
    assert sorted(p.name for p in target.iterdir()) == [p.name for p in example_models()]
    edited = target / "boom.yaml"
    edited.write_text(edited.read_text() + "# my note\n")
    outcomes = {c.path.name: c.outcome for c in copy_models(target)}
    assert outcomes["boom.yaml"] == "kept" and outcomes["excavator.yaml"] == "same"
    assert edited.read_text().endswith("# my note\n")
    assert {c.path.name: c.outcome for c in copy_models(target, overwrite=True)}["boom.yaml"] == "written"
    assert edited.read_bytes() == (MODELS / "boom.yaml").read_bytes()
