"""The FMUs at the largest step their dynamics allow, against a fine-step reference (issue 15).

The tester's operating scenarios step the hydraulic loader, the oscillation drive and the
fixture mechanics once per 0.1 s exchange (``solver_step`` = the period), where they took ten
internal 10 ms steps before. That is exact, not an approximation, for what each one integrates
with its inputs held over the exchange (the master holds them: zero-order hold):

* HydraulicLoader: the servo's step map is a matrix exponential (exact for any step) and a
  constant load profile is the same command at every internal step;
* OscillationDrive: the swing is a function of the phase and the sliding distance and friction
  energy are exact integrals of |omega| over any step (reversals inside a step included);
* FixtureMechanics: wear with its running-in is an exact integral over the sliding distance,
  creep an exact first-order step for the held load.

So the coarse run must equal the fine one to rounding: relative 1e-9 (ten steps of rounding
against one, on sums of up to 1.5 million steps). The exceptions are stated where they are
tested: the drive's vibration noise (one Gaussian draw per internal step: another realisation,
the same statistics) and profiles that change within an exchange (a sine or trapezoid load
keeps its 10 ms steps: there the command itself changes within 0.1 s).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from twin.cli import main
from twin.config.load import load_scenario, scenarios_dir
from twin.outputs.csv import read_signals_csv

TESTER = scenarios_dir() / "base" / "tester-system.toml"
FINE = [f"fmu.{n}.parameters.solver_step=0.01" for n in ("hydraulic", "oscillation", "mechanics")]
EXACT = [
    "hydraulic.radial_load",
    "hydraulic.q_station",
    "oscillation.angle",
    "oscillation.sliding_distance",
    "oscillation.friction_energy",
    "oscillation.cycles",
    "mechanics.wear_depth_true",
    "mechanics.dz_liner_creep",
    "mechanics.dz_loading",
]


#: both runs: the cylinder starts unloaded, so the servo's step map is compared through the
#: load's rise to its command (a run that starts at the command holds the servo at its fixed
#: point, where any step map gives the same constant), each 0.1 s exchange recorded
BOTH = ["fmu.hydraulic.parameters.start_at_command=false", 'scenario.output_interval="0.1 s"']


def _run(tmp_path: Path, name: str, sets: list[str]) -> dict[str, np.ndarray]:
    out = tmp_path / name
    args = ["run", str(TESTER), "--out", str(out), "--quiet", "--set", 'scenario.duration="20 min"']
    for s in [*BOTH, *sets]:
        args += ["--set", s]
    assert main(args) == 0
    table = read_signals_csv(out / "signals.csv")
    return {n: table[n] for n in table.names()}


@pytest.fixture(scope="module")
def runs(tmp_path_factory: pytest.TempPathFactory) -> tuple[dict[str, np.ndarray], dict[str, np.ndarray]]:
    tmp = tmp_path_factory.mktemp("steps")
    return _run(tmp, "coarse", []), _run(tmp, "fine", FINE)


def test_the_tester_steps_those_fmus_once_per_exchange() -> None:
    scenario = load_scenario(TESTER)
    for name in ("hydraulic", "oscillation", "mechanics"):
        spec = scenario.fmu(name)
        assert spec.parameters["solver_step"].value * 1e9 == spec.period_ns


def test_the_load_rises_through_the_servo_in_the_compared_runs(runs) -> None:
    """What the comparison of the loader's columns stands on: the servo's load (the recorded
    load without its ripple, a function of time) moves over the first exchanges before it
    settles at the command (15 Hz: within a few tenths of a second)."""
    fine = runs[1]
    servo = fine["hydraulic.radial_load"] - fine["hydraulic.load_ripple"]
    off = np.abs(servo - fine["hydraulic.load_command"])
    assert servo[0] == 0.0 and np.count_nonzero(off[1:] > 0.1) >= 2 and off[-1] < 1e-6  # 362 N, 0.5 N


@pytest.mark.parametrize("column", EXACT)
def test_one_step_per_exchange_equals_ten_to_rounding(runs, column: str) -> None:
    coarse, fine = runs
    scale = max(float(np.max(np.abs(fine[column]))), 1e-300)
    np.testing.assert_allclose(coarse[column], fine[column], rtol=1e-9, atol=1e-9 * scale, err_msg=column)


def test_the_vibration_is_another_draw_of_the_same_noise(runs) -> None:
    """One Gaussian draw per internal step: at 0.1 s the drive draws a tenth as many, so the
    samples differ; the ringing after each reversal and the noise's spread stay (within 10 %)."""
    coarse, fine = runs
    a, b = coarse["oscillation.vibration_z"], fine["oscillation.vibration_z"]
    assert not np.array_equal(a, b)
    assert np.std(a) == pytest.approx(np.std(b), rel=0.10)


def test_a_changing_load_profile_keeps_its_fine_steps() -> None:
    for name in ("sine-load", "trapezoid-load"):
        spec = load_scenario(scenarios_dir() / f"{name}.toml").fmu("hydraulic")
        assert spec.parameters["solver_step"].value == pytest.approx(0.01), name
