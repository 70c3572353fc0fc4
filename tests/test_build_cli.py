"""`twin build`: builds every FMU; without the tools it says what to install, exit code 2."""

from __future__ import annotations

import os
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

from twin.cli import main
from twin.fmu.build import source_hash
from twin.fmu.catalog import model_names, sources_dir


def test_build_writes_every_fmu_into_out(tmp_path: Path, capsys) -> None:
    assert main(["build", "--out", str(tmp_path)]) == 0
    for model in model_names():
        fmu = tmp_path / f"{model}.fmu"
        assert f"binaries/linux64/{model}.so" in zipfile.ZipFile(fmu).namelist()
    out, err = capsys.readouterr()
    assert "ThermalNetwork" in out
    # issue 33: one line per model, without a terminal too (a first build was 16 s of silence)
    assert err.splitlines() == [f"twin: building FMU {m} (first use of its sources)" for m in model_names()]


def test_missing_compiler_and_cmake_give_one_line_and_exit_2(tmp_path: Path) -> None:
    env = {k: v for k, v in os.environ.items() if k != "CC"}
    env["PATH"] = str(tmp_path)  # nothing on PATH: no cc, no cmake
    proc = subprocess.run(
        [sys.executable, "-m", "twin", "build", "--out", str(tmp_path / "out")],
        env=env,
        capture_output=True,
        text=True,
        check=False,
    )
    assert proc.returncode == 2
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in proc.stderr
    assert "install" in lines[0]


def test_source_hash_changes_with_any_source(tmp_path: Path) -> None:
    import shutil

    copy = tmp_path / "fmus"
    shutil.copytree(sources_dir(), copy)
    before = source_hash("ThermalNetwork", copy)
    (copy / "common" / "linalg.c").write_text(
        (copy / "common" / "linalg.c").read_text() + "\n/* changed */\n"
    )
    assert source_hash("ThermalNetwork", copy) != before


