#!/usr/bin/env python3
"""Draw the docs' pictures (docs/*.png) from real runs, small: ``python docs/pictures.py``.

Runs the paper's replay and the MIL endurance test into a temporary folder and draws their
error budget and wear plots with the twin's own figure builders at a lower resolution (the
README and the docs show them about 700 px wide). Nothing here is drawn by hand.
"""

from __future__ import annotations

import tempfile
from pathlib import Path

DOCS = Path(__file__).resolve().parent
DPI = 64


def main() -> None:
    from twin.cli import main as twin
    from twin.outputs.csv import read_signals_csv
    from twin.outputs.plots import budget_figure, wear_figure
    from twin.pipeline import RunOptions, prepare
    from twin.pipeline.stages import budget_columns
    from twin.validation import reports

    with tempfile.TemporaryDirectory() as tmp:
        for name, picture in (
            ("li2017-thermal-experiment", "error_budget_paper"),
            ("mil-endurance", "wear_mil"),
        ):
            out = Path(tmp) / name
            assert twin(["run", name, "--out", str(out), "--quiet", "--uncertainty", "0"]) == 0
            # as the run drew them: the wear limit, the cycles, the paper's measured drift
            prepared = prepare(name, options=RunOptions(reports=reports))
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
