"""Every FMU survives a deterministic fuzz run under AddressSanitizer and UBSan (issue 13).

The harness (``fuzz/fuzz_fmu.c``, built by ``sanitized.py`` with the model's sources, every
sanitizer report fatal and the sources held to -Wall -Wextra -Werror) first hands back one
crafted violation of each invariant the wrapper and the model check and requires each to be
refused with a message naming it; then it fuzzes serialized states (bit flips, special values
in fields, truncation, extension, random bytes, spliced states), inputs and parameters (NaN,
Inf, huge, out of range, unknown references), call orders and step sizes. A crash, an
out-of-bounds access, undefined behaviour, a leak, a refused call that changed the instance or a
legitimately reached state that is refused all fail the test. A few seconds per model here;
``tools/fuzz_fmus.py`` runs the same harness for as long as wanted.
"""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest

from tests.fmus.sanitized import build_harness, run_harness, sanitizer_problem
from twin.fmu.build import fmu_sources_dir, model_names

#: fixed seed: the CI run is reproducible (``fuzz_<Model> SEED ITERATIONS`` replays it)
SEED = 13
#: iterations per model: ~0.3 s each, but ThermalNetwork's state check exponentiates a 29x29
#: matrix (about 1 ms under the sanitizers)
ITERATIONS = {"ThermalNetwork": 2_000}
DEFAULT_ITERATIONS = 20_000
#: mutation kinds whose states are sometimes valid: the fuzzer must get some past the checks, or
#: it never exercised the model with a mutated state
REACHES_THE_MODEL = ("bitflip", "slot", "model_field", "value_field", "splice")


@pytest.fixture(scope="module")
def harness_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    problem = sanitizer_problem()
    if problem:
        pytest.skip(
            f"no sanitizer runtime: {problem} (Debian: apt-get install -y gcc, which brings libasan and libubsan)"
        )
    return tmp_path_factory.mktemp("fuzz")


@pytest.mark.parametrize("model", model_names())
def test_fuzz_under_sanitizers(model: str, harness_dir: Path) -> None:
    exe = build_harness(model, harness_dir)
    result = run_harness(exe, SEED, ITERATIONS.get(model, DEFAULT_ITERATIONS), timeout=300)
    assert result.clean, f"{exe} {SEED} {ITERATIONS.get(model, DEFAULT_ITERATIONS)}:\n{result.tail()}"
    counts = result.counts
    assert counts["crafted"][0] >= 25, counts  # the wrapper's cases and the model's own
    for kind in REACHES_THE_MODEL:
        accepted, refused = counts[kind]
        assert accepted > 0 and refused and refused > 0, (kind, counts[kind])
    for kind in ("header", "truncate", "extend", "random", "random_body"):
        assert counts[kind][0] == 0 and counts[kind][1], (kind, counts[kind])
    assert counts["legit"][0] > 100 and counts["restored"][0] > 10, counts
    assert counts["too_long"][0] > 0, counts


def test_the_harness_finds_a_removed_check(
    harness_dir: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Without the clock check a crafted step counter overflows in doStep: the crafted cases
    name it at once, and the random fuzzing alone runs into UBSan's report of the overflow."""
    sources = tmp_path / "fmus"
    shutil.copytree(fmu_sources_dir(), sources)
    wrapper = sources / "common" / "fmi2_wrapper.c"
    check = "static int bad_clock(StateCheck *c, const ModelValues *v) {\n"
    assert check in wrapper.read_text()
    wrapper.write_text(wrapper.read_text().replace(check, check + "    if (c) return 0; /* removed */\n"))
    monkeypatch.setenv("TWIN_FMU_SOURCES", str(sources))
    exe = build_harness("SensorsDAQ", tmp_path)
    crafted = run_harness(exe, SEED, 10)
    assert not crafted.clean and "crafted common case 3 (internal steps taken) was accepted" in crafted.stderr
    found = [run_harness(exe, seed, DEFAULT_ITERATIONS, random_only=True) for seed in range(1, 4)]
    assert any("runtime error: signed integer overflow" in r.stderr for r in found), [
        r.tail(3) for r in found
    ]
