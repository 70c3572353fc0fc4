"""A plain install runs its own copy of the scenarios: the commands that write the repository's
scenarios/ refuse that copy, one line and exit code 2, before anything runs.

The two layouts are built for real: the package as a wheel unpacks it (``twin/`` with the
scenarios as ``twin/config/scenarios`` and the FMU sources as ``twin/fmu/sources``, see
pyproject.toml), and as a checkout (``src/twin`` beside ``scenarios/``). .ci/run repeats the
refusals on a real ``pip install .``.
"""

from __future__ import annotations

import hashlib
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from twin.config.load import check_not_installed_copy, installed_scenarios
from twin.errors import ConfigError

ROOT = Path(__file__).resolve().parents[1]
IGNORE = shutil.ignore_patterns("__pycache__", "*.pyc")


def _wheel_layout(where: Path) -> Path:
    """``twin`` as ``pip install .`` puts it in site-packages; returns the folder to import from."""
    site = where / "site"
    shutil.copytree(ROOT / "src" / "twin", site / "twin", ignore=IGNORE)
    shutil.copytree(ROOT / "scenarios", site / "twin" / "config" / "scenarios", ignore=IGNORE)
    shutil.copytree(ROOT / "fmus", site / "twin" / "fmu" / "sources", ignore=IGNORE)
    return site


def _checkout_layout(where: Path) -> Path:
    """``src/twin`` beside ``scenarios/``, as an editable install imports it."""
    checkout = where / "checkout"
    shutil.copytree(ROOT / "src" / "twin", checkout / "src" / "twin", ignore=IGNORE)
    shutil.copytree(ROOT / "scenarios", checkout / "scenarios", ignore=IGNORE)
    return checkout / "src"


def _twin(path: Path, cwd: Path, *argv: str) -> subprocess.CompletedProcess[str]:
    env = {**os.environ, "PYTHONPATH": str(path), "TWIN_CACHE_DIR": str(cwd / "cache")}
    env.pop("TWIN_FMU_SOURCES", None)
    return subprocess.run(
        [sys.executable, "-m", "twin", *argv], cwd=cwd, env=env, capture_output=True, text=True, timeout=300
    )


def _digest(folder: Path) -> str:
    h = hashlib.sha256()
    for p in sorted(folder.rglob("*")):
        if p.is_file():
            h.update(str(p.relative_to(folder)).encode() + b"\0" + p.read_bytes())
    return h.hexdigest()


def test_a_target_inside_the_installed_copy_is_refused_with_its_option(tmp_path: Path) -> None:
    copy = tmp_path / "site" / "twin" / "config" / "scenarios"
    (copy / "records").mkdir(parents=True)
    with pytest.raises(ConfigError) as err:
        check_not_installed_copy(copy / "records" / "li2017-updated.toml", "--write", installed=copy)
    assert err.value.source == "--write"
    assert "pip install -e ." in str(err.value) and "\n" not in str(err.value)
    # the folder itself (twin geometry writes into it) and a link into it are the copy too
    with pytest.raises(ConfigError):
        check_not_installed_copy(copy, "--scenarios", installed=copy)
    (tmp_path / "link").symlink_to(copy / "records")
    with pytest.raises(ConfigError):
        check_not_installed_copy(tmp_path / "link" / "x.toml", "--write", installed=copy)
    # a lab's own file, elsewhere, is written as asked; one that is a link into the copy too,
    # since a file is written by replacing it in its folder (the link, not what it points to)
    lab = tmp_path / "lab"
    lab.mkdir()
    check_not_installed_copy(lab / "tester.toml", "--write", installed=copy)
    (copy / "records" / "li2017-updated.toml").write_text("")
    (lab / "linked.toml").symlink_to(copy / "records" / "li2017-updated.toml")
    check_not_installed_copy(lab / "linked.toml", "--write", installed=copy)
    # and the reverse: a link inside the copy that points to the lab's folder lands in the copy
    (copy / "records" / "out.toml").symlink_to(lab / "tester.toml")
    with pytest.raises(ConfigError):
        check_not_installed_copy(copy / "records" / "out.toml", "--write", installed=copy)


def test_this_process_finds_the_installed_copy_only_when_installed_plainly() -> None:
    """The twin the tests import: from the checkout (the editable install of the README's test
    command) it writes the repository's scenarios; from a plain install it has a copy."""
    import twin

    from_checkout = Path(twin.__file__).resolve().is_relative_to(ROOT / "src")
    assert (installed_scenarios() is None) == from_checkout


@pytest.fixture(scope="module")
def layouts(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    where = tmp_path_factory.mktemp("layouts")
    return {"wheel": _wheel_layout(where), "checkout": _checkout_layout(where)}


@pytest.mark.parametrize(
    ("layout", "expected"), [("wheel", "site/twin/config/scenarios"), ("checkout", None)]
)
def test_the_installed_copy_is_found_only_in_a_wheel_layout(
    layouts: dict[str, Path], tmp_path: Path, layout: str, expected: str | None
) -> None:
    code = "from twin.config.load import installed_scenarios as f; print(f())"
    env = {**os.environ, "PYTHONPATH": str(layouts[layout])}
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True)
    found = out.stdout.strip()
    if expected is None:
        assert found == "None"
    else:
        assert Path(found).resolve() == (layouts[layout].parent / expected).resolve()


@pytest.mark.parametrize(
    ("argv", "option"),
    [
        (("geometry",), "the scenarios folder (default; --scenarios DIR names another)"),
        (("calibrate", "--write"), "--write"),
        (("update", "--write", "--quiet"), "--write"),
    ],
)
def test_a_plain_install_refuses_to_write_its_own_copy(
    layouts: dict[str, Path], tmp_path: Path, argv: tuple[str, ...], option: str
) -> None:
    copy = layouts["wheel"] / "twin" / "config" / "scenarios"
    before = _digest(copy)
    proc = _twin(layouts["wheel"], tmp_path, *argv)
    assert proc.returncode == 2, proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"twin: {option}: "), proc.stderr
    assert "is in the installed copy of the scenarios" in lines[0] and "pip install -e ." in lines[0]
    assert _digest(copy) == before
    # refused before anything ran: no output folder, no built FMU
    assert sorted(p.name for p in tmp_path.iterdir()) == []


def test_a_checkout_writes_its_own_scenarios(layouts: dict[str, Path], tmp_path: Path) -> None:
    """The same command from a checkout writes the checkout's derived files (what the editable
    install does for a developer)."""
    scenarios = layouts["checkout"].parent / "scenarios"
    derived = scenarios / "base" / "geometry-thermal.toml"
    derived.unlink()
    proc = _twin(layouts["checkout"], tmp_path, "geometry")
    assert proc.returncode == 0, proc.stderr
    assert derived.read_bytes() == (ROOT / "scenarios" / "base" / "geometry-thermal.toml").read_bytes()
