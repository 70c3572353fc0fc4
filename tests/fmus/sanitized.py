"""Build and run the sanitizer fuzz harness of one FMU (``tests/fmus/fuzz/fuzz_fmu.c``).

The harness is a C program compiled together with the model's sources (those its
modelDescription.xml lists) and the FMI wrapper, with AddressSanitizer and UBSan, every report
fatal (``-fno-sanitize-recover=all``), and the FMU sources held to ``-Wall -Wextra -Werror``.
It drives the FMI functions directly, so a memory error or undefined behaviour in the FMU ends
the run with a sanitizer report instead of a silent corruption.

Used by ``test_fuzz_sanitized.py`` (a few seconds per model, fixed seeds) and by
``tools/fuzz_fmus.py`` (long runs). This module is the one place that imports the generator of
``model_vars.h``.
"""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import tempfile
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path

from twin.fmu.build import fmu_sources_dir, generate_vars_header
from twin.fmu.catalog import describe

HARNESS = Path(__file__).resolve().parent / "fuzz" / "fuzz_fmu.c"

#: every sanitizer report is fatal; float casts out of range and float division by zero are
#: undefined behaviour gcc's -fsanitize=undefined does not include by itself
SANITIZE = [
    "-fsanitize=address,undefined,float-cast-overflow,float-divide-by-zero",
    "-fno-sanitize-recover=all",
    "-fno-omit-frame-pointer",
]
WARNINGS = ["-std=c99", "-Wall", "-Wextra", "-Werror"]
#: halt at the first report; leaks count too (the harness frees everything)
RUN_ENV = {
    "ASAN_OPTIONS": "detect_leaks=1:halt_on_error=1:abort_on_error=0:exitcode=86",
    "UBSAN_OPTIONS": "print_stacktrace=1:halt_on_error=1:exitcode=87",
}
#: what the harness prints at the end: per mutation kind "name=accepted/refused", then counts
_COUNT = re.compile(r"(\w+)=(\d+)(?:/(\d+))?")


class SanitizerBuildError(RuntimeError):
    """The harness did not compile (a warning in the FMU sources counts as an error)."""


def compiler() -> str | None:
    """The C compiler to use: ``$CC``, else gcc, clang or cc on PATH."""
    return os.environ.get("CC") or shutil.which("gcc") or shutil.which("clang") or shutil.which("cc")


def sanitizer_problem() -> str | None:
    """Why sanitized programs cannot be built or run here, or None if they can."""
    cc = compiler()
    if not cc:
        return "no C compiler (apt-get install -y gcc)"
    with tempfile.TemporaryDirectory(prefix="twin-asan-probe-") as tmp:
        src = Path(tmp) / "probe.c"
        src.write_text(
            "#include <stdlib.h>\nint main(void) { char *p = malloc(4); p[0] = 1; free(p); return 0; }\n"
        )
        exe = Path(tmp) / "probe"
        for cmd in ([cc, *SANITIZE, str(src), "-o", str(exe)], [str(exe)]):
            proc = subprocess.run(
                cmd, capture_output=True, text=True, env={**os.environ, **RUN_ENV}, check=False
            )
            if proc.returncode != 0:
                tail = (proc.stderr or proc.stdout).strip().splitlines()[-3:]
                return f"{cc} cannot build or run a sanitized program ({' '.join(cmd[:1])}): " + " | ".join(
                    tail
                )
    return None


def _fmi_headers() -> Path:
    import fmpy

    return Path(fmpy.__file__).parent / "c-code"


def _source_files(xml_path: Path) -> list[str]:
    """The C files the model's FMU compiles, as its modelDescription.xml lists them."""
    root = ET.parse(xml_path).getroot()
    return [f.get("name", "") for f in root.iterfind("CoSimulation/SourceFiles/File")]


def model_tree(model: str, work: Path) -> list[Path]:
    """Lay out what a C program compiled with ``model``'s sources needs in ``work``: the
    model's and the common C files, the FMI headers and its generated ``model_vars.h``; returns
    the C files its FMU compiles (as its modelDescription.xml lists them), in ``work``."""
    src = fmu_sources_dir()
    work.mkdir(parents=True, exist_ok=True)
    for p in [*(src / "common").iterdir(), *(src / model).iterdir()]:
        if p.suffix in {".c", ".h"}:
            shutil.copyfile(p, work / p.name)
    for p in _fmi_headers().glob("fmi2*.h"):
        shutil.copyfile(p, work / p.name)
    xml = src / model / "modelDescription.xml"
    (work / "model_vars.h").write_text(generate_vars_header(describe(xml), str(xml)))
    return [work / name for name in _source_files(xml)]


def build_harness(
    model: str, out_dir: Path, *, optimize: str = "-O1", extra: list[str] | None = None
) -> Path:
    """Compile the fuzz harness of ``model`` into ``out_dir/fuzz_<model>`` and return its path."""
    cc = compiler()
    if not cc:
        raise SanitizerBuildError("no C compiler")
    work = out_dir / model
    sources = [str(p) for p in model_tree(model, work)]
    exe = out_dir / f"fuzz_{model}"
    cmd = [cc, optimize, "-g", *SANITIZE, *WARNINGS, *(extra or []), "-I", str(work), str(HARNESS), *sources]
    proc = subprocess.run([*cmd, "-o", str(exe), "-lm"], capture_output=True, text=True, check=False)
    if proc.returncode != 0:
        raise SanitizerBuildError(f"building the fuzz harness of {model} failed:\n{proc.stderr.strip()}")
    return exe


@dataclass(frozen=True)
class FuzzResult:
    """One run of a harness: its exit code, output and the counts of its last line."""

    returncode: int
    stdout: str
    stderr: str
    counts: dict[str, tuple[int, int | None]]

    @property
    def clean(self) -> bool:
        """Exit 0 and no sanitizer or harness report."""
        reports = ("FUZZ FAILURE", "AddressSanitizer", "LeakSanitizer", "runtime error:")
        return self.returncode == 0 and not any(r in self.stderr for r in reports)

    def tail(self, lines: int = 40) -> str:
        """The end of the output, for an assertion message."""
        return "\n".join((self.stdout + self.stderr).strip().splitlines()[-lines:])


def run_harness(
    exe: Path, seed: int, iterations: int, *, random_only: bool = False, timeout: float = 600.0
) -> FuzzResult:
    """Run ``exe`` with this seed and number of iterations (``random_only``: skip the crafted cases)."""
    proc = subprocess.run(
        [str(exe), str(seed), str(iterations), *(["-r"] if random_only else [])],
        capture_output=True,
        text=True,
        env={**os.environ, **RUN_ENV},
        timeout=timeout,
        check=False,
    )
    last = proc.stdout.strip().splitlines()[-1] if proc.stdout.strip() else ""
    counts = {name: (int(a), int(b) if b else None) for name, a, b in _COUNT.findall(last.partition(":")[2])}
    return FuzzResult(proc.returncode, proc.stdout, proc.stderr, counts)
