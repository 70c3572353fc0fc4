#!/usr/bin/env python3
"""Draw the docs' pictures (docs/*.png) from real runs, small: ``python docs/pictures.py``.

Runs the default run (the paper's replay with its updated tester, as plain ``twin run`` runs
it, here without its Monte Carlo) and the MIL endurance test into a temporary folder and draws
their error budget and wear plots with the twin's own figure builders at a lower resolution (the
README and the docs show them about 700 px wide). Nothing here is drawn by hand.
"""

from __future__ import annotations

import tempfile
from pathlib import Path

DOCS = Path(__file__).resolve().parent
DPI = 64


def main() -> None:
    from twin.cli import main as twin
    from twin.cli.common import tester_path
    from twin.outputs.csv import read_signals_csv
    from twin.outputs.plots import budget_figure, wear_figure
    from twin.pipeline import RunOptions, prepare
    from twin.pipeline.stages import budget_columns
    from twin.validation import reports

    with tempfile.TemporaryDirectory() as tmp:
        # the README shows the paper's picture as the default run's: that run, scenario unnamed
        # (its updated tester; a named scenario runs without one)
        for name, picture, named in (
            ("li2017-thermal-experiment", "error_budget_paper", False),
            ("mil-endurance", "wear_mil", True),
        ):
            out = Path(tmp) / name
            scenario = [name] if named else []
            assert twin(["run", *scenario, "--out", str(out), "--quiet", "--uncertainty", "0"]) == 0
            # as the run drew them: the wear limit, the cycles, the paper's measured drift
            options = RunOptions(reports=reports, tester=tester_path(None, default=not named))
            prepared = prepare(name if named else None, options=options)
            columns = budget_columns(prepared.evaluation, prepared)
            table = read_signals_csv(out / "signals.csv")
            derived = read_signals_csv(out / "errormodel.csv")
            for n in derived.names():
                table.add(derived.meta[n], derived[n])
            title = f"{name}: predicted error and its parts"
            figures = {picture: budget_figure(table, columns, title)}
            if picture == "wear_mil":
                figures = {
                    "wear_mil": wear_figure(table, columns, f"{name}: wear against swing cycles"),
                    "error_budget_mil": figures[picture],
                }
            for stem, fig in figures.items():
                assert fig is not None, stem
                fig.savefig(DOCS / f"{stem}.png", format="png", dpi=DPI, metadata={"Software": None})
                print(DOCS / f"{stem}.png")


if __name__ == "__main__":
    main()
