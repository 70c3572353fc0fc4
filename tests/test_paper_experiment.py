"""The paper's 480-minute thermal experiment through the whole twin (README's main job).

Validation rules (design notes section 6): the temperature rises are calibration data, the
probe drift (-0.021 mm) is validation data that nothing is fitted to.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from tests.runs import run_into
from twin.config.load import default_scenario_path, load_scenario
from twin.outputs import read_signals_csv
from twin.paper import DRIFT_M, FEM_PARTS_M, TEMPERATURE_RISE_K

pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def paper_run(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, dict]:
    out = tmp_path_factory.mktemp("paper")
    summary = run_into(load_scenario(default_scenario_path()), out)
    assert (out / "summary.json").read_text(encoding="utf-8") == summary.to_json()
    return out, summary.to_dict()


def test_run_writes_the_four_files(paper_run: tuple[Path, dict]) -> None:
    out, summary = paper_run
    for name in ("signals.csv", "summary.json", "recording.rrd", "error_budget.png"):
        assert (out / name).stat().st_size > 0, name
    assert summary["status"] == "completed"
    on_disk = json.loads((out / "summary.json").read_text())
    for key in ("drift_mm", "temperature_rise_C", "error_parts_mm", "status", "seed", "wall_s"):
        assert key in on_disk
    assert set(on_disk["error_parts_mm"]) == {
        "thermal",
        "loading",
        "fluctuating",
        "positioning",
        "interference",
        "total",
    }
    assert (out / "error_budget.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_recording_passes_rerun_verify(paper_run: tuple[Path, dict]) -> None:
    out, _ = paper_run
    proc = subprocess.run(
        [sys.executable, "-m", "rerun_cli", "rrd", "verify", str(out / "recording.rrd")],
        capture_output=True,
        text=True,
        check=False,
    )
    assert proc.returncode == 0, proc.stdout + proc.stderr


def test_signals_are_readable_by_fmpy(paper_run: tuple[Path, dict]) -> None:
    from fmpy.util import read_csv

    out, _ = paper_run
    data = read_csv(str(out / "signals.csv"))
    assert data["time"][0] == 0.0 and data["time"][-1] == 28800.0
    assert "sensors.probe_meas" in data.dtype.names


@pytest.mark.parametrize("point", sorted(TEMPERATURE_RISE_K))
def test_temperature_rise_within_0_3_K_of_the_paper(paper_run: tuple[Path, dict], point: str) -> None:
    """Issue 30's acceptance: the replay's thermometers (the DAQ's, on the nodes the paper names:
    the bearing block's cap, the frame's bottom, the pole's lower part) read each of the paper's
    eight rises within 0.3 K, with no calibrated value pulled beyond 3 prior sigma
    (tests/test_calibration_pulls.py). The network needed the bodies its lumps hid for it: the
    transmission on its floor behind the spindle, the block's cap and halves, the bearing's liner."""
    _, summary = paper_run
    assert summary["temperature_rise_C"][point] == pytest.approx(TEMPERATURE_RISE_K[point], abs=0.3)


def test_the_bearing_blocks_gradient_and_tilt_are_reported(paper_run: tuple[Path, dict]) -> None:
    # the front half (holding the roller bearing on the spindle, whose transmission lags on its
    # floor) ends cooler than the rear: a gradient of about -0.1 K; its tilt at the 115 mm overhang
    # moves the T-plate a few tenths of a micrometre. Reported, its size is not a goal
    _, summary = paper_run
    g = summary["gradients"]["bearing_block"]
    alpha, h, d, overhang = 11e-6, 0.1, 0.06, 0.115  # tester-geometry.toml
    assert g["tilt_urad"] == pytest.approx(-alpha * h * g["front_minus_rear_K"] / d * 1e6, rel=1e-6)
    assert g["z_t_plate_mm"] == pytest.approx(overhang * g["tilt_urad"] * 1e-6 * 1e3, rel=1e-3)
    assert 0.01 <= abs(g["front_minus_rear_K"]) <= 1.0


def test_predicted_drift_is_the_honest_nominal(paper_run: tuple[Path, dict]) -> None:
    """Lengths from the drawing, the thermal network from the drawing and the paper's eight
    rises (the transmission on its floor, the block's halves, the station's heat under the base),
    the probe's drifts at the prior's centre (0), the loop closed by the base's inset and the
    probe's body: the nominal replay predicts +0.0074 mm, the pole (warmed by the station's heat
    under the base) outgrowing the frame. The measured -0.021 mm is NOT reached (28 um off):
    issue 31 updates the twin from it openly. This asserts the honest figure, not the goal."""
    _, summary = paper_run
    predicted = summary["drift_mm"]["predicted"]
    assert predicted == pytest.approx(0.0074, abs=0.0005)
    assert abs(predicted - DRIFT_M * 1e3) == pytest.approx(0.0284, abs=0.0005)


def test_probe_reading_agrees_with_the_prediction_within_half_a_micrometre(
    paper_run: tuple[Path, dict],
) -> None:
    _, summary = paper_run
    assert abs(summary["drift_mm"]["probe"] - summary["drift_mm"]["predicted"]) <= 0.5e-3


def test_thermal_parts_sit_near_the_papers_fem_parts(paper_run: tuple[Path, dict]) -> None:
    # compared, not fitted: the tester's own parts (FixtureMechanics, drawing lengths) against the
    # FEM, within the 25 % that issue 12 sets as the goal. The bearing block's is the exception,
    # with its reason: the paper gives no number for it (its Table 6 is not in the text), the
    # -0.018 mm is derived from the paper's reasoning (facts 2: FEM total less the other parts),
    # so it carries their rounding and the FEM's whole total; the twin's block lifts the spindle by
    # its drawn heights at its halves' rises (-0.013 mm, 27 % short). Its sign and size are
    # asserted within 40 %, the others within 25 %.
    _, summary = paper_run
    parts = summary["thermal_parts_mm"]
    truth = summary["thermal_parts_mm_truth"]
    fem_in_ez = {  # FEM displacements as contributions to e_z (branch 1 +, branch 2 -, pole/clamp push the face down)
        "bearing_block": FEM_PARTS_M["bearing_block"],
        "t_plate": FEM_PARTS_M["t_plate"],
        "detecting_frame": -FEM_PARTS_M["detecting_frame"],
        "long_pole": FEM_PARTS_M["long_pole"],
    }
    for group, fem in fem_in_ez.items():
        rel = 0.40 if group == "bearing_block" else 0.25
        assert truth[group] == pytest.approx(fem * 1e3, rel=rel), group
    # the parts add up to the predicted thermal error
    assert sum(parts.values()) == pytest.approx(summary["error_parts_mm"]["thermal"], abs=1e-12)


def test_other_parts_are_zero_without_their_causes(paper_run: tuple[Path, dict]) -> None:
    _, summary = paper_run
    for part in ("loading", "fluctuating", "interference"):
        assert summary["error_parts_mm"][part] == 0.0
    # positioning is the identified cosine term (1 - probe_scale) on the reading's own ~20 um
    # change: the coefficients were identified on the base tester, whose probe is tilted
    # (probe_scale 0.99996), so it is of order 1 nm here, not exactly 0
    assert abs(summary["error_parts_mm"]["positioning"]) < 1e-5


def test_same_scenario_and_seed_give_byte_identical_signals(
    paper_run: tuple[Path, dict], tmp_path: Path
) -> None:
    out, _ = paper_run
    run_into(load_scenario(default_scenario_path()), tmp_path)
    assert (tmp_path / "signals.csv").read_bytes() == (out / "signals.csv").read_bytes()


def test_another_seed_gives_other_noise(paper_run: tuple[Path, dict], tmp_path: Path) -> None:
    out, _ = paper_run
    run_into(
        load_scenario(default_scenario_path(), ["scenario.seed=7", 'scenario.duration="30 min"']), tmp_path
    )
    a = read_signals_csv(out / "signals.csv")
    b = read_signals_csv(tmp_path / "signals.csv")
    n = len(b)
    assert not np.array_equal(a["sensors.probe_meas"][:n], b["sensors.probe_meas"])
    # while the noise-free physics is the same
    np.testing.assert_array_equal(a["thermal.t_base"][:n], b["thermal.t_base"])