def test_bad_command_line_gives_exit_2(capsys) -> None:
    assert main(["no-such-command"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("twin: ")


@pytest.mark.parametrize(
    "argv, words",
    [
        (["run", "--no-such-option"], "unrecognized arguments"),
        (["run", "--checkpoint-every", "soon"], "--checkpoint-every"),
        (["run", "--checkpoint-every", "0.05 s"], "multiple of scenario.step"),
        (["run", "no/such/scenario.toml"], "file not found"),
        (["run", "--set", "scenario.duration"], "expected KEY=VALUE"),
        (["run", "--set", 'scenario.duration="-3 min"'], "scenario.duration"),
        (["validate"], "scenario"),
        (["resume", "no/such/run"], "run.json"),
    ],
)
def test_bad_arguments_give_one_line_and_exit_2(argv: list[str], words: str, capsys) -> None:
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("twin: ") and words in err[0], err


def test_a_broken_c_compiler_gets_one_line_saying_what_to_install(tmp_path: Path) -> None:
    # issue 14: not a multi-line cmake dump; the dump goes to a log file the line names
    env = {**os.environ, "CC": "/bin/false", "TWIN_CACHE_DIR": str(tmp_path / "cache")}
    r = subprocess.run(
        [sys.executable, "-c", "import sys; from twin.cli import console; sys.exit(console())", "build"],
        capture_output=True, text=True, env=env, timeout=300,
    )  # fmt: skip
    assert r.returncode == 1
    lines = [ln for ln in r.stderr.strip().splitlines() if not ln.startswith("twin: building FMU ")]
    assert len(lines) == 1 and "Traceback" not in r.stderr, r.stderr
    assert "cannot compile a test program" in lines[0] and "apt-get install -y gcc" in lines[0]
    log = tmp_path / "cache" / "last-build-error.log"
    assert str(log) in lines[0] and "CMAKE" in log.read_text().upper()


def _path_with(tmp_path: Path, tools: list[str]) -> str:
    """A PATH holding only ``tools`` (links to the real ones) and cmake."""
    import shutil

    bin_dir = tmp_path / "bin"
    bin_dir.mkdir()
    for tool in [*tools, "cmake"]:
        real = shutil.which(tool)
        assert real, f"{tool} must be installed for this test"
        (bin_dir / tool).symlink_to(real)
    return str(bin_dir)


def _build_with_path(tmp_path: Path, path: str) -> subprocess.CompletedProcess[str]:
    env = {k: v for k, v in os.environ.items() if k not in ("CC", "CXX", "CMAKE_GENERATOR")}
    env |= {"PATH": path, "TWIN_CACHE_DIR": str(tmp_path / "cache")}
    return subprocess.run(
        [sys.executable, "-m", "twin", "build"],
        env=env,
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )


@pytest.mark.parametrize(
    "tools, named, package",
    [
        (["cc", "gcc", "make"], "a C++ compiler (g++, or set CXX)", "apt-get install -y g++"),
        (["cc", "gcc", "c++", "g++"], "make or ninja", "apt-get install -y make"),
        (["cc", "gcc"], "a C++ compiler (g++, or set CXX) and make or ninja", "apt-get install -y g++ make"),
    ],
)
def test_a_missing_build_tool_is_named_with_its_debian_package_in_one_line(
    tmp_path: Path, tools: list[str], named: str, package: str
) -> None:
    # issue 33: without g++ or make, cmake said "Configuring incomplete" and the cause was in a log
    proc = _build_with_path(tmp_path, _path_with(tmp_path, tools))
    assert proc.returncode == 2, proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in proc.stderr, proc.stderr
    assert f"{named} not found" in lines[0] and lines[0].endswith(f"(Debian: {package})"), lines[0]
    assert not (tmp_path / "cache").exists() or not list((tmp_path / "cache").glob("*.fmu"))


def test_ninja_builds_where_make_is_missing(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    from twin.fmu.build import build_fmu
    from twin.fmu.toolchain import generator_flags

    assert generator_flags() == []  # make is on the real PATH: cmake's default
    # the compilers, their assembler and linker, ninja and cmake: no make
    monkeypatch.setenv("PATH", _path_with(tmp_path, ["cc", "gcc", "c++", "g++", "as", "ld", "ninja"]))
    for name in ("CC", "CXX", "CMAKE_GENERATOR"):
        monkeypatch.delenv(name, raising=False)
    assert generator_flags() == ["-G", "Ninja"]
    fmu = build_fmu("SignalSource", tmp_path / "out")
    assert "binaries/linux64/SignalSource.so" in zipfile.ZipFile(fmu).namelist()


def test_the_readme_names_every_package_the_check_asks_for() -> None:
    readme = (Path(__file__).parents[1] / "README.md").read_text(encoding="utf-8")
    assert "apt-get install gcc g++ make" in readme and "ninja-build" in readme


def _fresh_process(monkeypatch: pytest.MonkeyPatch) -> None:
    """What a new process knows of the source hashes: only the cache's record."""
    from twin.fmu import build, toolchain

    monkeypatch.setattr(toolchain, "_recorded", {})
    build._content_hash.cache_clear()


def test_a_fresh_process_takes_the_source_hash_from_the_caches_record_until_a_file_changes(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    import json
    import shutil

    from twin.fmu import build, toolchain

    monkeypatch.setenv(toolchain.CACHE_ENV, str(tmp_path / "cache"))
    monkeypatch.setattr(toolchain, "SETTLED_S", -60.0)  # the copied files count as settled
    copy = tmp_path / "fmus"
    shutil.copytree(sources_dir(), copy)
    _fresh_process(monkeypatch)
    before = source_hash("ThermalNetwork", copy)
    assert before == source_hash("ThermalNetwork")  # the same files, the same hash
    record = json.loads((tmp_path / "cache" / toolchain.SOURCE_HASHES).read_text())
    assert before in record.values()

    _fresh_process(monkeypatch)
    hashed: list[str] = []
    real = build.content_hash
    monkeypatch.setattr(build, "content_hash", lambda *a: hashed.append("hashed") or real(*a))
    assert source_hash("ThermalNetwork", copy) == before
    assert hashed == []  # no source read: the record said it

    # the same size, another content: its change time (or inode) is another, the record not used
    linalg = copy / "common" / "linalg.c"
    text = linalg.read_text()
    linalg.write_text(text.replace("(", "[", 1))
    _fresh_process(monkeypatch)
    after = source_hash("ThermalNetwork", copy)
    assert hashed == ["hashed"] and after != before


def test_a_source_changed_just_now_is_hashed_but_not_recorded(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    # a file rewritten within the clock's tick keeps its times: only settled files are recorded
    import shutil

    from twin.fmu import toolchain

    monkeypatch.setenv(toolchain.CACHE_ENV, str(tmp_path / "cache"))
    copy = tmp_path / "fmus"
    shutil.copytree(sources_dir(), copy)
    _fresh_process(monkeypatch)
    copied = source_hash("ThermalNetwork", copy)
    assert not (tmp_path / "cache" / toolchain.SOURCE_HASHES).exists()
    assert copied == source_hash("ThermalNetwork")


def test_a_record_entry_that_is_no_hash_is_not_used(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    from twin.fmu import toolchain

    folder = tmp_path / "cache"
    monkeypatch.setenv(toolchain.CACHE_ENV, str(folder))
    toolchain.private_cache_dir()
    (folder / toolchain.SOURCE_HASHES).write_text('{"k": "../../etc/passwd", "j": 3}\n')
    assert toolchain._read_hashes(folder / toolchain.SOURCE_HASHES) == {}
    (folder / toolchain.SOURCE_HASHES).write_text("[not a record")
    assert toolchain._read_hashes(folder / toolchain.SOURCE_HASHES) == {}
