"""A real run's recording read back without a browser (rerun's dataframe API: a ChunkStore's
DataFusion reader): entity paths, units in the series names and properties, one view per unit,
and the 3D view of the tester; plus the run's two PNGs.

One short MIL endurance run (10 min of the 41.7 h test: swing, load, heat, wear) serves every test.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest

from twin.cli import main
from twin.config.drawing import load_geometry
from twin.config.load import default_scenario_path

BODIES = [
    "base",
    "heel_block",
    "bearing_block",
    "spindle",
    "t_plate",
    "long_pole",
    "clamp",
    "detecting_frame",
    "sensor",
]


@pytest.fixture(scope="module")
def run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("mil") / "run"
    code = main(["run", "mil-endurance", "--set", 'scenario.duration="10 min"', "--out", str(out), "--quiet"])
    assert code == 0
    return out


@pytest.fixture(scope="module")
def store(run: Path) -> Any:
    # rerun's dataframe reader runs on DataFusion: the test extra installs rerun-sdk[catalog]
    from rerun.chunk import RrdReader

    return RrdReader(run / "recording.rrd").stream().collect()


def _entities(store: Any) -> set[str]:
    """The entity paths of the recording's component columns (the schema's index column has none)."""
    return {str(c.entity_path) for c in store.schema() if hasattr(c, "entity_path")}


def _static(store: Any, contents: str) -> dict[str, Any]:
    table = store.reader(index=None, contents=contents).to_arrow_table()
    return {name: table.column(name).to_pylist()[0] for name in table.schema.names if name != "sim_time"}


def _series(store: Any, entity: str, component: str) -> list[Any]:
    table = store.reader(index="sim_time", contents=entity).to_arrow_table()
    return [v for v in table.column(f"{entity}:{component}").to_pylist() if v is not None]


def test_the_recording_verifies(run: Path) -> None:
    from .test_rerun_rec import _verify

    result = _verify(run / "recording.rrd")
    assert result.returncode == 0, result.stderr


def test_entity_paths_and_units(store: Any) -> None:
    entities = _entities(store)
    for path in (
        "/thermal/t_bearing_block",
        "/mechanics/z_t_plate",
        "/sensors/probe_meas",
        "/errormodel/e_z",
    ):
        assert path in entities, path
    length = _static(store, "/mechanics/z_t_plate")
    assert length["/mechanics/z_t_plate:SeriesLines:names"] == ["z_t_plate [µm]"]
    assert length["/mechanics/z_t_plate:unit"] == ["µm"] and length["/mechanics/z_t_plate:si_unit"] == ["m"]
    temperature = _static(store, "/thermal/t_bearing_block")
    assert temperature["/thermal/t_bearing_block:SeriesLines:names"] == ["t_bearing_block [K]"]
    force = _static(store, "/hydraulic/radial_load")
    assert force["/hydraulic/radial_load:SeriesLines:names"] == ["radial_load [N]"]


def test_lengths_are_recorded_in_microns(run: Path, store: Any) -> None:
    from twin.outputs.csv import read_signals_csv

    csv = read_signals_csv(run / "signals.csv")
    recorded = np.concatenate(_series(store, "/mechanics/z_t_plate", "Scalars:scalars"))
    np.testing.assert_array_equal(recorded, csv["mechanics.z_t_plate"] * 1e6)


def test_the_3d_view_has_the_tester_its_load_and_its_legend(store: Any) -> None:
    g = load_geometry(default_scenario_path().parent)
    entities = _entities(store)
    assert {f"/tester/{b}" for b in BODIES} | {"/tester/radial_load", "/tester/legend"} <= entities
    pole = _static(store, "/tester/long_pole")
    # sizes from the geometry source: the pole is 730 mm x 10 mm (the paper's drawing)
    half = pole["/tester/long_pole:Boxes3D:half_sizes"][0]
    assert half == pytest.approx([0.005, 0.005, g.dim("bodies.long_pole.length") / 2])
    legend = _static(store, "/tester/legend")["/tester/legend:TextDocument:text"][0]
    assert "x1000" in legend and "K" in legend
    # the T-plate moves (wear and heat, exaggerated) and is coloured by its rise
    centres = [c[0] for c in _series(store, "/tester/t_plate", "Boxes3D:centers")]
    assert len(centres) > 10 and centres[-1][2] != centres[0][2]
    plate_colours = {c[0] for c in _series(store, "/tester/t_plate", "Boxes3D:colors")}
    assert len(plate_colours) > 1
    # the load arrow points down onto the T-plate, its label the load
    vectors = [v[0] for v in _series(store, "/tester/radial_load", "Arrows3D:vectors")]
    assert all(v[2] < 0 for v in vectors[-5:])
    assert _series(store, "/tester/radial_load", "Arrows3D:labels")[-1][0].endswith("kN")
    # the spindle turns with the swing
    angles = _series(store, "/tester/spindle", "Boxes3D:rotation_axis_angles")
    assert len({str(a) for a in angles}) > 1


def test_the_blueprint_shows_the_budget_the_tester_and_one_view_per_unit(run: Path) -> None:
    from twin.outputs.rerun_rec import BUDGET_VIEW_NAME, SCENE_VIEW_NAME

    from .test_rerun_rec import _blueprint_rows

    rows = _blueprint_rows(run / "recording.rrd")
    views = {r["ViewBlueprint:display_name"][0][0]: r for r in rows if "ViewBlueprint:display_name" in r}
    assert views[SCENE_VIEW_NAME]["ViewBlueprint:class_identifier"][0] == ["3D"]
    assert views[SCENE_VIEW_NAME]["ViewBlueprint:space_origin"][0] == ["/tester"]
    assert BUDGET_VIEW_NAME in views
    assert {"thermal [K]", "thermal [J]", "mechanics [N]"} <= set(views)
    # the mechanics' lengths span mm (the T-plate's travel) to sub-µm: split by magnitude
    assert len([v for v in views if v.startswith("mechanics [µm] up to ")]) > 1


def test_the_run_draws_both_plots(run: Path) -> None:
    for name in ("error_budget.png", "wear.png"):
        assert (run / name).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n", name


def _view_queries(run: Path) -> dict[str, list[str]]:
    """View name -> the entity paths its time series shows."""
    from .test_rerun_rec import _blueprint_rows

    rows = _blueprint_rows(run / "recording.rrd")
    names = {r["ViewBlueprint:display_name"][0][0] for r in rows if "ViewBlueprint:display_name" in r}
    queries = [
        [q.removeprefix("+ ") for q in r["ViewContents:query"][0]] for r in rows if "ViewContents:query" in r
    ]
    series = [q for q in queries if q and all(e.startswith("/") and e != "/tester/**" for e in q)]
    assert len(series) == len(names) - 1  # every view but the 3D one lists its series
    return {str(i): q for i, q in enumerate(series)}


def test_no_view_holds_series_a_hundred_times_apart_and_the_budget_is_shown_once(
    run: Path, store: Any
) -> None:
    # issue 33: a 200 kN load beside a 20 N force, a 4850 µm reading beside sub-µm vibration on one
    # axis; the error budget in two views
    views = _view_queries(run)
    peak = {}
    for entity in {e for q in views.values() for e in q}:
        values = np.concatenate(_series(store, entity, "Scalars:scalars"))
        finite = np.abs(values[np.isfinite(values)])
        peak[entity] = float(finite.max()) if finite.size else 0.0
    for members in views.values():
        nonzero = [peak[e] for e in members if peak[e] > 0]
        assert not nonzero or max(nonzero) <= 100 * min(nonzero), {e: peak[e] for e in members}
    shown = [e for q in views.values() for e in q]
    assert len(shown) == len(set(shown)), "a series is in two views"
    view_of = {e: name for name, q in views.items() for e in q}
    assert peak["/hydraulic/radial_load"] > 1e5 and peak["/sensors/probe_meas"] > 1e3
    small = [e for e in peak if 0 < peak[e] < peak["/hydraulic/radial_load"] / 100 and "[N]" in e]
    assert all(view_of[e] != view_of["/hydraulic/radial_load"] for e in small)
